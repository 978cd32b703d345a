"""The robot side's one robot file (gaits/robot/robot_file.py, `gait-tuner robot export`): written from a
robot map, read back equal with numpy and PyYAML only, its servo conversions the servo table's, the
loop on the robot driven by it, and a broken file one line."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest
import yaml

import third_party_robot as T
from conftest import ROOT, run_cli
from gaits import JOINT_NAMES, ParamError
from gaits.robot.robot_file import load_robot_file, to_units
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
    (lambda d: d["bus"].update(imu={"protocol": "mpu"}), "bus.imu.protocol = 'mpu': expected one of gait-tuner, bitbots"),
    (lambda d: d["bus"]["soles"]["left"].update(id=d["joints"]["l_knee"]["servo"]["id"]),
     "is already l_knee's"),
    (lambda d: d["bus"]["soles"]["right"].update(port=9), "bus.soles.right.port = 9: expected a bus number in [0, 7]"),
    (lambda d: d["bus"]["soles"]["right"].update(zero=[1, 2, 3]), "bus.soles.right.zero = [1, 2, 3]: expected a number "
                                                                  "or four"),
    (lambda d: d["bus"]["soles"]["right"].update(newtons_per_unit=0), "bus.soles.right.newtons_per_unit[0] = 0"),
    (lambda d: d["bus"].update(cameras=1), "bus: unknown key 'cameras'"),
    (lambda d: d["joints"]["l_knee"]["servo"].update(port=-1), "joints.l_knee.servo.port = -1"),
])
def test_a_broken_robot_file_is_one_line(exported, tmp_path, edit, words):
    _, out = exported
    doc = yaml.safe_load(out.read_text())
    edit(doc)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(ParamError, match=re.escape(words)) as info:
        load_robot_file(bad)
    assert "\n" not in str(info.value) and str(bad) in str(info.value)


def test_its_boards_and_buses_read_back_equal(exported, tmp_path):
    """The bus: section (the IMU, the sole boards and their calibration, each device's port) is
    written and read back as it was."""
    import dataclasses
    from gaits.robot.robot_file import ImuBoard, SoleBoard, save_robot_file
    _, out = exported
    rf = load_robot_file(out)
    assert rf.imu == ImuBoard() and [b.id for b in rf.soles] == [102, 101] and rf.ports == 1
    assert rf.sensing_gap() is None
    knee = rf.joints["l_knee"]
    other = dataclasses.replace(
        rf, imu=ImuBoard("bitbots", 241, 2), sole_protocol="bitfoot",
        soles=(SoleBoard(102, 1, (1.0, 2.0, 3.0, 4.0), (0.5, 0.25, 2.0, 1.0)), SoleBoard(101, 3)),
        joints={**rf.joints, "l_knee": dataclasses.replace(knee, servo=dataclasses.replace(knee.servo, port=2))})
    save_robot_file(tmp_path / "other.yaml", other)
    back = load_robot_file(tmp_path / "other.yaml")
    assert back == other and back.ports == 4
    assert back.devices()[241] == "the IMU" and back.devices()[102] == "the left sole board"
    cells = np.array([3.0, 2.0, 7.0, 4.0])
    np.testing.assert_allclose(back.soles[0].newtons(back.soles[0].raw(cells)), cells)
    np.testing.assert_allclose(back.soles[0].newtons([1.0, 2.0, 3.0, 4.0]), 0.0)
    assert dataclasses.replace(back, soles=None).sensing_gap() is not None
    assert dataclasses.replace(back, soles=None, foot_sensors=False).sensing_gap() is None


@pytest.mark.parametrize("protocol", ["gait-tuner", "bitbots"])
def test_an_imu_board_reads_back_what_it_holds(protocol):
    """An IMU board's registers as the simulated bus writes them read back as the readings
    (Bit-Bots' board holds a quaternion: the angles come back through it)."""
    from gaits.robot.dynamixel import IMU_REGISTERS, imu_reading, imu_registers
    rng = np.random.default_rng(4)
    for _ in range(50):
        rpy = rng.uniform([-1.2, -1.2, -3.0], [1.2, 1.2, 3.0])
        gyro, accel = rng.normal(size=3), rng.normal(size=3) * 9
        data = imu_registers(protocol, rpy, gyro, accel)
        assert len(data) == IMU_REGISTERS[protocol][1]
        got = imu_reading(protocol, data)
        for a, b in zip(got, (rpy, gyro, accel)):
            np.testing.assert_allclose(a, b, atol=2e-6 * max(1.0, np.max(np.abs(b))))
    if protocol == "bitbots":            # a board just powered on holds a zero quaternion: no reading
        assert imu_reading(protocol, bytes(40)) is None


def test_a_robot_whose_soles_sense_what_the_loop_cannot_read_is_refused(tmp_path):
    """The soles sense force unless the map says not (the simulator's walks read them): a map wired
    for the robot side (servo ids) that names no sole boards is refused where a walk for the robot
    would be made or sent (init, a study, robot export, bus serve) and by the loop itself; with
    foot_sensors: false, or the boards named, it is taken."""
    from conftest import run_in_process
    text = servos_yaml().replace("bus: {soles: {left: 102, right: 101}}\n", "")
    robot_map = T.write(tmp_path, T.mjcf(), T.map_yaml(extra=text))
    study = tmp_path / "study.yaml"
    study.write_text(f"name: s\nrobot: {robot_map}\nsurfaces: [carpet4]\ngait: eros\nbase: eros-x24-with\n"
                     f"space:\n  c_dc: {{low: 0.0, high: 4.0}}\nobjectives: [pitch_rms]\ntrials: 2\n")
    for args in (["robot", "export", str(robot_map), "--out", str(tmp_path / "rf.yaml")],
                 ["init", "--robot", str(robot_map), "--surface", "carpet4", "--out", str(tmp_path / "init")],
                 ["bus", "serve", "--robot", str(robot_map), "--surface", "carpet4", "--wait", "1"],
                 ["tune", str(study)]):
        r = run_in_process(args)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, (args, r.stderr)
        assert "names no sole boards (bus: soles:)" in r.stderr and "foot_sensors: false" in r.stderr, r.stderr
    assert not (tmp_path / "rf.yaml").exists() and not (tmp_path / "init").exists()
    # robot check, which refuses nothing of a valid map, says it
    r = run_in_process(["robot", "check", str(robot_map), "--no-stand"])
    assert r.returncode == 0 and "note: the soles sense force" in r.stdout and "names no sole boards" in r.stdout
    # the loop on the robot, given a robot file written before the boards were named
    wired = T.write(tmp_path / "ok", T.mjcf(), T.map_yaml(extra=servos_yaml()))
    ok = tmp_path / "ok.yaml"
    assert run_in_process(["robot", "export", str(wired), "--out", str(ok)]).returncode == 0
    doc = yaml.safe_load(ok.read_text())
    doc["bus"].pop("soles")
    old = tmp_path / "old.yaml"
    old.write_text(yaml.safe_dump(doc))
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "robot_loop.py"),
                        str(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"), "--port",
                        str(tmp_path / "no-such-bus"), "--robot", str(old)], capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "names no sole boards" in r.stderr, r.stderr
    # said so, the same map is taken
    quiet = T.write(tmp_path / "quiet", T.mjcf(), T.map_yaml(extra="foot_sensors: false\n" + text))
    assert run_in_process(["robot", "export", str(quiet), "--out", str(tmp_path / "q.yaml")]).returncode == 0


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


def test_a_missing_robot_file_says_so_once(tmp_path):
    with pytest.raises(ParamError) as info:
        load_robot_file(tmp_path / "nowhere.yaml")
    assert str(info.value).endswith("no such robot file") and "file file" not in str(info.value)
