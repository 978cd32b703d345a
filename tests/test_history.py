"""Constant work per trial: the worker's incremental index of its study, the windowed sampler,
the budget lock free of study scans, and one fsync per trial in the journal."""

from dataclasses import replace

import optuna
import pytest
from optuna.distributions import FloatDistribution
from optuna.storages import InMemoryStorage, JournalStorage
from optuna.trial import TrialState

from tuner.store import history
from tuner.store.history import TrialIndex, WindowedTPESampler
from tuner.store.journal import PackedJournalStorage, SafeJournalBackend

optuna.logging.set_verbosity(optuna.logging.WARNING)

SPACE = {"x": FloatDistribution(-1.0, 1.0), "y": FloatDistribution(-1.0, 1.0)}


def _storage(kind, tmp_path):
    if kind == "journal":
        return PackedJournalStorage(SafeJournalBackend(tmp_path / "s.journal"))   # as gait-tuner opens it
    return InMemoryStorage()            # the database branch (states by query)


def _add(study, state, value=None, x=0.0, constraint=-1.0):
    t = optuna.trial.create_trial(state=state, value=value if state == TrialState.COMPLETE else None,
                                  params={"x": x, "y": 0.0}, distributions=SPACE,
                                  system_attrs={"constraints": [constraint]})
    study.add_trial(t)


def _scan(study):
    ts = study.get_trials(deepcopy=False)
    return (sum(t.state in (TrialState.COMPLETE, TrialState.PRUNED) for t in ts),
            sorted(t.number for t in ts if t.state == TrialState.RUNNING),
            sorted(t.number for t in ts if t.state == TrialState.WAITING),
            sorted(t.number for t in ts if t.state == TrialState.FAIL))


def _index_view(ix):
    return (ix.n_done, sorted(t.number for t in ix.running), sorted(t.number for t in ix.waiting),
            sorted(t.number for t in ix.failed))


@pytest.mark.parametrize("kind", ["journal", "database"])
def test_index_counts_match_a_scan_of_the_study_as_it_changes(kind, tmp_path):
    study = optuna.create_study(storage=_storage(kind, tmp_path), study_name="ix")
    for i in range(6):
        _add(study, TrialState.COMPLETE, value=float(i), x=i / 10)
    _add(study, TrialState.PRUNED, x=0.9)
    _add(study, TrialState.FAIL, x=0.8)
    running = study.ask()
    study.enqueue_trial({"x": 0.5, "y": 0.0})
    ix = TrialIndex().refresh(study)
    assert _index_view(ix) == _scan(study) == (7, [8], [9], [7])
    # another process finishes one, pops the queue, adds trials: the next refresh sees it all
    study.tell(running, 3.0)
    popped = study.ask()
    assert popped.number == 9
    fresh = study.ask()
    _add(study, TrialState.COMPLETE, value=0.5, x=0.33)
    ix.refresh(study)
    assert _index_view(ix) == _scan(study) == (9, [9, 10], [], [7])
    study.tell(popped, state=TrialState.FAIL)
    study.tell(fresh, 1.0)
    ix.refresh(study)
    assert _index_view(ix) == _scan(study) == (10, [], [], [7, 9])


@pytest.mark.parametrize("kind", ["journal", "database"])
def test_reserve_pops_the_oldest_waiting_trial_then_creates(kind, tmp_path):
    study = optuna.create_study(storage=_storage(kind, tmp_path), study_name="res")
    study.enqueue_trial({"x": 0.25, "y": 0.0})
    study.enqueue_trial({"x": 0.5, "y": 0.0})
    ix = TrialIndex().refresh(study)
    a = ix.reserve(study)
    assert a.number == 0 and a.suggest_float("x", -1, 1) == 0.25
    ix.refresh(study)
    b = ix.reserve(study)
    assert b.number == 1
    ix.refresh(study)
    c = ix.reserve(study)
    assert c.number == 2 and ix.refresh(study).n_running == 3


def test_duplicate_is_confirmed_on_the_trial_not_the_hash(monkeypatch, tmp_path):
    monkeypatch.setattr(history, "params_key", lambda params: 0)        # every set collides
    study = optuna.create_study(storage=_storage("journal", tmp_path), study_name="dup")
    for x in (0.1, 0.2, 0.3):
        _add(study, TrialState.COMPLETE, value=x, x=x)
    _add(study, TrialState.FAIL, x=0.4)              # a failed walk is no source
    ix = TrialIndex().refresh(study)
    for x, want in ((0.2, 1), (0.4, None), (0.7, None)):
        t = study.ask()
        study._storage.set_trial_param(t._trial_id, "x", x, SPACE["x"])
        study._storage.set_trial_param(t._trial_id, "y", 0.0, SPACE["y"])
        found = ix.duplicate_of(optuna.Trial(study, t._trial_id))
        assert (found.number if found else None) == want
        study.tell(t, 9.0)
        ix.refresh(study)


@pytest.mark.parametrize("direction", ["minimize", "maximize"])
def test_window_holds_the_best_feasible_and_the_latest(direction, tmp_path):
    study = optuna.create_study(storage=_storage("journal", tmp_path), study_name="w", direction=direction)
    values = [5.0, 1.0, 9.0, 3.0, 7.0, 0.5, 8.0, 2.0, 6.0, 4.0, 9.5, 0.1]
    for i, v in enumerate(values):
        _add(study, TrialState.COMPLETE, value=v, x=i / 20, constraint=1.0 if v in (0.1, 9.5) else -1.0)
    ix = TrialIndex(n_best=3, n_recent=4).refresh(study)
    feasible = sorted((v, i) for i, v in enumerate(values) if v not in (0.1, 9.5))
    best = feasible[:3] if direction == "minimize" else feasible[-3:]
    want = {i for _, i in best} | set(range(len(values) - 4, len(values)))
    assert {t.number for t in ix.window()} == want
    assert [t.number for t in ix.window()] == sorted(want)


def test_window_of_several_objectives_keeps_the_non_dominated(tmp_path):
    study = optuna.create_study(storage=_storage("journal", tmp_path), study_name="mo",
                                directions=["minimize", "maximize"])
    pts = [(1.0, 1.0), (2.0, 3.0), (0.5, 0.5), (1.5, 3.0), (3.0, 0.2), (1.0, 2.0)]
    for i, (a, b) in enumerate(pts):
        t = optuna.trial.create_trial(values=[a, b], params={"x": i / 10, "y": 0.0}, distributions=SPACE,
                                      system_attrs={"constraints": [-1.0]})
        study.add_trial(t)
    ix = TrialIndex(n_best=10, n_recent=1).refresh(study)
    front = {t.number for _, t in ix._front}
    assert front == {2, 3, 5}      # (0.5,.5), (1.5,3), (1,2): the others are dominated
    assert {t.number for t in ix.window()} == front | {5}


def _quadratic(trial):
    x, y = trial.suggest_float("x", -1, 1), trial.suggest_float("y", -1, 1)
    return (x - 0.3) ** 2 + (y + 0.2) ** 2


def test_windowed_sampler_samples_what_tpe_samples_while_the_history_fits_the_window(tmp_path):
    runs = []
    for sampler in (WindowedTPESampler(SPACE, seed=3, n_startup_trials=8, constant_liar=True),
                    optuna.samplers.TPESampler(seed=3, multivariate=True, n_startup_trials=8, constant_liar=True)):
        study = optuna.create_study(sampler=sampler)
        study.optimize(_quadratic, n_trials=40)
        runs.append([t.params for t in study.trials])
    assert runs[0] == runs[1]


def test_windowed_sampler_reads_the_window_only(monkeypatch):
    from tuner.store.optuna_compat import tpe_sampler_module as tpe
    seen = []
    split = tpe._split_trials

    def spy(study, trials, n_below):
        seen.append(len(trials))
        return split(study, trials, n_below)
    monkeypatch.setattr(tpe, "_split_trials", spy)
    sampler = WindowedTPESampler(SPACE, TrialIndex(n_best=5, n_recent=10), seed=0, n_startup_trials=4)
    study = optuna.create_study(sampler=sampler)
    study.optimize(_quadratic, n_trials=60)
    assert max(seen) <= 15 and len(seen) >= 50
    assert study.best_value < 0.05          # it still finds the bowl's bottom


def test_a_worker_never_scans_the_study_under_the_budget_lock(monkeypatch, tmp_path):
    """Whatever the study's size, the budget lock's section reads new and unfinished trials
    only: no call lists the study's trials while the lock is held."""
    import contextlib

    from tuner.search import objective, workers
    from tuner.store import storage
    from tuner.search.objective import TrialResult
    from tuner.search.study import load_study

    spec = replace(load_study("quickstart"), name="scan", enqueue=())
    store = storage.StudyStore.open("scan", None, tmp_path / "runs")
    study = workers.open_study(spec, store.optuna_storage(), 0)
    dists = workers.trial_distributions(spec)
    for i in range(40):
        params = {k: d.low + (d.high - d.low) * ((i * 7919 + j * 104729) % 97) / 97
                  for j, (k, d) in enumerate(dists.items())}
        study.add_trial(optuna.trial.create_trial(params=params, distributions=dists, value=float(i),
                                                  system_attrs={"constraints": [-1.0]}))
    canned = TrialResult(score=1.0, speed=0.1, fall_constraint=-1.0, fell=False, per_surface={})
    monkeypatch.setattr(objective.Evaluator, "__post_init__", lambda self: None)
    monkeypatch.setattr(objective.Evaluator, "evaluate", lambda self, drive, report=None: canned)
    held, scans = [False], []
    lock = storage.StudyStore.budget_lock

    @contextlib.contextmanager
    def spying(self, name):
        with lock(self, name):
            held[0] = True
            try:
                yield
            finally:
                held[0] = False
    monkeypatch.setattr(storage.StudyStore, "budget_lock", spying)
    listing = JournalStorage.get_all_trials

    def spy(self, study_id, deepcopy=True, states=None):
        if held[0]:
            scans.append(states)
        return listing(self, study_id, deepcopy, states)
    monkeypatch.setattr(JournalStorage, "get_all_trials", spy)
    assert workers.work(spec, store, 45, 0, log=lambda m: None) == 5
    assert scans == []
    done = [t for t in study.get_trials(deepcopy=False) if t.state == TrialState.COMPLETE]
    assert len(done) == 45


def test_the_journal_syncs_once_per_trial_and_at_once_for_what_must_last(tmp_path):
    backend = SafeJournalBackend(tmp_path / "f.journal")
    study = optuna.create_study(storage=JournalStorage(backend), study_name="f")
    base = backend.fsyncs
    study.enqueue_trial({"x": 0.1, "y": 0.2})            # a start or a retry: durable at once
    assert backend.fsyncs == base + 1
    for _ in range(3):
        t = study.ask()
        t.suggest_float("x", -1, 1)
        t.suggest_float("y", -1, 1)
        t.set_user_attr("worker", {"pid": 1})
        t.set_user_attr("result", {"fell": False})
        t.storage.set_trial_system_attr(t._trial_id, "constraints", [-1.0])
        study.tell(t, 1.0)
    assert backend.fsyncs == base + 1 + 3
    study.set_user_attr("budget", 10)
    assert backend.fsyncs == base + 5
    reread = optuna.load_study(study_name="f", storage=JournalStorage(SafeJournalBackend(tmp_path / "f.journal")))
    assert [t.state for t in reread.trials] == [TrialState.COMPLETE] * 3 and reread.trials[0].params["x"] == 0.1


def test_a_retry_is_enqueued_once_and_an_old_studys_retries_are_found(tmp_path):
    from tuner.store.storage import WORKER_DIED, StudyStore

    store = StudyStore.open("old", None, tmp_path / "runs")
    study = optuna.create_study(storage=store.optuna_storage(), study_name="old")
    died = optuna.trial.create_trial(state=TrialState.FAIL, params={"x": 0.3, "y": 0.0}, distributions=SPACE,
                                     user_attrs={"failed": WORKER_DIED})
    study.add_trial(died)
    study.add_trial(replace_attrs(died, {"failed": WORKER_DIED}))           # trial 1: died too
    study.enqueue_trial({"x": 0.3, "y": 0.0}, user_attrs={"retry_of": 0, "retry_for": 0, "retries": 1})
    notes = store.reap(study)          # trial 0 was retried before the attribute existed; 1 was not
    assert notes == ["trial 1 died with its worker: failed, enqueued again"]
    assert study.user_attrs["retried"] == [0, 1]
    assert store.reap(study) == [] and len(study.trials) == 4


def replace_attrs(t, attrs):
    return optuna.trial.create_trial(state=t.state, params=t.params, distributions=t.distributions, user_attrs=attrs)


def test_the_good_share_follows_the_studys_count_not_the_windows():
    ix = TrialIndex()
    one = WindowedTPESampler(SPACE, ix)
    ix._signs, ix.n_done = (1.0,), 40
    assert one._good(40) == 4                      # within the window: Optuna's own split
    ix.n_done = 1000
    assert one._good(200) == 25                    # beyond it: the study's 1000 trials say 25
    ix._signs = (1.0, -1.0)
    assert one._good(200) == 30                    # several objectives: 100, at most the best kept


def test_a_trial_whose_worker_died_before_sampling_is_failed_not_retried(tmp_path):
    """A worker reserves a trial under the lock and samples after it: one killed in between
    leaves a trial without parameters, which is failed with a note and not walked again."""
    import socket
    import subprocess

    from tuner.store.storage import WORKER_DIED, StudyStore

    gone = subprocess.Popen(["true"])
    gone.wait()
    store = StudyStore.open("pre", None, tmp_path / "runs")
    study = optuna.create_study(storage=store.optuna_storage(), study_name="pre")
    t = study.ask()
    t.set_user_attr("worker", {"host": socket.gethostname(), "pid": gone.pid, "start": 0})
    notes = store.reap(study)
    assert notes == ["trial 0's worker died before it drew the trial's parameters: failed, nothing to walk again"]
    [failed] = study.trials
    assert failed.state == TrialState.FAIL and failed.user_attrs["failed"] == WORKER_DIED
    assert store.reap(study) == [] and len(study.trials) == 1


def test_scipy_log_ndtr_stands_in_for_optunas_own():
    """TPE's truncated normals use SciPy's log Phi in C in place of Optuna 5's element-by-element Python
    (tuner/store/history.py): the same function to 1e-12 of its size (at least 1) over the left tail,
    the centre and the right, where Optuna's series switches branches (-20, 6), and Optuna's sampler
    module uses it."""
    import numpy as np
    from scipy.special import log_ndtr

    from optuna.distributions import FloatDistribution

    from tuner.store import optuna_compat
    WindowedTPESampler({"x": FloatDistribution(0, 1)}, seed=0)
    optuna_own = optuna_compat.use_scipy_log_ndtr()
    assert callable(optuna_own) and optuna_compat.log_ndtr_in_use() is log_ndtr
    x = np.concatenate([np.linspace(-60.0, 12.0, 3001), [-20.0, -20.0 - 1e-9, 6.0, 6.0 + 1e-9, 0.0]])
    ours = optuna_own(x)
    assert np.all(np.abs(ours - log_ndtr(x)) <= 1e-12 * np.maximum(1.0, np.abs(ours)))


def test_a_worker_freezes_what_it_has_read_once_and_every_thousand_trials():
    """The garbage collector would walk the replayed study in every full collection: a worker
    freezes it once read (its first call always does) and again each 1000 trials read since."""
    import gc

    from tuner.search.workers import FREEZE_EVERY, _freeze_history
    try:
        at = _freeze_history(0, -FREEZE_EVERY)                 # the worker's first call
        assert at == 0 and gc.get_freeze_count() > 0
        gc.unfreeze()
        assert _freeze_history(FREEZE_EVERY - 1, at) == at and gc.get_freeze_count() == 0
        assert _freeze_history(FREEZE_EVERY + 5, at) == FREEZE_EVERY + 5 and gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()


@pytest.mark.parametrize("kind", ["journal", "database"])
def test_the_indexed_median_pruner_decides_as_optunas_without_reading_the_study(kind, tmp_path, monkeypatch):
    import random
    from tuner.store.history import IndexedMedianPruner
    study = optuna.create_study(storage=_storage(kind, tmp_path), study_name="m")
    index = TrialIndex()
    ours = IndexedMedianPruner(index, n_startup_trials=3, n_warmup_steps=0)
    theirs = optuna.pruners.MedianPruner(n_startup_trials=3, n_warmup_steps=0)
    reads = []
    listing = optuna.Study.get_trials
    monkeypatch.setattr(optuna.Study, "get_trials",
                        lambda self, *a, **k: reads.append(k.get("states")) or listing(self, *a, **k))
    rng = random.Random(0)
    decisions = []
    for i in range(30):
        index.refresh(study)
        trial = study.ask()
        if i % 7 == 3:                                  # completed without reports, and failed
            study.tell(trial, 1.0) if i % 2 else study.tell(trial, state=TrialState.FAIL)
            continue
        pruned = False
        for step in range(3):
            trial.report(rng.uniform(0.0, 1.0) + 0.1 * step, step)
            frozen = study._storage.get_trial(trial._trial_id)
            reads.clear()
            a = ours.prune(study, frozen)
            assert reads == []                          # the index's curves, not the study
            assert a == theirs.prune(study, frozen)
            decisions.append(a)
            if a:
                pruned = True
                break
        study.tell(trial, state=TrialState.PRUNED) if pruned else study.tell(trial, rng.uniform(0.0, 1.0))
    assert True in decisions and False in decisions
