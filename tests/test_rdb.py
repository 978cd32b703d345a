"""LeanRDBStorage against Optuna's own RDBStorage on the same database (SQLite and PostgreSQL).

Every method ours replaces is checked by writing with one and reading with the other: a trial
written through the deferred path reads back from Optuna's code as the same FrozenTrial, and
Optuna's trials read back from ours as Optuna reads them.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import optuna
import pytest
from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution
from optuna.storages import RDBStorage
from optuna.trial import TrialState

from tuner.store.rdb import LeanRDBStorage, lean

optuna.logging.set_verbosity(optuna.logging.WARNING)

DISTS = {"a": FloatDistribution(0.0, 1.0), "b": FloatDistribution(1e-3, 1.0, log=True),
         "c": IntDistribution(1, 9), "d": CategoricalDistribution(["x", "y", 3])}


@pytest.fixture(scope="module")
def postgres():
    sys.path.insert(0, str(Path(__file__).parent))
    from postgres_server import PostgresServer
    with PostgresServer() as pg:
        yield pg


@pytest.fixture(params=["sqlite", "postgresql"])
def url(request, tmp_path):
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'lean.db'}"
    name = f"lean_{abs(hash(request.node.name)) % 10**8}"
    return request.getfixturevalue("postgres").create_database(name).replace(
        "postgresql://", "postgresql+psycopg://")


def _pair(url):
    """Ours and Optuna's storage on one database, and a study made by Optuna's."""
    theirs = RDBStorage(url)
    ours = LeanRDBStorage(url)
    study = optuna.create_study(storage=theirs, study_name="s", directions=["minimize", "maximize"])
    return ours, theirs, study._study_id


def _same(t1, t2):
    assert (t1.number, t1.state, t1._trial_id) == (t2.number, t2.state, t2._trial_id)
    assert t1.params == t2.params and t1.distributions == t2.distributions
    assert t1.user_attrs == t2.user_attrs and t1.system_attrs == t2.system_attrs
    assert t1.intermediate_values.keys() == t2.intermediate_values.keys()
    for k, v in t1.intermediate_values.items():
        assert v == t2.intermediate_values[k] or (math.isnan(v) and math.isnan(t2.intermediate_values[k]))
    assert t1.values == t2.values
    assert t1.datetime_start == t2.datetime_start and t1.datetime_complete == t2.datetime_complete


def _fill(theirs, sid):
    """Trials of every kind, written by Optuna's code."""
    ids = []
    for i, (state, values) in enumerate([(TrialState.COMPLETE, [0.5, float("inf")]),
                                         (TrialState.PRUNED, None), (TrialState.FAIL, None),
                                         (TrialState.RUNNING, None), (TrialState.COMPLETE, [float("-inf"), 2.0])]):
        tid = theirs.create_new_trial(sid)
        for name, value in (("a", 0.25 + i / 10), ("b", 0.01), ("c", 3 + i), ("d", "y" if i % 2 else 3)):
            theirs.set_trial_param(tid, name, DISTS[name].to_internal_repr(value), DISTS[name])
        theirs.set_trial_user_attr(tid, "result", {"fell": bool(i % 2), "per": [1, 2, {"x": None}]})
        theirs.set_trial_system_attr(tid, "constraints", [float(i) - 2])
        theirs.set_trial_intermediate_value(tid, 0, 1.5 * i)
        theirs.set_trial_intermediate_value(tid, 3, float("nan") if i == 1 else float("inf"))
        if state != TrialState.RUNNING:
            theirs.set_trial_state_values(tid, state, values)
        ids.append(tid)
    return ids


def test_reads_match_optunas(url):
    ours, theirs, sid = _pair(url)
    ids = _fill(theirs, sid)
    for tid in ids:
        _same(ours.get_trial(tid), theirs.get_trial(tid))
    for included, greater in [(set(), -1), ({ids[1], ids[3]}, ids[2]), (set(), ids[3])]:
        a = ours._get_trials(sid, None, included, greater)
        b = theirs._get_trials(sid, None, included, greater)
        assert [t.number for t in a] == [t.number for t in b] and a
        for x, y in zip(a, b):
            _same(x, y)
    a = ours._get_trials(sid, [TrialState.RUNNING, TrialState.WAITING], set(), -1)
    assert [t.number for t in a] == [3]
    assert ours.get_trial_id_from_study_id_trial_number(sid, 2) == ids[2]
    with pytest.raises(KeyError):
        ours.get_trial_id_from_study_id_trial_number(sid, 99)
    with pytest.raises(KeyError):
        ours.get_trial(10**6)
    with pytest.raises(KeyError):
        ours._get_trials(sid + 100, None, set(), -1)
    theirs.set_study_user_attr(sid, "budget", 12)
    theirs.set_study_user_attr(sid, "spec", {"gait": "eros", "surfaces": ["carpet4"]})
    assert ours.get_study_user_attrs(sid) == theirs.get_study_user_attrs(sid)


def test_deferred_writes_are_one_transaction_at_flush_and_at_tell(url):
    ours, theirs, sid = _pair(url)
    _fill(theirs, sid)                              # the study knows the distributions
    cached = optuna.load_study(study_name="s", storage=ours)._storage   # Optuna's cache over ours
    warm = cached.create_new_trial(sid)
    ours.defer(warm)
    for name, value in (("a", 0.5), ("b", 0.5), ("c", 2), ("d", "x")):
        # the first write of each name in a process: Optuna's own check against the study, at once
        cached.set_trial_param(warm, name, DISTS[name].to_internal_repr(value), DISTS[name])
        assert name in theirs.get_trial(warm).params
    with pytest.raises(ValueError):
        cached.set_trial_param(warm, "c", 2.0, FloatDistribution(0.0, 1.0))   # incompatible with the study's
    cached.set_trial_state_values(warm, TrialState.FAIL)
    template = optuna.trial.FrozenTrial(number=-1, state=TrialState.RUNNING, value=None, values=None,
                                        datetime_start=None, datetime_complete=None, params={},
                                        distributions={}, user_attrs={"worker": {"pid": 7}},
                                        system_attrs={}, intermediate_values={}, trial_id=-1)
    tid = cached.create_new_trial(sid, template)
    t = theirs.get_trial(tid)
    assert t.number == 6 and t.state == TrialState.RUNNING and t.user_attrs == {"worker": {"pid": 7}}
    ours.defer(tid)
    for name, value in (("a", 0.75), ("b", 0.5), ("c", 8), ("d", "x")):
        cached.set_trial_param(tid, name, DISTS[name].to_internal_repr(value), DISTS[name])
    cached.set_trial_param(tid, "a", 0.1, DISTS["a"])              # a second write: ignored, as Optuna's
    cached.set_trial_user_attr(tid, "params", {"h_z": 0.2})
    assert theirs.get_trial(tid).params == {}                       # not written yet
    assert ours.get_trial(tid).params == {"a": 0.75, "b": 0.5, "c": 8, "d": "x"}   # this process sees them
    assert ours.get_trial(tid).user_attrs["params"] == {"h_z": 0.2}
    ours.flush(tid)
    assert theirs.get_trial(tid).params == {"a": 0.75, "b": 0.5, "c": 8, "d": "x"}
    assert "params" in theirs.get_trial(tid).user_attrs
    cached.set_trial_user_attr(tid, "result", {"fell": False})
    cached.set_trial_system_attr(tid, "constraints", [-1.0])
    assert "result" not in theirs.get_trial(tid).user_attrs
    with pytest.raises(TypeError):
        cached.set_trial_user_attr(tid, "bad", object())           # not JSON: refused at once
    assert cached.set_trial_state_values(tid, TrialState.RUNNING) is False
    assert ours.deferred() == []
    # the same trial through Optuna's path, for comparison
    ref = theirs.create_new_trial(sid)
    for name, value in (("a", 0.75), ("b", 0.5), ("c", 8), ("d", "x")):
        theirs.set_trial_param(ref, name, DISTS[name].to_internal_repr(value), DISTS[name])
    ours.defer(tid2 := cached.create_new_trial(sid))
    for name, value in (("a", 0.75), ("b", 0.5), ("c", 8), ("d", "x")):
        cached.set_trial_param(tid2, name, DISTS[name].to_internal_repr(value), DISTS[name])
    cached.set_trial_user_attr(tid2, "result", {"fell": False})
    cached.set_trial_system_attr(tid2, "constraints", [-1.0])
    theirs.set_trial_user_attr(ref, "result", {"fell": False})
    theirs.set_trial_system_attr(ref, "constraints", [-1.0])
    assert cached.set_trial_state_values(tid2, TrialState.COMPLETE, [0.3, float("inf")])
    theirs.set_trial_state_values(ref, TrialState.COMPLETE, [0.3, float("inf")])
    a, b = theirs.get_trial(tid2), theirs.get_trial(ref)
    assert (a.params, a.user_attrs, a.system_attrs, a.values, a.state) == \
        (b.params, b.user_attrs, b.system_attrs, b.values, b.state)
    assert a.datetime_complete is not None and ours.deferred() == []
    ours.defer(tid3 := cached.create_new_trial(sid))                # ended without values
    cached.set_trial_user_attr(tid3, "failed", "ValueError: x")
    assert cached.set_trial_state_values(tid3, TrialState.PRUNED)
    c = theirs.get_trial(tid3)
    assert (c.state, c.values, c.user_attrs["failed"]) == (TrialState.PRUNED, None, "ValueError: x")
    assert c.datetime_complete is not None and ours.get_trial(tid3).state == TrialState.PRUNED


def test_a_deferred_trial_failed_by_another_process_is_not_overwritten(url):
    ours, theirs, sid = _pair(url)
    _fill(theirs, sid)
    cached = optuna.load_study(study_name="s", storage=ours)._storage
    tid = cached.create_new_trial(sid)
    ours.defer(tid)
    cached.set_trial_user_attr(tid, "result", {"fell": True})
    theirs.set_trial_state_values(tid, TrialState.FAIL)            # a reaper, elsewhere
    with pytest.raises(optuna.exceptions.UpdateFinishedTrialError):
        cached.set_trial_state_values(tid, TrialState.COMPLETE, [1.0, 1.0])
    t = theirs.get_trial(tid)
    assert t.state == TrialState.FAIL and "result" not in t.user_attrs and t.values is None


def test_numbers_count_the_study_trials_whoever_creates_them(url):
    ours, theirs, sid = _pair(url)
    other = optuna.create_study(storage=theirs, study_name="other")
    for _ in range(3):
        theirs.create_new_trial(other._study_id)
    numbers = []
    for i in range(9):
        store = ours if i % 3 else theirs         # ours twice in a row: its count from its anchor
        numbers.append(store.get_trial(store.create_new_trial(sid)).number)
        theirs.create_new_trial(other._study_id)  # another study's trials between, ids interleaved
    assert numbers == list(range(9))
    assert [t.number for t in theirs.get_all_trials(other._study_id)] == list(range(12))


def test_lean_finds_ours_behind_optunas_cache(tmp_path):
    study = optuna.create_study(storage=LeanRDBStorage(f"sqlite:///{tmp_path / 'x.db'}"))
    assert isinstance(lean(study._storage), LeanRDBStorage)
    plain = optuna.create_study(storage=RDBStorage(f"sqlite:///{tmp_path / 'y.db'}"))
    assert lean(plain._storage) is None


def test_a_study_through_ours_gives_optunas_draws(tmp_path):
    """A seeded study run with ask/tell on ours and on Optuna's storage: the same trials."""
    out = []
    for cls, name in ((RDBStorage, "a.db"), (LeanRDBStorage, "b.db")):
        study = optuna.create_study(storage=cls(f"sqlite:///{tmp_path / name}"),
                                    sampler=optuna.samplers.TPESampler(seed=3, n_startup_trials=4))
        rdb = lean(study._storage)
        for _ in range(10):
            trial = study.ask()
            if rdb is not None:
                rdb.defer(trial._trial_id)
            x, n = trial.suggest_float("x", -2, 2), trial.suggest_int("n", 1, 5)
            if rdb is not None:
                rdb.flush(trial._trial_id)
            trial.set_user_attr("seen", [x, n])
            study.tell(trial, (x - 0.3) ** 2 + n)
        out.append([(t.params, t.values, t.user_attrs) for t in study.get_trials()])
    assert out[0] == out[1]


def test_stale_trials_are_optunas(url):
    """The heartbeat reading: ours and Optuna's name the same running trials stale."""
    import time
    ours = LeanRDBStorage(url, heartbeat_interval=1, grace_period=1)
    theirs = RDBStorage(url, heartbeat_interval=1, grace_period=1)
    sid = optuna.create_study(storage=theirs, study_name="h")._study_id
    old, silent, done = (theirs.create_new_trial(sid) for _ in range(3))
    for tid in (old, done):
        theirs.record_heartbeat(tid)
    theirs.set_trial_state_values(done, TrialState.COMPLETE, [1.0])
    time.sleep(2.5)          # past the grace period even in whole seconds (SQLite's clock); nothing here can turn stale later
    assert ours._get_stale_trial_ids(sid) == theirs._get_stale_trial_ids(sid) == [old]


def test_a_workers_index_reads_around_optunas_cache(url):
    """The index on ours counts and windows the study as on Optuna's storage, reads it in
    chunks, and leaves Optuna's cache empty (so a worker does not hold the whole study); a
    waiting trial it pops is put in the cache, where suggest needs it."""
    from tuner.store.history import TrialIndex
    ours, theirs, _ = _pair(url)
    study = optuna.create_study(storage=theirs, study_name="w")
    for i in range(12):
        study.add_trial(optuna.trial.create_trial(params={"a": i / 20}, distributions={"a": DISTS["a"]},
                                                  value=float((i * 7) % 5)))
    study.enqueue_trial({"a": 0.5})
    mine = optuna.load_study(study_name="w", storage=ours)
    index = TrialIndex()
    index.READ_CHUNK = 5                          # three chunks and a rest
    index.refresh(mine)
    ref = TrialIndex().refresh(optuna.load_study(study_name="w", storage=RDBStorage(url)))
    assert (index.n_done, index.seen, [t.number for t in index.window()]) == \
        (ref.n_done, ref.seen, [t.number for t in ref.window()]) == (12, 13, list(range(12)))
    assert [t.number for t in index.waiting] == [12]
    assert not mine._storage._studies.get(mine._study_id, None) or not mine._storage._studies[mine._study_id].trials
    trial = index.reserve(mine, {"worker": {"pid": 1}})
    assert theirs.get_trial(trial._trial_id).user_attrs == {"worker": {"pid": 1}}   # popped with its worker
    assert trial.number == 12 and trial.suggest_float("a", 0.0, 1.0) == 0.5
    study.tell(trial.number, 0.1)
    index.refresh(mine)
    assert index.n_done == 13 and not index.waiting and index.window()[-1].number == 12


def test_a_worker_reads_its_own_ended_trials_from_its_copy(url):
    """A trial this process ended is not read back from the database by its next
    ``read_trials`` (one statement, not two), and the copy it gets is the trial the database
    holds, as another process reads it; a trial ended elsewhere is read whole."""
    import sqlalchemy as sa
    ours, theirs, sid = _pair(url)
    _fill(theirs, sid)
    cached = optuna.load_study(study_name="s", storage=ours)._storage
    after = max(t._trial_id for t in theirs.get_all_trials(sid))
    tid = cached.create_new_trial(sid, optuna.trial.FrozenTrial(
        number=-1, state=TrialState.RUNNING, value=None, values=None, datetime_start=None,
        datetime_complete=None, params={}, distributions={}, user_attrs={"worker": {"pid": 7}},
        system_attrs={}, intermediate_values={}, trial_id=-1))
    ours.defer(tid)
    for name, value in (("a", 0.75), ("b", 0.5), ("c", 8), ("d", 3)):
        cached.set_trial_param(tid, name, DISTS[name].to_internal_repr(value), DISTS[name])
    ours.flush(tid)
    cached.set_trial_user_attr(tid, "result", {"per": (1, 2.5, None), "fell": False})   # a tuple: a list once stored
    cached.set_trial_system_attr(tid, "constraints", [-1.0])
    assert cached.set_trial_state_values(tid, TrialState.COMPLETE, [0.3, float("-inf")])
    other = theirs.create_new_trial(sid)                  # ended by another process
    theirs.set_trial_user_attr(other, "result", {"fell": True})
    theirs.set_trial_state_values(other, TrialState.FAIL)
    statements = []
    sa.event.listen(ours.engine, "before_cursor_execute", lambda *a: statements.append(a[2]))
    got = {t._trial_id: t for t in ours.read_trials(sid, after)}
    assert len(statements) == 2                           # the trials, and the rows of the other one only
    fresh = LeanRDBStorage(url)                           # another process's reading
    for t in fresh.read_trials(sid, after):
        _same(got[t._trial_id], t)
    assert got[tid].user_attrs["result"]["per"] == [1, 2.5, None]
    statements.clear()
    assert [t._trial_id for t in ours.read_trials(sid, after)] == [tid, other]   # the copy used once
    assert len(statements) == 2
    mine = LeanRDBStorage(url)                            # only the own trial new: one statement
    mine_cached = optuna.load_study(study_name="s", storage=mine)._storage
    t2 = mine_cached.create_new_trial(sid)
    mine.defer(t2)
    mine_cached.set_trial_state_values(t2, TrialState.PRUNED)
    statements.clear()
    sa.event.listen(mine.engine, "before_cursor_execute", lambda *a: statements.append(a[2]))
    [back] = mine.read_trials(sid, other)
    assert len(statements) == 1
    _same(back, fresh.get_trial(t2))


def test_a_waiting_trial_is_popped_with_its_worker_in_one_write(url):
    """``claim``: RUNNING from WAITING with its start and the worker's identity at once (one
    statement on PostgreSQL), False for a trial another process popped, Optuna's errors for an
    ended or missing trial; the same trial Optuna's two writes make."""
    import sqlalchemy as sa
    from optuna.exceptions import UpdateFinishedTrialError
    ours, theirs, _ = _pair(url)
    study = optuna.create_study(storage=theirs, study_name="q")
    for a in (0.1, 0.2, 0.3):
        study.enqueue_trial({"a": a})
    first, second, third = (t._trial_id for t in study.get_trials())
    statements = []
    sa.event.listen(ours.engine, "before_cursor_execute", lambda *a: statements.append(a[2]))
    assert ours.claim(first, {"worker": {"pid": 7}, "note": "x"})
    if url.startswith("postgresql"):
        assert len(statements) == 1
    theirs.set_trial_state_values(second, TrialState.RUNNING)          # Optuna's pop, for comparison
    theirs.set_trial_user_attr(second, "worker", {"pid": 7})
    theirs.set_trial_user_attr(second, "note", "x")
    a, b = theirs.get_trial(first), theirs.get_trial(second)
    assert (a.state, a.user_attrs) == (b.state, b.user_attrs)
    assert a.system_attrs == {"fixed_params": {"a": 0.1}}                 # the enqueued parameters kept
    assert a.state == TrialState.RUNNING and a.datetime_start >= study.get_trials()[0].datetime_start
    assert abs((b.datetime_start - a.datetime_start).total_seconds()) < 60
    assert ours.claim(first, {"worker": {"pid": 8}}) is False             # popped already: left as it is
    assert theirs.get_trial(first).user_attrs["worker"] == {"pid": 7}
    theirs.set_trial_state_values(third, TrialState.FAIL)
    with pytest.raises(UpdateFinishedTrialError):
        ours.claim(third, {"worker": {"pid": 7}})
    assert "worker" not in theirs.get_trial(third).user_attrs
    with pytest.raises(KeyError):
        ours.claim(10**6, {"worker": {}})
