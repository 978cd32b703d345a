"""examples/robot_loop.py, the loop a team runs on its robot: it walks the stand-in robot with an
engine set with and without an IMU stabiliser, and imports neither the simulator nor the search."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

_RUN = """
import runpy, sys
sys.argv = ["robot_loop.py", {gait!r}, "--dry-run", "--seconds", "3"]
runpy.run_path({loop!r}, run_name="__main__")
heavy = sorted(m for m in ("mujoco", "optuna", "casadi", "scipy", "tuner") if m in sys.modules)
print("imported:", heavy)
"""


@pytest.mark.parametrize("name", ["kidsize-engine-grass50", "kidsize-engine-carpet4"])
def test_the_robot_loop_walks_the_stand_in_and_needs_only_numpy_and_the_engine(name):
    gait = ROOT / "studies" / "results" / f"{name}.yaml"
    code = _RUN.format(gait=str(gait), loop=str(ROOT / "examples" / "robot_loop.py"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "imported: []" in out.stdout
    first = out.stdout.splitlines()[0]
    assert "301 ticks" in first and "ended" in first


def test_the_stabiliser_of_a_set_is_in_the_robot_loop():
    """A set with an IMU stabiliser walks with it on the robot as in the simulator: the loop's
    targets are the engine's plus the stabiliser's corrections of the measured tilt."""
    import runpy

    import numpy as np

    import gaits
    from gaits.control import Measurement
    loop = runpy.run_path(str(ROOT / "gaits" / "robot" / "loop.py"))
    geometry = loop["RobotGeometry"](gaits.LegGeometry(), (0.10, 0.055))
    for name, stabilised in (("kidsize-engine-grass50", True), ("kidsize-engine-carpet4", False)):
        gait = gaits.load_gait_file(ROOT / "studies" / "results" / f"{name}.yaml")
        engine, walk = loop["controller"](gait, geometry, 0.01)
        assert (walk is not engine) == stabilised
        pose = walk.start_pose().q
        n = len(gaits.JOINT_NAMES)
        m = Measurement(0.0, q=pose, dq=np.zeros(n), imu_rpy=np.array([0.0, 0.05, 0.0]), gyro=np.zeros(3),
                        accel=np.array([0.0, 0.0, 9.81]), foot_force=np.full(8, 6.0))
        walk.reset(m)
        q = walk.step(m, np.zeros(3))
        bare, _ = loop["controller"](gait, geometry, 0.01)
        bare.reset(m)
        q0 = bare.step(m, np.zeros(3))
        moved = np.abs(q - q0) > 1e-9
        assert moved.any() == stabilised
        if stabilised:       # only the ankles and hips: pitch by the 0.05 rad tilt
            assert {gaits.JOINT_NAMES[i] for i in np.flatnonzero(moved)} <= {
                f"{s}_{j}" for s in "lr" for j in ("ankle_pitch", "hip_pitch", "ankle_roll", "hip_roll")}


def test_a_trained_residual_of_a_set_is_in_the_robot_loop(tmp_path):
    """A set with a trained residual (gaits/engine/residual.py) walks with it on the robot as in the
    simulator: the loop's targets are the engine's plus the residual's correction of what it senses,
    on the legs only; and the loop walks such a set with numpy alone."""
    import runpy

    import numpy as np

    import gaits
    from gaits.control import Measurement
    from gaits.engine.residual import ResidualParams
    loop = runpy.run_path(str(ROOT / "gaits" / "robot" / "loop.py"))
    geometry = loop["RobotGeometry"](gaits.LegGeometry(), (0.10, 0.055))
    base = gaits.load_gait_file(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml")
    w = np.zeros((2, 6, 12))
    w[0, 2, 6] = 0.1                     # stance hip pitch from the pitch beyond the lean
    path = tmp_path / "with-residual.yaml"
    path.write_text(gaits.gait_file_text(base.params, "", base.stabiliser, base.engine,
                                         ResidualParams.from_matrix(w)))
    gait = gaits.load_gait_file(path)
    n = len(gaits.JOINT_NAMES)
    out = []
    for g in (gait, base):
        engine, walk = loop["controller"](g, geometry, 0.01)
        pose = walk.start_pose().q
        m = Measurement(0.0, q=pose, dq=np.zeros(n), imu_rpy=np.array([0.0, 0.05, 0.0]), gyro=np.zeros(3),
                        accel=np.array([0.0, 0.0, 9.81]), foot_force=np.full(8, 6.0))
        walk.reset(m)
        out.append(walk.step(m, np.zeros(3)))
    moved = {gaits.JOINT_NAMES[i] for i in np.flatnonzero(np.abs(out[0] - out[1]) > 1e-9)}
    assert moved == {"l_hip_pitch", "r_hip_pitch"}
    code = _RUN.format(gait=str(path), loop=str(ROOT / "examples" / "robot_loop.py"))
    ran = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert ran.returncode == 0, ran.stderr
    assert "imported: []" in ran.stdout and "301 ticks" in ran.stdout.splitlines()[0]


def test_a_paper_family_s_online_set_walks_in_the_robot_loop(tmp_path):
    """An EROS set with an engine: section (walked online, re-planned each step) was a traceback in
    the loop (it built the TLIPFM engine from any set); the loop now builds the walk as the
    simulator does (gaits.Drive), numpy alone, and says what it did."""
    import yaml

    import gaits
    doc = yaml.safe_load((gaits.baselines.BASELINE_DIR / "eros-x8-with.yaml").read_text())
    doc["engine"] = {"preview_steps": 2}
    path = tmp_path / "eros-online.yaml"
    path.write_text(yaml.safe_dump(doc))
    code = _RUN.format(gait=str(path), loop=str(ROOT / "examples" / "robot_loop.py"))
    ran = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert ran.returncode == 0, ran.stderr
    first = ran.stdout.splitlines()[0]
    assert "imported: []" in ran.stdout and "301 ticks" in first and "of the online table, re-planned" in first


def test_the_loop_s_walk_is_the_engine_its_residual_and_its_stabiliser_tick_for_tick():
    """The loop builds a set's walk where the simulator does (gaits.Drive.controller), and that walk
    is the engine with the set's residual inside and its IMU stabiliser outside, composed here by
    hand: the same targets from the same noisy readings, tick for tick, and the engine it reports
    is the one inside."""
    import runpy

    import numpy as np
    import yaml

    import gaits
    from gaits.control import Measurement, Stabilised
    from gaits.engine import ResidualWalk
    from gaits.engine.residual import ResidualParams
    from gaits.gait_file import gait_file_from_mapping
    loop = runpy.run_path(str(ROOT / "gaits" / "robot" / "loop.py"))
    geometry = loop["RobotGeometry"](gaits.LegGeometry(), (0.10, 0.055))
    base = gaits.load_gait_file(ROOT / "studies" / "results" / "kidsize-engine-grass50.yaml")
    assert base.stabiliser is not None and base.stabiliser.enabled
    w = np.random.default_rng(2).normal(0, 0.05, (2, 6, 12))
    gait = gait_file_from_mapping(yaml.safe_load(gaits.gait_file_text(base.params, "", base.stabiliser, base.engine,
                                                                      ResidualParams.from_matrix(w))), "test")
    engine, walk = loop["controller"](gait, geometry, 0.01)
    limits = gaits.family("tlipfm").step_limits(gait.params, geometry)
    by_hand = Stabilised(ResidualWalk(gaits.WalkEngine(gait.params, gait.engine, geometry, 0.01, limits),
                                      gait.residual), gait.stabiliser)
    assert type(engine) is gaits.WalkEngine and engine is walk.inner.inner
    n = len(gaits.JOINT_NAMES)
    rng = np.random.default_rng(4)
    pose = walk.start_pose().q
    assert np.array_equal(pose, by_hand.start_pose().q)
    moved = False
    for k in range(80):
        m = Measurement(0.01 * k, q=pose + rng.normal(0, 0.01, n), dq=np.zeros(n),
                        imu_rpy=rng.normal(0, 0.03, 3), gyro=rng.normal(0, 0.1, 3),
                        accel=np.array([0.0, 0.0, 9.81]), foot_force=np.full(8, 6.0))
        if k == 0:
            walk.reset(m)
            by_hand.reset(m)
        q = walk.step(m, np.array([0.1, 0.0, 0.0]))
        assert np.array_equal(q, by_hand.step(m, np.array([0.1, 0.0, 0.0]))), k
        moved = moved or bool(np.any(q != pose))
    assert moved and engine.mode == by_hand.inner.inner.mode


@pytest.mark.parametrize("args, words", [
    (["--max-tilt", "nan"], "--max-tilt: 'nan' is outside (0, 90] deg"),
    (["--max-tilt", "-5"], "--max-tilt: '-5' is outside (0, 90] deg"),
    (["--seconds", "0"], "--seconds: '0' is outside (0, 86400] s"),
    (["--seconds", "nan"], "--seconds: 'nan' is outside"),
    (["--seconds", "-2"], "--seconds: '-2' is outside"),
    (["--watchdog", "0"], "--watchdog: '0' is outside"),
    (["--udp-timeout", "inf"], "--udp-timeout: 'inf' is outside"),
])
def test_a_number_the_loop_cannot_use_is_one_line(capsys, args, words):
    """A NaN tilt limit would never read a fall, a negative one read one at t = 0, --seconds 0 ran
    no tick (an IndexError): each is refused in one line naming the option and its range."""
    from gaits.robot.loop import main
    with pytest.raises(SystemExit) as stop:
        main([str(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"), "--dry-run", *args])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and err.startswith("robot_loop: error:"), err


@pytest.mark.parametrize("make, args, words, code", [
    (lambda p: p.write_bytes(bytes(range(256)) * 8), ["--sweep", "{f}"], "not a sweep (not text", 2),
    (lambda p: os.mkfifo(p), ["--sweep", "{f}"], "is a FIFO", 2),
    (lambda p: p.write_text("t,target.l_knee\n0," + "1" * 200_000 + "\n"), ["--sweep", "{f}"],
     "field larger than field limit", 2),
    (lambda p: p.write_text("a file"), ["--record", "{f}/walk.mcap"], "a file stands where a folder is needed", 2),
])
def test_what_the_loop_cannot_read_or_write_is_one_line(tmp_path, capsys, make, args, words, code):
    """The code that runs on the robot printed tracebacks: a binary sweep (UnicodeDecodeError), a
    --record path inside a file (FileExistsError); a FIFO as the sweep hung, a giant cell raised."""
    from gaits.robot.loop import main
    f = tmp_path / "input.csv"
    make(f)
    argv = [a.format(f=f) for a in args]
    if "--sweep" not in argv:
        argv = [str(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"), *argv]
    with pytest.raises(SystemExit) as stop:
        main([*argv, "--dry-run", "--seconds", "0.5"])
    assert stop.value.code == code
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and err.startswith("robot_loop: error:"), err


def test_a_full_disk_under_the_loop_s_recording_is_one_line_and_exit_3(tmp_path, capsys, monkeypatch):
    """A recording on a full disk: one line, exit 3, the older recording of the name kept."""
    import errno as _errno
    from gaits.robot.loop import main
    old = tmp_path / "walk.mcap"
    old.write_bytes(b"an older walk")

    def full(fd):
        raise OSError(_errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(SystemExit) as stop:
        main([str(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"), "--dry-run", "--seconds", "0.2",
              "--record", str(old)])
    assert stop.value.code == 3 and old.read_bytes() == b"an older walk"
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "No space left on device" in err, err
