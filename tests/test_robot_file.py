"""The robot side's one robot file (gaits/robot_file.py, `gait-tuner robot export`): written from a
robot map, read back equal with numpy and PyYAML only, its servo conversions the servo table's, the
loop on the robot driven by it, and a broken file one line."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml

import third_party_robot as T
from conftest import ROOT, run_cli
from gaits import JOINT_NAMES, ParamError
from gaits.robot_file import load_robot_file, to_units
from test_servo_table import servos_yaml


@pytest.fixture
def exported(tmp_path, gait_tuner_cmd, run_env):
    robot_map = T.write(tmp_path, T.mjcf(), T.map_yaml(extra=servos_yaml()))
    out = tmp_path / "robot.yaml"
    r = run_cli(gait_tuner_cmd, ['robot', 'export', str(robot_map), '--out', str(out)], run_env)
    assert r.returncode == 0, r.stderr
    return robot_map, out


def test_the_robot_file_holds_what_the_map_derives(exported):
    from tuner.robots import load_robot
    robot_map, out = exported
    model = load_robot(str(robot_map))
    rf = load_robot_file(out)
    assert rf.robot == model.name and rf.leg == model.leg and rf.foot_size == tuple(model.foot_size)
    assert rf.mass == pytest.approx(float(np.sum(model.model().body_mass)))
    assert set(rf.joints) == set(model.joint_map)
    for ours, (theirs, sign) in model.joint_map.items():
        j = rf.joints[ours]
        assert (j.name, j.sign) == (theirs, sign) and j.servo == model.servo_units[theirs]
        assert j.speed == model.servos[theirs].speed
    lo, hi = model.joint_ranges([rf.joints["l_knee"].name])
    assert (rf.joints["l_knee"].lower, rf.joints["l_knee"].upper) == (lo[0], hi[0])


def test_its_servo_positions_are_the_servo_tables_and_read_back(exported):
    _, out = exported
    rf = load_robot_file(out)
    rng = np.random.default_rng(1)
    q = rng.uniform(-0.3, 0.3, len(JOINT_NAMES))
    ticks = rf.to_servos(q)
    for ours, j in rf.joints.items():
        want = to_units(min(max(j.sign * q[JOINT_NAMES.index(ours)], j.lower), j.upper), j.servo)
        assert ticks[j.servo.id] == want
    back = rf.from_servos(ticks)
    half_tick = max(0.5 / j.servo.units_per_rad for j in rf.joints.values())
    inside = [JOINT_NAMES.index(o) for o, j in rf.joints.items() if j.lower < j.sign * q[JOINT_NAMES.index(o)] < j.upper]
    assert np.all(np.abs(back[inside] - q[inside]) <= half_tick + 1e-12)


def test_the_loop_on_the_robot_takes_it(exported):
    _, out = exported
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "robot_loop.py"),
                        str(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"), "--dry-run", "--seconds", "1",
                        "--robot", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "20 servo position(s) a tick from its robot file" in r.stdout


@pytest.mark.parametrize("edit, words", [
    (lambda d: d.pop("leg"), "missing 'leg'"),
    (lambda d: d["joints"].pop("l_knee"), "the leg joints l_knee are missing"),
    (lambda d: d["joints"]["r_knee"]["servo"].update(id=d["joints"]["l_knee"]["servo"]["id"]), "servo id"),
    (lambda d: d["joints"]["l_knee"].update(sign=2), "sign = 2: must be 1 or -1"),
    (lambda d: d["joints"]["l_knee"].update(lower=2.0, upper=-2.0), "lower = 2 is above upper = -2"),
    (lambda d: d["leg"].update(thigh=-1), "leg.thigh"),
    (lambda d: d.update(colour="red"), "unknown key 'colour'"),
    (lambda d: d["joints"].update(tail={"name": "t"}), "'tail' is not one of our joints"),
])
def test_a_broken_robot_file_is_one_line(exported, tmp_path, edit, words):
    _, out = exported
    doc = yaml.safe_load(out.read_text())
    edit(doc)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(ParamError, match=words.replace("(", "\\(").replace(")", "\\)")) as info:
        load_robot_file(bad)
    assert "\n" not in str(info.value) and str(bad) in str(info.value)


def test_it_states_what_the_servos_give_way_by_as_the_simulator_does(exported):
    """Each joint's kp and velocity terms (the servo law's pieces: kv, back-EMF, joint damping) are in
    the robot file, so the engine on the robot puts the same give back into its targets as in the
    simulator (gaits/engine/servo_load.py): its servo terms and the give it predicts agree."""
    import gaits
    from gaits.engine import EngineParams, WalkEngine
    from gaits.engine.servo_load import servo_terms
    from tuner.params_io import resolve_params
    from tuner.robots import load_robot
    robot_map, out = exported
    model, rf = load_robot(str(robot_map)), load_robot_file(out)
    on_robot, in_sim = servo_terms(rf), servo_terms(model)
    for name in ("kp", "damping", "torque"):
        np.testing.assert_allclose(getattr(on_robot, name), getattr(in_sim, name), rtol=1e-12)
    assert np.all(on_robot.kp[[JOINT_NAMES.index(n) for n in rf.joints]] > 0)
    params = resolve_params("kidsize-engine-carpet4", None).params
    gives = [WalkEngine(params, EngineParams(load_share=0.8, lag_share=0.3), r, 0.01,
                        gaits.family("tlipfm").step_limits(params, r)).predicted_give() for r in (rf, model)]
    np.testing.assert_allclose(gives[0], gives[1], atol=1e-12)
    assert np.max(np.abs(gives[0])) > 0.01
