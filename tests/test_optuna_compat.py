"""Every private Optuna touchpoint of ``tuner/store/optuna_compat.py``, against the installed Optuna.

One test per touchpoint: an Optuna release that moves, renames or re-signs one fails here by
name, instead of a study failing in the field. A last test holds the rule itself: no module of
the project imports a private Optuna module except the compat module.
"""

import ast
import datetime
import importlib
import inspect
import subprocess
import sys

import numpy as np
import optuna
import pytest
from optuna.distributions import FloatDistribution
from optuna.trial import FrozenTrial, TrialState

from conftest import ROOT
from tuner.store import optuna_compat as compat


def _study(storage=None):
    return optuna.create_study(storage=storage, sampler=optuna.samplers.RandomSampler(seed=0))


def test_journal_private_names_are_the_ones_we_subclass_and_read():
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend
    assert issubclass(JournalStorage, object) and inspect.isclass(compat.JournalStorageReplayResult)
    assert inspect.isabstract(compat.BaseJournalFileLock)
    assert {"acquire", "release"} <= set(compat.BaseJournalFileLock.__abstractmethods__)
    assert inspect.isclass(compat.BaseJournalSnapshot)
    # the op codes our packed replay and the torn-journal repair read
    for op in ("CREATE_STUDY", "CREATE_TRIAL", "SET_TRIAL_PARAM", "SET_TRIAL_STATE_VALUES",
               "SET_TRIAL_USER_ATTR", "SET_TRIAL_SYSTEM_ATTR"):
        assert isinstance(getattr(compat.JournalOperation, op).value, int), op
    assert "lock_obj" in inspect.signature(JournalFileBackend).parameters


def test_the_tpe_default_splits_are_callables_of_a_count():
    assert compat.default_gamma(100) == min(int(np.ceil(0.1 * 100)), 25)
    assert 1 <= compat.default_gamma_multiobjective(100) <= 100


def test_set_tpe_gamma_is_what_tpe_reads():
    sampler = optuna.samplers.TPESampler(seed=0, n_startup_trials=2)
    calls = []

    def gamma(n):
        calls.append(n)
        return 1
    compat.set_tpe_gamma(sampler, gamma)
    study = optuna.create_study(sampler=sampler)
    study.optimize(lambda t: t.suggest_float("x", 0.0, 1.0) ** 2, n_trials=5)
    assert calls, "TPE no longer reads _gamma: WindowedTPESampler's split would be ignored"


def test_trial_and_study_ids():
    study = _study()
    trial = study.ask()
    assert compat.study_storage(study) is study._storage
    assert compat.trial_id(trial) == compat.study_storage(study).get_trial_id_from_study_id_trial_number(
        compat.study_id(study), trial.number)
    frozen = compat.study_storage(study).get_trial(compat.trial_id(trial))
    assert compat.trial_id(frozen) == compat.trial_id(trial)


@pytest.mark.parametrize("module,cls,attr", compat.ATTRIBUTES)
def test_private_attributes_exist_on_live_objects(module, cls, attr, tmp_path):
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend
    kind = getattr(importlib.import_module(module), cls)
    if cls == "JournalStorageReplayResult":
        obj = kind("prefix-")
    elif cls == "JournalStorage":
        obj = JournalStorage(JournalFileBackend(str(tmp_path / "j.log")))
    elif cls == "_CachedStorage":
        obj = optuna.storages.get_storage(f"sqlite:///{tmp_path / 's.db'}")
        assert isinstance(obj, kind)
    elif cls == "TPESampler":
        obj = kind(seed=0)
    elif cls in ("Study", "Trial"):
        study = _study()
        obj = study if cls == "Study" else study.ask()
    else:
        obj = _study().ask()
        obj = compat.study_storage(obj.study).get_trial(obj._trial_id)
    assert hasattr(obj, attr), f"{cls}.{attr} is gone in optuna {optuna.__version__}"


@pytest.mark.parametrize("module,cls,method,args", compat.OVERRIDDEN, ids=lambda v: str(v))
def test_overridden_private_methods_keep_their_arguments(module, cls, method, args):
    kind = getattr(importlib.import_module(module), cls)
    fn = getattr(kind, method, None)
    assert callable(fn), f"{cls}.{method} is gone in optuna {optuna.__version__}"
    assert tuple(inspect.signature(fn).parameters)[1:] == args


def test_frozen_trial_fields_in_constructor_order():
    t = FrozenTrial(number=0, state=TrialState.COMPLETE, value=1.0,
                    datetime_start=datetime.datetime.now(), datetime_complete=datetime.datetime.now(),
                    params={"x": 0.5}, distributions={"x": FloatDistribution(0, 1)}, user_attrs={},
                    system_attrs={}, intermediate_values={}, trial_id=3)
    assert tuple(t.__dict__) == compat.FROZEN_TRIAL_FIELDS


def test_stale_trial_ids_and_cached_backend(tmp_path):
    storage = optuna.storages.RDBStorage(f"sqlite:///{tmp_path / 'h.db'}", heartbeat_interval=60)
    study = _study(storage)
    study.ask()
    assert compat.cached_backend(storage) is storage
    assert compat.stale_trial_ids(storage, compat.study_id(study)) == []
    cached = optuna.storages.get_storage(f"sqlite:///{tmp_path / 'c.db'}")
    assert isinstance(compat.cached_backend(cached), optuna.storages.RDBStorage)


def test_rdb_models_and_into_cache(tmp_path):
    models = compat.rdb_models()
    assert {"trials", "trial_params", "trial_values"} <= {
        m.__tablename__ for m in (models.TrialModel, models.TrialParamModel, models.TrialValueModel)}
    cached = optuna.storages.get_storage(f"sqlite:///{tmp_path / 'c.db'}")
    study = _study(cached)
    tid = cached.create_new_trial(compat.study_id(study))
    frozen = compat.cached_backend(cached).get_trial(tid)
    compat.into_cache(cached, compat.study_id(study), frozen)
    # the trial is where a write of its parameters looks for it
    cached.set_trial_param(tid, "x", 0.5, FloatDistribution(0, 1))
    assert cached.get_trial(tid).params == {"x": 0.5}
    compat.into_cache(optuna.storages.InMemoryStorage(), 0, frozen)      # no cache: nothing to do


def test_scipy_log_ndtr_is_in_use_once_a_windowed_sampler_is_made():
    from scipy.special import log_ndtr
    from tuner.store.history import WindowedTPESampler
    WindowedTPESampler({"x": FloatDistribution(0, 1)}, seed=0)      # puts it in place
    assert compat.log_ndtr_in_use() is log_ndtr
    own = compat.use_scipy_log_ndtr()          # again: idempotent, returns Optuna's own
    assert callable(own) and own is not log_ndtr


def test_importing_the_project_changes_nothing_in_optuna():
    """No monkeypatch runs at import: every module of the house imported, TPE's truncated normal
    still calls Optuna's own log normal CDF (a fresh interpreter: this one may have made a sampler)."""
    code = ("import importlib, pathlib, sys\n"
            "for p in sorted(pathlib.Path('tuner').rglob('*.py')):\n"
            "    mod = '.'.join(p.with_suffix('').parts)\n"
            "    mod = mod[:-len('.__init__')] if mod.endswith('.__init__') else mod\n"
            "    if not mod.endswith('__main__'): importlib.import_module(mod)\n"
            "from scipy.special import log_ndtr\n"
            "from tuner.store import optuna_compat as c\n"
            "sys.exit(0 if c.log_ndtr_in_use() is not log_ndtr else 3)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]


def _private_names():
    """Every private name of Optuna's the compat module declares (attributes and methods)."""
    return {a for _, _, a in compat.ATTRIBUTES} | {m for _, _, m, _ in compat.OVERRIDDEN}


def _private_touches(path, names):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    where = path.relative_to(ROOT) if ROOT in path.parents else path.name
    return [f"{where}:{node.lineno} {getattr(node, 'attr', getattr(node, 'name', 'getattr'))}"
            for node in ast.walk(tree)
            if (isinstance(node, ast.Attribute) and node.attr in names)
            or (isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in names)
            or (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("getattr", "setattr")
                and len(node.args) > 1 and isinstance(node.args[1], ast.Constant) and node.args[1].value in names)]


def test_no_module_outside_the_store_touches_optunas_private_attributes():
    """Outside ``tuner/store/``, no module of the house reads, sets or implements a private name of
    Optuna's that the compat module declares (``study._storage``, ``Study._get_trials``, ...)."""
    names = _private_names()
    files = [p for d in ("tuner", "gaits") for p in (ROOT / d).rglob("*.py")
             if (ROOT / "tuner" / "store") not in p.parents]
    assert [f for p in files for f in _private_touches(p, names)] == []


def test_the_private_touch_scan_can_fail(tmp_path):
    bad = tmp_path / "probe.py"
    bad.write_text("def f(study):\n    return study._storage\nclass V:\n    def _get_trials(self):\n        return []\n"
                   "g = getattr(object(), '_study_id', None)\n")
    assert sorted(f.split()[-1] for f in _private_touches(bad, _private_names())) == ["_get_trials", "_storage", "getattr"]


def _private_optuna_imports(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for n in names:
            parts = n.split(".")
            if parts[0] == "optuna" and any(p.startswith("_") for p in parts[1:]):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {n}")
    return found


def test_no_private_optuna_import_outside_the_compat_module():
    files = [p for d in ("tuner", "gaits", "tests", "benchmarks", "notebooks", "examples")
             for p in (ROOT / d).rglob("*.py") if p.name != "optuna_compat.py"]
    found = [f for p in files for f in _private_optuna_imports(p)]
    assert found == []


def test_enqueued_params_are_where_enqueue_trial_keeps_them():
    study = _study()
    study.enqueue_trial({"x": 0.25})
    waiting = study.get_trials(deepcopy=False)[0]
    assert compat.enqueued_params(waiting) == {"x": 0.25} and waiting.params == {}
    popped = study.ask()                    # pops the waiting one
    fresh = study.ask()
    assert popped.number == 0 and compat.enqueued_params(study.get_trials(deepcopy=False)[fresh.number]) == {}
