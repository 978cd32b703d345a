"""Every use of Optuna's private code, in one module.

The search wing reads and extends Optuna's storages and TPE beyond their public API in a few
places, each for a measured reason (a worker's cost per trial that stays flat to 10k trials, a
journal that survives kills, a study shared over PostgreSQL). Those places import nothing private
themselves: they take it from here, so an Optuna release that moves or renames one of them breaks
this module and its tests (``tests/test_optuna_compat.py``, one test per touchpoint, run against
the installed Optuna), not a study in the field.

The touchpoints, each named where it is used:

- **private modules** imported: the journal's lock interface, operation codes and replay result,
  its snapshot base (``optuna.storages.journal._file``, ``._storage``, ``._base``); the RDB
  storage's table models (``optuna.storages._rdb.models``); the cached storage's per-study record
  (``optuna.storages._cached_storage._StudyInfo``); TPE's default split functions and its
  truncated normal's log CDF (``optuna.samplers._tpe``);
- **private attributes**: a trial's storage id (``Trial._trial_id``, ``FrozenTrial._trial_id``), a
  study's storage and id (``Study._storage``, ``Study._study_id``), TPE's split
  (``TPESampler._gamma``), the cached storage's lock, per-study cache and trial insertion;
- **private methods** our storages override or call (:data:`OVERRIDDEN`), checked to exist with
  the arguments we pass.

Written against optuna 5.0-5.1 (the pin admits the newest 5.x; CI installs it).
"""

from __future__ import annotations

from typing import Any, Callable

from optuna.samplers._tpe import _truncnorm as _tpe_truncnorm
from optuna.samplers._tpe import sampler as tpe_sampler_module   # its _split_trials, spied on by a test
from optuna.samplers._tpe.sampler import default_gamma, default_gamma_multiobjective
from optuna.storages.journal._base import BaseJournalSnapshot
from optuna.storages.journal._file import BaseJournalFileLock
from optuna.storages.journal._storage import JournalOperation, JournalStorageReplayResult

__all__ = [
    "BaseJournalFileLock", "BaseJournalSnapshot", "JournalOperation", "JournalStorageReplayResult",
    "default_gamma", "default_gamma_multiobjective", "tpe_sampler_module", "OVERRIDDEN", "FROZEN_TRIAL_FIELDS",
    "trial_id", "study_storage", "study_id", "cached_backend", "enqueued_params", "set_tpe_gamma", "stale_trial_ids", "rdb_models",
    "into_cache", "use_scipy_log_ndtr", "log_ndtr_in_use", "ATTRIBUTES",
]


def trial_id(trial: Any) -> int:
    """The storage's id of a trial (``optuna.Trial`` or ``FrozenTrial``): what every storage call
    takes; the public ``number`` is the study's count, not the id."""
    return trial._trial_id


def study_storage(study: Any) -> Any:
    """The storage a study object reads and writes (Optuna keeps it private)."""
    return study._storage


def study_id(study: Any) -> int:
    """The storage's id of a study object."""
    return study._study_id


def enqueued_params(trial: Any) -> dict:
    """The parameters a trial was enqueued with (``Study.enqueue_trial`` keeps them in the system
    attribute ``fixed_params`` until a ``suggest`` stores each), or {} for a sampled trial."""
    return dict(trial.system_attrs.get("fixed_params") or {})


def set_tpe_gamma(sampler: Any, gamma: Callable[[int], int]) -> None:
    """Give a TPE sampler its "good trials" split: its ``gamma`` argument is deprecated since
    Optuna 4.9 and warns; the attribute is what every 5.x TPE reads."""
    sampler._gamma = gamma


def stale_trial_ids(storage: Any, sid: int) -> list[int]:
    """Optuna's heartbeat reading of a database study: the running trials whose heartbeat is older
    than the grace period (``RDBStorage._get_stale_trial_ids``)."""
    return storage._get_stale_trial_ids(sid)


def cached_backend(storage: Any) -> Any:
    """The storage under Optuna's cache (``_CachedStorage._backend``: the RDB storage a database
    URL opens), or ``storage`` itself when it has no cache."""
    return getattr(storage, "_backend", storage)


def rdb_models() -> Any:
    """Optuna's SQLAlchemy table models (imported on use: SQLAlchemy's ORM costs ~0.2 s)."""
    from optuna.storages._rdb import models
    return models


def into_cache(storage: Any, sid: int, trial: Any) -> None:
    """Put ``trial`` into Optuna's cache over a database storage (``_CachedStorage``), where a
    trial must be before this process writes its parameters (its ``set_trial_param`` looks the
    trial up there). A storage without that cache needs nothing."""
    add = getattr(storage, "_add_trials_to_cache", None)
    if add is None:
        return
    from optuna.storages._cached_storage import _StudyInfo
    with storage._lock:
        storage._studies.setdefault(sid, _StudyInfo())
        add(sid, [trial])


def use_scipy_log_ndtr() -> Callable[..., Any] | None:
    """Put SciPy's ``special.log_ndtr`` (C) in place of TPE's truncated normal's own log normal CDF
    (``_truncnorm._log_ndtr``, element by element in Python in Optuna 5.x; at 10k trials most of
    the sampling time), in this process. Returns Optuna's own function (for the test that holds
    the two equal), or None where that private function is not there as expected (nothing is
    changed then)."""
    from scipy.special import log_ndtr
    own = getattr(_tpe_truncnorm, "_log_ndtr", None)
    if not callable(own):
        return None
    if own is not log_ndtr:
        _tpe_truncnorm._log_ndtr = log_ndtr
        use_scipy_log_ndtr.optuna_own = own          # type: ignore[attr-defined]
    return getattr(use_scipy_log_ndtr, "optuna_own", own)


def log_ndtr_in_use() -> Callable[..., Any] | None:
    """The log normal CDF TPE's truncated normal calls now."""
    return getattr(_tpe_truncnorm, "_log_ndtr", None)


#: FrozenTrial's fields (its ``__dict__``) in the order its constructor sets them (its repr and hash
#: follow it): the journal's packed trial keeps a few of them and rebuilds the rest
#: (``tuner/store/journal.py``).
FROZEN_TRIAL_FIELDS = ("_number", "state", "_values", "_datetime_start", "datetime_complete", "_params",
                       "_user_attrs", "_system_attrs", "intermediate_values", "_distributions", "_trial_id")


#: Optuna's private methods our storages override (``tuner/store/journal.py``,
#: ``tuner/store/rdb.py``) or whose state they set up, and the one a study view implements for
#: Optuna's TPE sampler and median pruner, which read a study's trials through it
#: (``tuner/store/history.py``: ``_WindowStudy``, ``_CurveStudy``), with the arguments (after self):
#: (module, class, method, parameter names)
OVERRIDDEN: tuple[tuple[str, str, str, tuple[str, ...]], ...] = (
    ("optuna.storages.journal._storage", "JournalStorageReplayResult", "_apply_create_trial", ("log",)),
    ("optuna.storages.journal._storage", "JournalStorageReplayResult", "_apply_set_trial_state_values", ("log",)),
    ("optuna.storages", "JournalStorage", "_sync_with_backend", ()),
    ("optuna.storages", "RDBStorage", "_get_trials",
     ("study_id", "states", "included_trial_ids", "trial_id_greater_than")),
    ("optuna.storages", "RDBStorage", "_get_stale_trial_ids", ("study_id",)),
    ("optuna.storages", "RDBStorage", "_create_new_trial", ("study_id", "template_trial")),
    ("optuna.storages", "RDBStorage", "_set_trial_param",
     ("trial_id", "param_name", "param_value_internal", "distribution", "previous_distribution")),
    ("optuna.storages._cached_storage", "_CachedStorage", "_add_trials_to_cache", ("study_id", "trials")),
    ("optuna", "Study", "_get_trials", ("deepcopy", "states", "use_cache")),
)

#: Optuna's private attributes our storages read or set: (module, class, attribute). The packed
#: journal's replay reads the replay result's trials; its storage's ``__init__`` is Optuna's with
#: our replay, so it sets what Optuna's sets.
ATTRIBUTES: tuple[tuple[str, str, str], ...] = (
    ("optuna.storages.journal._storage", "JournalStorageReplayResult", "_trials"),
    ("optuna.storages._cached_storage", "_CachedStorage", "_backend"),
    ("optuna.storages._cached_storage", "_CachedStorage", "_lock"),
    ("optuna.storages._cached_storage", "_CachedStorage", "_studies"),
    ("optuna.storages", "JournalStorage", "_worker_id_prefix"),
    ("optuna.storages", "JournalStorage", "_backend"),
    ("optuna.storages", "JournalStorage", "_thread_lock"),
    ("optuna.storages", "JournalStorage", "_replay_result"),
    ("optuna.samplers", "TPESampler", "_gamma"),
    ("optuna", "Study", "_storage"),
    ("optuna", "Study", "_study_id"),
    ("optuna", "Trial", "_trial_id"),
    ("optuna.trial", "FrozenTrial", "_trial_id"),
)
