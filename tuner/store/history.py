"""What a worker knows of its study, kept up to date with constant work per trial.

A worker used to scan every trial of the study several times per trial (the count under the
budget lock, the duplicate check, the sampler's history), so a study cost O(n^2) and the shared
lock was held longer as the study grew. :class:`TrialIndex` reads each trial once, when it
first sees it finished, and keeps only what the worker needs of it:

* counts of finished, running and failed trials (exact at each :meth:`TrialIndex.refresh`,
  which the worker calls under the budget lock);
* a key of every finished trial's parameters, to find a set walked before without a scan;
* a bounded *window* for the sampler: the study's best ``n_best`` feasible trials (single
  objective: by value; several objectives: the newest ``n_best`` of the non-dominated front),
  the ``n_recent`` latest finished trials, and the running ones (for the constant liar).

:class:`WindowedTPESampler` is Optuna's multivariate TPE given that window instead of every
trial. Ours, and what it costs: TPE splits the trials into the best ``min(ceil(n/10), 25)``
(several objectives: ``ceil(n/10)``) and the rest; the window keeps the study's best 30, and the
split is computed from the study's count n, not the window's, so the "good" density is the
one the whole history gives (several objectives: at most 30 good trials); the "rest" density
is estimated from the latest 170 trials instead of all of them. Up to 200 trials the window
*is* the history and the samples are TPE's own (tested); beyond it the sampler's cost stays
flat. ``benchmarks/bench_scale.py`` measures the cost; ``benchmarks/bench_sampler_quality.py``
the best found with and without the window (on a smooth 8-dimensional bowl after 600 trials,
median of 5 seeds: 0.0015 against TPE's 0.0012; with the latest 90 only, 0.0024).

On the journal, reads go through Optuna's storage interface (a trial's id by number,
``get_trial``, trials by state). On a database (:class:`~tuner.store.rdb.LeanRDBStorage`) they
go around Optuna's cache, which would keep every trial the worker reads
(:meth:`~tuner.store.rdb.LeanRDBStorage.read_trials`): a worker keeps only what the index
keeps, and under the budget lock it recounts the states in one statement (:meth:`TrialIndex.recount`).
"""

from __future__ import annotations

import datetime
import heapq
import itertools
from collections import deque
from typing import Any, Sequence

import optuna
from optuna.distributions import BaseDistribution
from optuna.storages import JournalStorage
from optuna.study import StudyDirection
from optuna.trial import FrozenTrial, TrialState

from .journal import unpacked
from . import optuna_compat as compat
from .rdb import lean

__all__ = ["DONE_STATES", "TrialIndex", "WindowedTPESampler", "params_key", "N_BEST", "N_RECENT"]

#: The window's size (ours): the best trials kept, and the latest ones. (A uniform sample of
#: the whole history in place of half the latest was tried and made the search worse on the bowl
#: of ``benchmarks/bench_sampler_quality.py``: 0.0035 against 0.0024 at 30 + 90.)
N_BEST = 30
N_RECENT = 170

#: A trial that is over and counts toward a study's budget (a failed one does not).
DONE_STATES = (TrialState.COMPLETE, TrialState.PRUNED)
_UNFINISHED = (TrialState.RUNNING, TrialState.WAITING)


#: TPE draws from truncated normals; Optuna 5.x evaluates their log normal CDF element by element
#: in Python. Late in a long study the kernels are narrow, the bounds sit far in their tails, and
#: the Newton inversion calls it a thousand times a trial: at 10k trials that was most of the
#: sampling time (``benchmarks/bench_scale.py``). SciPy's ``special.log_ndtr`` is the same function
#: in C; ours is to put it in place of Optuna's, in this process, when the first
#: :class:`WindowedTPESampler` is made (nothing is changed by importing this module), where that
#: private function exists as expected (:func:`optuna_compat.use_scipy_log_ndtr`). They agree to
#: 1e-12 of the value (tested, ``tests/test_history.py``); draws may differ from an unpatched
#: Optuna's in their last bits, a seeded study still gives the same draws on every run.


def params_key(params: dict[str, Any]) -> int:
    """A hash of a parameter set (candidates only: a match is confirmed on the trial itself)."""
    return hash(tuple(sorted(params.items())))


def _feasible(t: FrozenTrial) -> bool:
    return all(c <= 0.0 for c in (t.system_attrs.get("constraints") or ()))


def _dominates(a: Sequence[float], b: Sequence[float]) -> bool:
    return all(x <= y for x, y in zip(a, b)) and any(x < y for x, y in zip(a, b))


class TrialIndex:
    """An incremental view of one study's trials in one process (see the module docstring)."""

    def __init__(self, n_best: int = N_BEST, n_recent: int = N_RECENT) -> None:
        self.n_best = n_best
        self.n_recent = n_recent
        self._source: Any = None
        self._study_id: int | None = None
        self._signs: tuple[float, ...] = ()
        self.seen = 0                                   # trials numbered below this were read
        self._unfinished: dict[int, int] = {}           # number -> trial id, read while unfinished
        self.n_done = 0                                 # finished as COMPLETE or PRUNED
        self.running: list[FrozenTrial] = []            # RUNNING at the last refresh
        self.waiting: list[FrozenTrial] = []            # WAITING (enqueued) at the last refresh
        self.failed: list[FrozenTrial] = []             # every FAIL trial read
        self._by_params: dict[int, list[int]] = {}      # params_key -> ids of DONE trials
        self._best: list[tuple[float, int, FrozenTrial]] = []   # single objective: a max-heap by -key
        self._front: list[tuple[tuple[float, ...], FrozenTrial]] = []   # several: non-dominated
        self._recent: deque[FrozenTrial] = deque(maxlen=n_recent)
        self._tie = itertools.count()
        self._pending_done = 0                          # finished at the last recount, not yet read
        self._last_id = -1                              # a database: the largest trial id read
        self._curves: list[_Curve] = []                 # every COMPLETE trial's intermediate values

    def _bind(self, study: optuna.Study) -> None:
        if self._source is None:
            self._source = compat.study_storage(study)
            self._study_id = compat.study_id(study)
            self._signs = tuple(1.0 if d == StudyDirection.MINIMIZE else -1.0 for d in study.directions)

    def refresh(self, study: optuna.Study) -> "TrialIndex":
        """Read the trials created since the last refresh and those that finished since; the
        counts are exact for the storage's state at this call. The first call reads the whole
        study once (call it before taking the budget lock); later calls do constant work: new
        trials are found by number, the unfinished ones re-read (by id from the journal, which
        holds them in memory; in one query by state from a database, whose Optuna cache then
        reads only the unfinished and newer rows), never the whole study."""
        storage = self._source
        if storage is None:
            self._bind(study)
            storage = self._source
        rdb = lean(storage)
        if rdb is not None:
            return self._refresh_lean(rdb)
        if self.seen == 0 and not self._unfinished:
            for t in storage.get_all_trials(self._study_id, deepcopy=False):
                if t.state.is_finished():
                    self._absorb(t)
                else:
                    self._unfinished[t.number] = compat.trial_id(t)
                self.seen = max(self.seen, t.number + 1)
        sid = self._study_id
        journal = isinstance(storage, JournalStorage)
        # a database: this query also brings a trial popped from the queue into Optuna's cache,
        # where it must be before this process writes to it
        now = {} if journal else {t.number: t for t in
                                  storage.get_all_trials(sid, deepcopy=False, states=_UNFINISHED)}
        while True:
            try:
                tid = storage.get_trial_id_from_study_id_trial_number(sid, self.seen)
            except KeyError:
                break
            self._unfinished[self.seen] = tid
            self.seen += 1
        for number, tid in list(self._unfinished.items()):
            t = now.get(number)
            if t is None:
                t = storage.get_trial(tid)
            if t.state.is_finished():
                del self._unfinished[number]
                now.pop(number, None)
                self._absorb(t)
            else:
                now[number] = t
        self.running = [t for t in now.values() if t.state == TrialState.RUNNING]
        self.waiting = [t for t in now.values() if t.state == TrialState.WAITING]
        self._pending_done = 0
        return self

    #: trials per read when a worker first reads a study from a database
    READ_CHUNK = 500

    def _refresh_lean(self, rdb: Any) -> "TrialIndex":
        """:meth:`refresh` on a database: read through :meth:`LeanRDBStorage.read_trials`, not
        Optuna's cache, so that this process keeps only what the index keeps (the first read in
        chunks of :data:`READ_CHUNK` trials by number; later reads: the new trials and the
        unfinished ones, two statements)."""
        sid = self._study_id
        if self.seen == 0 and not self._unfinished:
            while True:
                chunk = rdb.read_trials(sid, self._last_id, (), limit=self.READ_CHUNK)
                self._take(chunk, {})
                if len(chunk) < self.READ_CHUNK:
                    break
        now: dict[int, FrozenTrial] = {}
        self._take(rdb.read_trials(sid, self._last_id, self._unfinished.values()), now)
        self.running = [t for t in now.values() if t.state == TrialState.RUNNING]
        self.waiting = [t for t in now.values() if t.state == TrialState.WAITING]
        self._pending_done = 0
        return self

    def _take(self, trials: list[FrozenTrial], now: dict[int, FrozenTrial]) -> None:
        for t in sorted(trials, key=lambda t: t.number):
            self.seen = max(self.seen, t.number + 1)
            self._last_id = max(self._last_id, compat.trial_id(t))
            if t.state.is_finished():
                self._unfinished.pop(t.number, None)
                self._absorb(t)
            else:
                self._unfinished[t.number] = compat.trial_id(t)
                now[t.number] = t

    def recount(self, study: optuna.Study, attr: str = "budget") -> Any:
        """The counts exact for the storage's state at this call, for the budget lock; returns
        the study's user attribute ``attr``. On a database (:class:`~tuner.store.rdb.LeanRDBStorage`)
        one statement reads the states of the trials created or unfinished since the last
        :meth:`refresh` (which the worker makes before taking the lock) and the attribute:
        ``n_done``, ``running`` and ``waiting`` are set from them, the trials themselves are read
        at the next refresh (``running`` then holds the running trials read at the last refresh
        plus any found running now, as ids only). The journal holds the study in memory: a
        :meth:`refresh`."""
        rdb = lean(self._source) if self._source is not None else None
        if rdb is None:
            self.refresh(study)
            return study.user_attrs.get(attr)
        rows, value = rdb.trial_states(self._study_id, self._last_id, self._unfinished.values(), attr)
        known = {t.number: t for t in self.running}
        self._pending_done = sum(1 for _, _, st in rows if st in DONE_STATES)
        self.running = [known.get(n) or _Stub(tid, n, st) for tid, n, st in rows if st == TrialState.RUNNING]
        self.waiting = [_Stub(tid, n, st) for tid, n, st in rows if st == TrialState.WAITING]
        return value

    @property
    def n_done_now(self) -> int:
        """Finished trials at the last :meth:`recount` (or :meth:`refresh`)."""
        return self.n_done + self._pending_done

    @property
    def n_running(self) -> int:
        return len(self.running)

    @property
    def running_read(self) -> list[FrozenTrial]:
        """The running trials read whole (a recount's new ones are known by id only)."""
        return [t for t in self.running if not isinstance(t, _Stub)]

    def reserve(self, study: optuna.Study, user_attrs: dict[str, Any] | None = None) -> optuna.Trial:
        """A trial for this process: the oldest waiting one (an enqueued start or retry) if
        another process has not taken it, else a new one; as ``Study.ask()`` does, but from the
        index's waiting trials instead of a scan of the study. ``user_attrs`` are stored with it
        (a new trial: in the write that creates it). Sampling is left to the caller (relative
        parameters are sampled at the first ``suggest``)."""
        storage = self._source
        attrs = dict(user_attrs or {})
        rdb = lean(storage)
        for t in sorted(self.waiting, key=lambda t: t.number):
            try:
                if rdb is not None:
                    # a database: popped with its worker in one write; the index reads around
                    # Optuna's cache, where the trial must be before its parameters are written
                    if rdb.claim(compat.trial_id(t), attrs):
                        compat.into_cache(storage, self._study_id, storage.get_trial(compat.trial_id(t)))
                        return optuna.Trial(study, compat.trial_id(t))
                elif storage.set_trial_state_values(compat.trial_id(t), state=TrialState.RUNNING):
                    for k, v in attrs.items():
                        storage.set_trial_user_attr(compat.trial_id(t), k, v)
                    return optuna.Trial(study, compat.trial_id(t))
            except optuna.exceptions.UpdateFinishedTrialError:
                continue
        template = None
        if attrs:
            template = FrozenTrial(number=-1, state=TrialState.RUNNING, value=None, values=None,
                                   datetime_start=datetime.datetime.now(), datetime_complete=None,
                                   params={}, distributions={}, user_attrs=attrs, system_attrs={},
                                   intermediate_values={}, trial_id=-1)
        return optuna.Trial(study, storage.create_new_trial(self._study_id, template))

    def _absorb(self, t: FrozenTrial) -> None:
        if t.state.is_finished():
            t = unpacked(t)             # the journal's packed trial: the index keeps it whole
        if t.state == TrialState.FAIL:
            self.failed.append(t)
        if t.state not in DONE_STATES:
            return
        self.n_done += 1
        if t.state == TrialState.COMPLETE:
            self._curves.append(_Curve(t.intermediate_values) if t.intermediate_values else _NO_CURVE)
        self._by_params.setdefault(params_key(t.params), []).append(compat.trial_id(t))
        self._recent.append(t)
        if t.state != TrialState.COMPLETE or not _feasible(t) or t.values is None:
            return
        if len(self._signs) == 1:
            key = self._signs[0] * t.values[0]
            item = (-key, next(self._tie), t)
            if len(self._best) < self.n_best:
                heapq.heappush(self._best, item)
            elif key < -self._best[0][0]:
                heapq.heapreplace(self._best, item)
            return
        v = tuple(s * x for s, x in zip(self._signs, t.values))
        if any(_dominates(w, v) or w == v for w, _ in self._front):
            return
        self._front = [(w, u) for w, u in self._front if not _dominates(v, w)] + [(v, t)]
        if len(self._front) > self.n_best:
            self._front.pop(0)                          # the oldest member leaves the window

    def duplicate_of(self, trial: optuna.Trial) -> FrozenTrial | None:
        """A finished trial (COMPLETE or PRUNED) that walked exactly ``trial``'s parameters."""
        params = trial.params
        for tid in self._by_params.get(params_key(params), ()):
            t = self._source.get_trial(tid)
            if t.params == params and t.number != trial.number:
                return t
        return None

    def window(self) -> list[FrozenTrial]:
        """The sampler's trials: the best, the latest finished, the running; by number."""
        best = [t for _, _, t in self._best] + [t for _, t in self._front]
        out = {t.number: t for t in itertools.chain(best, self._recent, self.running_read)}
        return [out[k] for k in sorted(out)]


class _Stub:
    """A trial a :meth:`TrialIndex.recount` found, known by its id, number and state only (the
    reaper and the reservation need no more; the next refresh reads it whole)."""

    def __init__(self, trial_id: int, number: int, state: TrialState) -> None:
        self._trial_id, self.number, self.state = trial_id, number, state
        self.user_attrs: dict[str, Any] = {}
        self.datetime_start = None


class _WindowStudy:
    """The study as the sampler sees it: its trials are the index's window."""

    def __init__(self, study: optuna.Study, trials: list[FrozenTrial]) -> None:
        self._study = study
        self._trials = trials

    def _get_trials(self, deepcopy: bool = True, states: Any = None, use_cache: bool = False) -> list[FrozenTrial]:
        return [t for t in self._trials if states is None or t.state in states]

    def get_trials(self, deepcopy: bool = True, states: Any = None) -> list[FrozenTrial]:
        return self._get_trials(deepcopy, states)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._study, name)


class _Curve:
    """A completed trial as the median pruner reads it: its intermediate values only."""
    __slots__ = ("intermediate_values",)
    state = TrialState.COMPLETE

    def __init__(self, values: dict[int, float]) -> None:
        self.intermediate_values = values


_NO_CURVE = _Curve({})       # a completed trial that reported nothing (one shared object)


class _CurveStudy(_WindowStudy):
    """The study as the pruner sees it: its completed trials are the index's curves (returned
    as they are: every curve is a completed trial, so no filter runs over the study)."""

    def _get_trials(self, deepcopy: bool = True, states: Any = None, use_cache: bool = False) -> list[Any]:
        if tuple(states or ()) != (TrialState.COMPLETE,):
            return self._study.get_trials(deepcopy=deepcopy, states=states)
        return self._trials


class IndexedMedianPruner(optuna.pruners.MedianPruner):
    """Optuna's median pruner (its decision, unchanged) reading the completed trials'
    intermediate values from a worker's :class:`TrialIndex` instead of the whole study (ours).

    Optuna's reads every completed trial at every ``should_prune``: on a database that pulls the
    whole study into Optuna's cache, so a worker's memory grew with the study again (a study of
    several surfaces prunes). The index keeps each completed trial's intermediate values (a few
    numbers; the journal's packed trial keeps the same dict), as of the index's last read: trials
    that completed while this trial walked are not yet among them, where Optuna's would read them
    (with one worker nothing differs; with several, the median of a few trials fewer)."""

    def __init__(self, index: TrialIndex, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._index = index

    def prune(self, study: optuna.Study, trial: FrozenTrial) -> bool:
        if self._index._source is None:             # not read yet: Optuna's own reading
            return super().prune(study, trial)
        return super().prune(_CurveStudy(study, self._index._curves), trial)  # type: ignore[arg-type]


class WindowedTPESampler(optuna.samplers.TPESampler):
    """Multivariate TPE over a study's fixed space, reading the :class:`TrialIndex` window
    (see the module docstring). ``index`` may be shared with the worker that refreshes it
    under the budget lock; the sampler refreshes it once per trial itself as well, so that the
    running trials it lies about (``constant_liar``) are the current ones."""

    def __init__(self, space: dict[str, BaseDistribution], index: TrialIndex | None = None, **kw: Any) -> None:
        kw.setdefault("multivariate", True)
        super().__init__(**kw)
        compat.use_scipy_log_ndtr()                     # see the note above params_key
        compat.set_tpe_gamma(self, self._good)
        # sorted by name, as Optuna's own inferred space is: the same draws in the same order
        self._space = {k: space[k] for k in sorted(space) if not space[k].single()}
        self.index = index or TrialIndex()
        self._fresh_for: int | None = None

    def _good(self, n: int) -> int:
        """How many of the window's ``n`` trials are "good": Optuna's default for the *study's*
        count of finished trials (not the window's), at most the window's best."""
        ix = self.index
        full = (compat.default_gamma if len(ix._signs) <= 1 else compat.default_gamma_multiobjective)(ix.n_done)
        return min(full, n) if ix.n_done <= n else min(full, n, ix.n_best)

    def mark_fresh(self, number: int) -> None:
        """The index was refreshed for trial ``number`` (the worker's refresh under the budget
        lock, just before it reserved the trial): sampling it reads no more of the storage. A
        trial another worker reserves in between is not lied about; TPE leaves the trial being
        sampled out of its own history, so one worker's draws are the same either way."""
        self._fresh_for = number

    def _view(self, study: optuna.Study, trial: FrozenTrial) -> _WindowStudy:
        if self._fresh_for != trial.number:
            self.index.refresh(study)
            self._fresh_for = trial.number
        return _WindowStudy(study, self.index.window())

    def infer_relative_search_space(self, study: optuna.Study, trial: FrozenTrial) -> dict[str, BaseDistribution]:
        return dict(self._space)

    def sample_relative(self, study: optuna.Study, trial: FrozenTrial,
                        search_space: dict[str, BaseDistribution]) -> dict[str, Any]:
        return super().sample_relative(self._view(study, trial), trial, search_space)

    def sample_independent(self, study: optuna.Study, trial: FrozenTrial, param_name: str,
                           param_distribution: BaseDistribution) -> Any:
        return super().sample_independent(self._view(study, trial), trial, param_name, param_distribution)
