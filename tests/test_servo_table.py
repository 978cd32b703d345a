"""Exports a robot can play: a map's servos: section, tables in servo units at the control rate,
checked against each servo's speed and range (issue: team robots, item 4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import third_party_robot as T
from tuner.errors import UserError
from tuner.robots import load_robot
from tuner.robots.servo_table import ServoUnit, check_table, from_units, read_servo_units, to_units
from conftest import run_cli

JOINTS = [T.joint_name("head_pan", "c"), T.joint_name("head_tilt", "c")] + \
    [T.joint_name(k, s) for s in "lr" for k in T.ARM] + [T.joint_name(k, s) for s in "lr" for k in T.LEG]


def servos_yaml(skip: str | None = None, extra: str = "") -> str:
    # the soles sense force (the default): a map wired for the robot side names its sole boards
    rows = ["bus: {soles: {left: 102, right: 101}}", "servos:", "  default: {ticks_per_turn: 4096, centre: 2048}"]
    for i, j in enumerate(JOINTS):
        if j == skip:
            continue
        more = ", direction: -1, offset: 0.05" if j == "Knee_L" else ""
        rows.append(f"  {j}: {{id: {i + 1}{more}}}")
    return "\n".join(rows) + "\n" + extra


def run(cmd, args, env):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env)


def test_units_round_trip_within_half_a_tick():
    rng = np.random.default_rng(3)
    for u in (ServoUnit(1), ServoUnit(2, units_per_rad=1000 / math.radians(300), centre=512, direction=-1, offset=0.1)):
        q = rng.uniform(-2, 2, 500)
        back = from_units(to_units(q, u), u)
        assert np.max(np.abs(back - q)) <= 0.5 / u.units_per_rad + 1e-12


def test_the_check_names_the_first_move_too_fast_and_clip_plays_what_the_servo_can():
    t = np.arange(0, 1.0, 0.01)
    q = np.column_stack([np.zeros_like(t), np.where(t > 0.5, 0.5, 0.0)])      # a 0.5 rad jump at 0.51 s
    names = ("A", "B")
    speed, lo, hi = np.array([6.5, 6.5]), np.array([-1.0, -1.0]), np.array([1.0, 0.3])
    with pytest.raises(UserError, match=r"joint B is asked to move at 50.00 rad/s at t = 0.51 s where its servo "
                                        r"gives 6.5 rad/s"):
        check_table(q, t, names, speed, lo, hi, clip=False)
    out, notes = check_table(q, t, names, speed, lo, hi, clip=True)
    assert np.all(np.abs(np.diff(out[:, 1])) <= 6.5 * 0.01 + 1e-12)         # at most the servo's speed
    assert out[:, 1].max() == pytest.approx(0.3)                            # and within the range
    assert np.array_equal(out[:, 0], q[:, 0]) and len(notes) == 1 and notes[0].startswith("clipped B:")
    slow = np.column_stack([0.2 * np.sin(t), 0.1 * t])
    assert np.array_equal(check_table(slow, t, names, speed, lo, hi, clip=False)[0], slow)


def test_a_servo_table_through_the_cli_round_trips_and_refuses_a_too_fast_gait(tmp_path, gait_tuner_cmd, run_env):
    path = T.write(tmp_path, T.mjcf(), T.map_yaml(extra=servos_yaml()))
    robot = load_robot(str(path))
    r = run(gait_tuner_cmd, ["trajectory", "--robot", path, "--gait", "tlipfm", "--out", tmp_path / "slow",
                             "--format", "servo", "--no-plot"], run_env)
    assert r.returncode == 0, r.stderr
    lines = (tmp_path / "slow" / "servo.csv").read_text().splitlines()
    assert lines[0].startswith(f"# gait-tuner servo table for robot {robot.name}") and "every 10 ms (100 Hz)" in lines[0]
    assert lines[2].startswith("# the servos it was tuned with (write these into them): pd kp 21.1 N m/rad")
    header = lines[3].split(",")
    ticks = np.array([[float(v) for v in ln.split(",")] for ln in lines[4:]])
    # the same gait in radians, in the robot's names
    r = run(gait_tuner_cmd, ["trajectory", "--robot", path, "--gait", "tlipfm", "--out", tmp_path / "rad",
                             "--no-plot"], run_env)
    assert r.returncode == 0, r.stderr
    rad_lines = [ln for ln in (tmp_path / "rad" / "joints.csv").read_text().splitlines() if not ln.startswith("#")]
    cols = rad_lines[0].split(",")
    rad = np.array([[float(v) for v in ln.split(",")] for ln in rad_lines[1:]])
    ids = {u.id: n for n, u in robot.servo_units.items()}
    assert len(ticks) == len(rad)
    for k, h in enumerate(header[1:], start=1):
        name = ids[int(h[2:])]
        back = from_units(ticks[:, k], robot.servo_units[name])
        assert np.max(np.abs(back - rad[:, cols.index(f"{name}[rad]")])) <= 0.5 / robot.servo_units[name].units_per_rad + 1e-6
    # a fast set: refused in one line naming joint, time and rate, unless --clip
    fast = ["trajectory", "--robot", path, "--params", "kidsize-omni-grass50", "--command", "0.2,0,0",
            "--format", "servo", "--no-plot", "--out"]
    r = run(gait_tuner_cmd, fast + [tmp_path / "fast"], run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "is asked to move at" in r.stderr and "rad/s at t = " in r.stderr and "--clip" in r.stderr
    assert not (tmp_path / "fast" / "servo.csv").exists()
    r = run(gait_tuner_cmd, fast + [tmp_path / "fast", "--clip"], run_env)
    assert r.returncode == 0 and "note: clipped Knee_L" in r.stderr, r.stderr
    # a plain table of the same set says it is too fast for the servos (the simulator limits it)
    r = run(gait_tuner_cmd, ["trajectory", "--robot", path, "--params", "kidsize-omni-grass50", "--command", "0.2,0,0",
                             "--no-plot", "--out", tmp_path / "plain"], run_env)
    assert r.returncode == 0 and "note: the table asks" in r.stderr and "--clip writes" in r.stderr, r.stderr
    # ... and with --clip a plain table is the one the servos play: no move beyond any servo's speed,
    # each changed joint named, the header saying so
    r = run(gait_tuner_cmd, ["trajectory", "--robot", path, "--params", "kidsize-omni-grass50", "--command", "0.2,0,0",
                             "--no-plot", "--clip", "--out", tmp_path / "clipped"], run_env)
    assert r.returncode == 0 and "note: clipped Knee_L" in r.stderr and "the table asks" not in r.stderr, r.stderr
    text = (tmp_path / "clipped" / "joints.csv").read_text().splitlines()
    assert "joint targets clipped to the servos' speed and range" in text[0]
    cols = text[1].split(",")
    data = np.array([[float(v) for v in ln.split(",")] for ln in text[2:]])
    speed = np.array([robot.servos[n].speed for n in robot.servos])
    q = data[:, [cols.index(f"{n}[rad]") for n in robot.servos]]
    assert (np.abs(np.diff(q, axis=0)) / np.diff(data[:, 0])[:, None] <= speed * (1 + 1e-6) + 1e-6).all()


@pytest.mark.parametrize("extra, needle", [
    ("dup", "id 1 given to more than one joint"),
    ("unknown", "'NoSuchJoint' is not an actuated joint"),
    ("ticks", "ticks_per_turn = 0"),
    ("direction", "direction = 2: must be 1 or -1"),
    ("id", "id = 300: expected an integer in [0, 253]"),
    ("field", "unknown field 'speed'"),
    ("one tick", "ticks_per_turn = 1: expected a number in [256, 1e+07] ticks"),
    ("both units", "give ticks_per_turn or units_per_rad, not both"),
])
def test_bad_servos_sections_are_one_line(tmp_path, gait_tuner_cmd, run_env, extra, needle):
    text = servos_yaml()
    text = {"dup": text.replace("{id: 2}", "{id: 1}", 1),
            "unknown": text + "  NoSuchJoint: {id: 99}\n",
            "ticks": text.replace("ticks_per_turn: 4096", "ticks_per_turn: 0"),
            "direction": text.replace("{id: 3}", "{id: 3, direction: 2}"),
            "id": text.replace("{id: 3}", "{id: 300}"),
            "field": text.replace("{id: 3}", "{id: 3, speed: 5}"),
            "one tick": text.replace("ticks_per_turn: 4096", "ticks_per_turn: 1"),
            "both units": text.replace("{id: 3}", "{id: 3, ticks_per_turn: 4096, units_per_rad: 651.9}")}[extra]
    path = T.write(tmp_path, T.mjcf(), T.map_yaml(extra=text))
    r = run(gait_tuner_cmd, ["robot", "check", path, "--no-stand"], run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and needle in r.stderr, r.stderr


def test_a_servo_table_needs_an_id_for_every_column_and_clip_needs_it(tmp_path, gait_tuner_cmd, run_env):
    path = T.write(tmp_path, T.mjcf(), T.map_yaml(extra=servos_yaml(skip="Knee_R")))
    r = run(gait_tuner_cmd, ["trajectory", "--robot", path, "--gait", "tlipfm", "--out", tmp_path / "o",
                             "--format", "servo", "--no-plot"], run_env)
    assert r.returncode == 2 and "no id for joint(s) Knee_R" in r.stderr, r.stderr
    r = run(gait_tuner_cmd, ["trajectory", "--robot", path, "--gait", "tlipfm", "--out", tmp_path / "o",
                             "--clip", "--joint-names", "ours", "--no-plot"], run_env)
    assert r.returncode == 2 and "--clip writes the robot's own joints" in r.stderr, r.stderr


def test_a_servo_table_outside_its_servos_positions_is_refused(tmp_path, gait_tuner_cmd, run_env):
    """A centre that sends positions below 0 (or past one turn) is one line, and nothing is written."""
    path = T.write(tmp_path, T.mjcf(), T.map_yaml(extra=servos_yaml().replace("centre: 2048", "centre: 100")))
    r = run(gait_tuner_cmd, ["trajectory", "--robot", path, "--gait", "tlipfm", "--out", tmp_path / "o",
                             "--format", "servo", "--no-plot", "--clip"], run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "would be sent position -" in r.stderr and "outside its 0..4095" in r.stderr, r.stderr
    assert not [p for p in (tmp_path / "o").rglob("*") if p.name.endswith("servo.csv")]


def test_read_servo_units_defaults():
    units = read_servo_units({"default": {"ticks_per_turn": 1024, "centre": 512}, "A": {"id": 3}}, ("A", "B"), "m")
    assert units["A"] == ServoUnit(3, 1024 / (2 * math.pi), 512.0, 1, 0.0) and "B" not in units


@pytest.mark.parametrize("share", [0.0, 0.95])
def test_an_engine_sets_servo_table_is_the_engines_own_targets(tmp_path, gait_tuner_cmd, run_env, share):
    """`export --format servo` of an engine study: the targets the engine sent walking the command in
    the simulator (its header says so). Capped at 95 % of the servos' speed (engine.servo_share, as
    init's studies are) it passes the servo check; uncapped, its re-plans jump past the servos and
    the export is refused in one line."""
    study = tmp_path / "eng.yaml"
    study.write_text("gait: tlipfm\nbase: kidsize-engine-carpet4\nsurfaces: [carpet4]\n"
                     f"engine: {{servo_share: {share}}}\nspace:\n  engine.k_vel: {{low: 0.5, high: 0.6}}\n"
                     "trials: 1\nenqueue: []\nscenario: {walks: 1, duration: 3.0, min_survival: 0.0}\n")
    r = run(gait_tuner_cmd, ["tune", study, "--runs", tmp_path / "runs", "--workers", "1"], run_env)
    assert r.returncode == 0, r.stderr
    r = run(gait_tuner_cmd, ["export", study, "--runs", tmp_path / "runs", "--format", "servo", "--command",
                             "0.2,0,0", "--out", tmp_path / "best.yaml"], run_env)
    if share:
        assert r.returncode == 0, r.stderr
        text = (tmp_path / "best.servo.csv").read_text()
        assert "the engine's own targets walking it on carpet4 in the simulator" in text.splitlines()[0]
        ticks = np.array([[float(v) for v in ln.split(",")] for ln in text.splitlines()
                          if ln and not ln.startswith("#") and ln[0].isdigit()])
        turn = 4096 / (2 * math.pi)
        fastest = max(s.speed for s in load_robot("kidsize").servos.values())
        assert np.max(np.abs(np.diff(ticks[:, 1:], axis=0))) / turn / 0.01 <= fastest + 1e-6
    else:
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "is asked to move at" in r.stderr
