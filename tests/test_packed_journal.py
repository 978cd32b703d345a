"""The journal's replay held packed: a finished trial reads as Optuna's replay reads it."""

from __future__ import annotations

import copy
import pickle

import optuna
import pytest
from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution
from optuna.storages import JournalStorage
from optuna.trial import TrialState

from tuner.store.journal import PackedJournalStorage, PackedTrial, SafeJournalBackend, unpacked

optuna.logging.set_verbosity(optuna.logging.WARNING)

DISTS = {"a": FloatDistribution(0.0, 1.0), "b": FloatDistribution(1e-3, 1.0, log=True),
         "c": IntDistribution(1, 9), "d": CategoricalDistribution(["x", "y", 3])}


def _fill(path):
    """A study of every kind of trial, written through Optuna's journal storage."""
    study = optuna.create_study(storage=JournalStorage(SafeJournalBackend(path)), study_name="p",
                                directions=["minimize", "maximize"])
    sid, storage = study._study_id, study._storage
    for i, state in enumerate([TrialState.COMPLETE, TrialState.PRUNED, TrialState.FAIL, TrialState.RUNNING,
                               TrialState.COMPLETE, TrialState.WAITING]):
        tid = storage.create_new_trial(sid)
        for name, value in (("a", 0.25 + i / 10), ("b", 0.01), ("c", 3 + i), ("d", "y" if i % 2 else 3)):
            storage.set_trial_param(tid, name, DISTS[name].to_internal_repr(value), DISTS[name])
        storage.set_trial_user_attr(tid, "result", {"fell": bool(i % 2), "per": [1, 2.5 * i, {"x": None}]})
        storage.set_trial_system_attr(tid, "constraints", [float(i) - 2])
        storage.set_trial_intermediate_value(tid, 0, 1.5 * i)
        if state.is_finished():
            storage.set_trial_state_values(tid, state, [0.5 * i, float("inf")] if state == TrialState.COMPLETE else None)
    study.enqueue_trial({"a": 0.5})
    study.add_trial(optuna.trial.create_trial(params={"a": 0.9}, distributions={"a": DISTS["a"]}, values=[1.0, 2.0],
                                              user_attrs={"added": True}))
    return sid


def test_packed_trials_read_as_optunas_replay_reads_them(tmp_path):
    path = tmp_path / "p.journal"
    sid = _fill(path)
    theirs = JournalStorage(SafeJournalBackend(path)).get_all_trials(sid, deepcopy=False)
    ours = PackedJournalStorage(SafeJournalBackend(path))
    mine = ours.get_all_trials(sid, deepcopy=False)
    assert [type(t) is PackedTrial for t in mine] == [t.state.is_finished() for t in theirs]
    assert sum(isinstance(t, PackedTrial) for t in mine) == 5
    for a, b in zip(mine, theirs):
        assert a == b and b == a and unpacked(a).__dict__ == b.__dict__
        for field in ("number", "state", "values", "datetime_start", "datetime_complete", "params",
                      "distributions", "user_attrs", "system_attrs", "intermediate_values", "_trial_id",
                      "last_step", "duration"):
            assert getattr(a, field) == getattr(b, field), field
        assert repr(unpacked(a)) == repr(b)
        for c in (copy.copy(a), copy.deepcopy(a), pickle.loads(pickle.dumps(a))):
            assert c == b
    assert ours.get_all_trials(sid, states=(TrialState.COMPLETE,)) == \
        [t for t in theirs if t.state == TrialState.COMPLETE]


def test_a_packed_trials_reads_are_copies_and_a_set_field_is_kept(tmp_path):
    path = tmp_path / "p.journal"
    sid = _fill(path)
    t = PackedJournalStorage(SafeJournalBackend(path)).get_all_trials(sid, deepcopy=False)[0]
    assert isinstance(t, PackedTrial)
    t.user_attrs["result"]["fell"] = "changed"             # a copy: nothing held changes
    assert t.user_attrs["result"]["fell"] is False
    t.user_attrs = {"set": 1}                              # set on it: kept, ahead of the packed one
    assert t.user_attrs == {"set": 1} and unpacked(t).user_attrs == {"set": 1}
    with pytest.raises(AttributeError):
        t.no_such_field


def test_a_study_through_the_packed_journal_is_optunas(tmp_path):
    """Seeded TPE through ours and through Optuna's journal: the same trials; a finished trial
    refuses writes as Optuna's does; the study is packed as it runs and when reopened."""
    def run(storage):
        study = optuna.create_study(storage=storage, study_name="r", sampler=optuna.samplers.TPESampler(seed=3, n_startup_trials=4))
        study.optimize(lambda tr: (tr.suggest_float("x", -1, 1) - 0.3) ** 2 + tr.suggest_int("k", 0, 4), n_trials=14)
        return study
    a = run(PackedJournalStorage(SafeJournalBackend(tmp_path / "a.journal")))
    b = run(JournalStorage(SafeJournalBackend(tmp_path / "b.journal")))
    assert [(t.params, t.values, t.state) for t in a.trials] == [(t.params, t.values, t.state) for t in b.trials]
    assert all(isinstance(t, PackedTrial) for t in a.get_trials(deepcopy=False))
    with pytest.raises(RuntimeError):
        a._storage.set_trial_user_attr(a.trials[0]._trial_id, "late", 1)
    again = PackedJournalStorage(SafeJournalBackend(tmp_path / "a.journal"))
    assert again.get_all_trials(a._study_id) == a.get_trials()
    assert (a.best_trial.number, a.best_trial.params) == (b.best_trial.number, b.best_trial.params)


def test_a_packed_trial_holds_a_fraction_of_the_objects(tmp_path):
    """What the replay holds per finished trial: its record packed against a like trial's."""
    path = tmp_path / "m.journal"
    study = optuna.create_study(storage=JournalStorage(SafeJournalBackend(path)), study_name="m")
    for i in range(50):
        study.add_trial(optuna.trial.create_trial(
            params={k: 0.01 * i for k in "abcdefgh"}, distributions={k: DISTS["a"] for k in "abcdefgh"},
            value=float(i), user_attrs={"params": {f"p{j}": 0.1 * j + i for j in range(30)},
                                        "result": {"score": i / 7, "fell": False, "per": [i / 3, i / 5]}}))
    ours = PackedJournalStorage(SafeJournalBackend(path))
    for t in ours.get_all_trials(study._study_id, deepcopy=False)[1:]:
        whole = len(pickle.dumps(unpacked(t).__dict__))
        assert len(t.__dict__["_packed"]) < whole / 3
