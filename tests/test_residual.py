"""The residual on the engine's leg targets (gaits/engine/residual.py) and its training's search step
(tuner/search/train.py): exact unit tests; walking it is in tests/test_integration_walks.py."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import gaits
from gaits import JOINT_NAMES, ParamError
from gaits.control import Measurement
from gaits.engine.residual import (FEATURES, LEG_JOINTS, ResidualParams, ResidualWalk, features,
                                   residual_from_mapping)
from gaits.engine.walk import STAND, WALK
from gaits.gait_file import gait_file_from_mapping, gait_file_text, read_yaml

LATERAL = ("hip_yaw", "hip_roll", "ankle_roll")


class _Engine:
    """What ResidualWalk reads of the engine, set by hand; its own targets all zero."""

    def __init__(self, mode, side, progress, command, tilt, est_vel, plan_vel):
        self.dt, self.duration, self.walk_start = 0.01, None, 0.5
        self.mode, self.t, self.step_t0 = mode, 1.0 + 0.4 * progress, 1.0
        self.cur = None if side is None else SimpleNamespace(side=side, T=0.4)
        self.command, self.tilt = np.asarray(command, float), np.asarray(tilt, float)
        self.estimator = SimpleNamespace(velocity=np.asarray(est_vel, float))
        self.vel = np.asarray(plan_vel, float)

    def step(self, m, command=None):
        return np.zeros(len(JOINT_NAMES))


def _measurement(gyro):
    return Measurement(t=1.0, q=np.zeros(20), imu_rpy=np.zeros(3), gyro=np.asarray(gyro, float))


def _legs(out):
    return ({j: out[JOINT_NAMES.index(f"l_{j}")] for j in LEG_JOINTS},
            {j: out[JOINT_NAMES.index(f"r_{j}")] for j in LEG_JOINTS})


def test_a_walk_mirrored_left_to_right_gets_the_mirrored_correction():
    """Stepping on the left foot, drifting left, rolled left, turning left: the correction of each
    leg equals the other leg's in the mirrored state (right foot, right, right, right), its
    lateral joints' signs turned; and a left-right-symmetric state corrects both legs alike."""
    rng = np.random.default_rng(3)
    params = ResidualParams.from_matrix(rng.normal(0.0, 0.02, (2, 6, 12)), limit=1.0)
    state = dict(mode=WALK, progress=0.3, command=(0.2, 0.05, 0.4), tilt=(0.03, 0.05),
                 est_vel=(0.25, 0.04), plan_vel=(0.2, -0.01))
    gyro = (0.3, -0.2, 0.1)
    a = ResidualWalk(_Engine(side=1, **state), params).step(_measurement(gyro))
    mirrored = dict(state, command=(0.2, -0.05, -0.4), tilt=(-0.03, 0.05), est_vel=(0.25, -0.04),
                    plan_vel=(0.2, 0.01))
    b = ResidualWalk(_Engine(side=-1, **mirrored), params).step(_measurement((-0.3, -0.2, -0.1)))
    (al, ar), (bl, br) = _legs(a), _legs(b)
    for j in LEG_JOINTS:
        s = -1.0 if j in LATERAL else 1.0
        assert al[j] == pytest.approx(s * br[j], abs=1e-15) and ar[j] == pytest.approx(s * bl[j], abs=1e-15)
    assert np.count_nonzero(a) == 12                      # only the legs move, all twelve of them
    standing = ResidualWalk(_Engine(STAND, None, 0.0, (0, 0, 0), (0.0, 0.02), (0.1, 0), (0, 0)), params)
    sl, sr = _legs(standing.step(_measurement((0.0, 0.4, 0.0))))
    for j in LEG_JOINTS:
        s = -1.0 if j in LATERAL else 1.0
        assert sl[j] == pytest.approx(s * sr[j], abs=1e-15)


def test_the_correction_is_the_map_times_the_features_by_role_and_clipped():
    """The stance leg takes the stance rows, the swing leg the swing rows, each row times the
    features as the docstring scales them, clipped at the limit."""
    w = np.zeros((2, 6, 12))
    w[0, 2, 6] = 0.1          # stance hip pitch from the pitch feature (tilt / 0.2 rad)
    w[1, 3, 1] = 0.2          # swing knee from sin(pi s)
    w[1, 1, 7] = 0.3          # swing hip roll from roll (mirrored) / 0.2
    eng = _Engine(WALK, side=1, progress=0.5, command=(0, 0, 0), tilt=(0.04, 0.05), est_vel=(0, 0), plan_vel=(0, 0))
    out = ResidualWalk(eng, ResidualParams.from_matrix(w, limit=0.08)).step(_measurement((0, 0, 0)))
    left, right = _legs(out)
    assert left["hip_pitch"] == pytest.approx(0.1 * 0.05 / 0.2)            # the left foot supports
    assert right["knee"] == pytest.approx(0.08)                              # 0.2 x sin(pi/2), clipped
    assert right["hip_roll"] == pytest.approx((-1) * 0.3 * (-1) * 0.04 / 0.2)  # both signs of the right side
    assert sum(abs(v) for v in out) == pytest.approx(0.1 * 0.05 / 0.2 + 0.08 + 0.06)
    f = features(0.25, np.array([0.3, 0.3, 1.0]), np.array([0.2, 0.2]), np.array([2.0, 2.0, 0.0]),
                 np.array([0.2, 0.2]), -1.0)
    assert f.tolist() == pytest.approx([1, np.sin(np.pi / 4), 1, 1, -1, -1, 1, -1, 1, -1, 1, -1])
    assert len(FEATURES) == f.size == 12


def test_a_dropped_gyro_reading_keeps_the_last_one():
    w = np.zeros((2, 6, 12))
    w[0, 4, 8] = 0.1                   # stance ankle pitch from the pitch rate
    walk = ResidualWalk(_Engine(STAND, None, 0.0, (0, 0, 0), (0, 0), (0, 0), (0, 0)), ResidualParams.from_matrix(w))
    first = walk.step(_measurement((0.0, 1.0, 0.0)))
    again = walk.step(_measurement((np.nan, np.nan, 0.0)))
    assert np.array_equal(first, again) and first[JOINT_NAMES.index("l_ankle_pitch")] == pytest.approx(0.05)


def test_a_set_with_a_residual_reads_back_identically_and_bad_ones_are_one_line():
    from conftest import ROOT
    doc = read_yaml(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml", "set")
    g = gait_file_from_mapping(doc, "s")
    res = ResidualParams.from_matrix(np.round(np.random.default_rng(1).normal(0, 0.05, (2, 6, 12)), 6), 0.25)
    text = gait_file_text(g.params, "d", g.stabiliser, g.engine, res)
    import yaml
    back = gait_file_from_mapping(yaml.safe_load(text), "s")
    assert back.residual == res and back.engine == g.engine and back.params == g.params
    assert gait_file_text(back.params, "d", back.stabiliser, back.engine, back.residual) == text
    assert gaits.Drive.of(back).residual == res
    bad = dict(yaml.safe_load(text))
    with pytest.raises(ParamError, match=r"^s: residual: stance\[knee\]\[pitch\] = 'x': expected a finite number"):
        r = dict(bad["residual"])
        r["stance"] = [list(row) for row in r["stance"]]
        r["stance"][3][6] = "x"
        gait_file_from_mapping(dict(bad, residual=r), "s")
    with pytest.raises(ParamError, match=r"^s: residual: swing: expected 6 rows .* got shape \(6, 11\)"):
        gait_file_from_mapping(dict(bad, residual=dict(bad["residual"], swing=[row[:11] for row in
                                                                             bad["residual"]["swing"]])), "s")
    with pytest.raises(ParamError, match=r"^s: residual: limit = 2: expected a clip in \(0, 1\] rad"):
        gait_file_from_mapping(dict(bad, residual=dict(bad["residual"], limit=2)), "s")
    with pytest.raises(ParamError, match=r"^s: residual: unknown field 'gain'"):
        gait_file_from_mapping(dict(bad, residual={"gain": 1}), "s")
    with pytest.raises(ParamError, match=r"^s: residual: .* needs an engine: section .*no engine"):
        gait_file_from_mapping({k: v for k, v in bad.items() if k != "engine"}, "s")
    assert residual_from_mapping({}) == ResidualParams()


def test_the_search_step_is_ars_v1t():
    """Mania et al. 2018's V1-t on numbers worked by hand: the top two directions by their better
    sign, their reward differences over the kept rewards' standard deviation."""
    from tuner.search.train import ars_update
    theta = np.zeros((2, 2))
    deltas = np.array([np.eye(2), -np.eye(2), np.ones((2, 2))])
    r_plus, r_minus = np.array([3.0, 1.0, 0.0]), np.array([1.0, 2.0, 0.5])
    # kept: direction 0 (max 3) and 1 (max 2); rewards kept 3, 1, 1, 2: std 0.8292
    sigma = np.std([3.0, 1.0, 1.0, 2.0])
    expected = 0.1 / (2 * sigma) * ((3 - 1) * np.eye(2) + (1 - 2) * -np.eye(2))
    assert np.allclose(ars_update(theta, deltas, r_plus, r_minus, 2, 0.1), expected, atol=1e-15)
    same = ars_update(theta + 1, deltas, np.ones(3), np.ones(3), 2, 0.1)
    assert np.array_equal(same, theta + 1)              # nothing to learn from equal rewards


def test_the_rewards_count_what_the_docstring_says():
    from tuner.search.train import match_reward, push_reward
    row = {"walked": 0.5, "survived": False, "tracking": {"vx_rmse_mps": 0.1, "vy_rmse_mps": 0.05,
                                                          "wz_rmse_radps": 0.5}}
    assert match_reward(row) == pytest.approx(1.5 - 0.25 * 0.5)
    assert match_reward({"walked": 1.2, "survived": True, "tracking": None}) == pytest.approx(4.0)
    assert push_reward({"absorbed": 2, "t_fall_s": 7.0}, 14.0) == pytest.approx(2.5)
    assert push_reward({"absorbed": 3, "t_fall_s": None}, 14.0) == pytest.approx(4.0)


def test_train_refuses_what_it_cannot_train(tmp_path):
    from tuner.errors import UserError
    from tuner.params_io import resolve_drive
    from tuner.search.train import TrainSettings, train
    with pytest.raises(UserError, match="tlipfm set with an engine: section"):
        train(resolve_drive("tkux-table2", None), "kidsize", "carpet4", TrainSettings(iterations=1))
    with pytest.raises(UserError, match=r"top = 5: expected a whole number in \[1, directions = 4\]"):
        TrainSettings(directions=4, top=5)
    with pytest.raises(UserError, match=r"objective = 'run': one of match, command, push"):
        TrainSettings(objective="run")
    with pytest.raises(UserError, match=r"distance = 2: expected a release distance"):
        TrainSettings(distance=2)
    with pytest.raises(UserError, match=r"command = \(0.3, 0.0, 9.0\): expected \(vx, vy, wz\)"):
        TrainSettings(objective="command", command=(0.3, 0.0, 9.0))


def test_train_walks_each_surface_in_turn_and_both_sides_on_each(monkeypatch):
    """Several surfaces: rollout k of an evaluation walks surface k mod n, the third push alternates
    every n rollouts (so each surface meets it from the front and from behind); every map of an
    iteration walks the same rollouts; the rewards come back in order into the search step."""
    import tuner.search.train as tr
    from tuner.params_io import resolve_drive
    seen = []

    def fake_map(fn, tasks, workers, progress=None, chunksize=1):
        seen.append(tasks)
        return [(float(i % 3), True) for i in range(len(tasks))]
    monkeypatch.setattr(tr, "map_in_order", fake_map)
    monkeypatch.setattr(tr, "_world", lambda robot, surfaces: SimpleNamespace(sims_with_pendulum=lambda *a: None))
    res = tr.train(resolve_drive("kidsize-engine-push", None), "kidsize", ["carpet4", "grass30"],
                   tr.TrainSettings(iterations=2, directions=2, top=1, walks=4, objective="push", seed=5))
    assert len(seen) == 2 and len(seen[0]) == (2 * 2 + 1) * 4
    first = seen[0][:4]
    assert [t[1][t[2]] for t in first] == ["carpet4", "grass30", "carpet4", "grass30"]
    assert [t[7] for t in first] == ["front", "front", "back", "back"]
    assert [t[-1] for t in first] == [(5, 0, k) for k in range(4)]
    for i in range(5):                                   # every map: the same four rollouts
        assert [t[1:3] + t[4:] for t in seen[0][4 * i:4 * i + 4]] == [t[1:3] + t[4:] for t in first]
    assert len({id(t[3]) for t in seen[0]}) == 5          # one drive a map, shared by its four rollouts
    assert [t[-1] for t in seen[1][:4]] == [(5, 1, k) for k in range(4)]
    assert res.stood == [1.0, 1.0] and len(res.rewards) == 2
