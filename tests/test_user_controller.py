"""Bring your own controller: a team's class named in a YAML walks, is stress-tested and is tuned
by a study through the CLI, like the built-in gaits; every mistake in its file is one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tuner.controllers import load_controller
from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "controllers"


def run(cmd, args, env, **kw):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env, **kw)


def test_the_example_controller_walks_and_reports_its_plan(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["simulate", "--controller", EXAMPLE / "march.yaml", "--surface", "rigid",
                             "--duration", "3", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert "controller " in out["drive"] and "march.py:MarchInPlace" in out["drive"]
    assert out["metrics"]["walk_time_s"] == pytest.approx(2.5, abs=0.02)     # from its own walk_start


def test_a_tiny_study_tunes_it_end_to_end(gait_tuner_cmd, run_env, tmp_path):
    runs = tmp_path / "runs"
    study = EXAMPLE / "march-study.yaml"
    r = run(gait_tuner_cmd, ["tune", study, "--trials", "4", "--workers", "2", "--runs", runs], run_env)
    assert r.returncode == 0, r.stderr
    assert "runs the code of a controller of your own" in r.stdout and "march.py:MarchInPlace" in r.stdout
    out = tmp_path / "best.yaml"
    r = run(gait_tuner_cmd, ["export", study, "--runs", runs, "--out", out], run_env)
    assert r.returncode == 0, r.stderr
    doc = yaml.safe_load(out.read_text())
    assert doc["class"].endswith("march.py:MarchInPlace") and "trial" in doc["description"]
    tuned = load_controller(out)
    shipped = load_controller(EXAMPLE / "march.yaml")
    assert set(tuned.params) == set(shipped.params) and tuned.ranges == shipped.ranges
    for name, (lo, hi) in shipped.ranges.items():
        assert lo <= tuned.params[name] <= hi
    trials = json.loads(run(gait_tuner_cmd, ["trials", study, "--runs", runs, "--json"], run_env).stdout)
    assert trials["trials"] == 4 and {"controller.period", "controller.sway"} <= set(trials["shown"][0]["params"])
    r = run(gait_tuner_cmd, ["simulate", "--controller", out, "--surface", "rigid", "--duration", "2"], run_env)
    assert r.returncode == 0, r.stderr
    r = run(gait_tuner_cmd, ["robustness", "--controller", out, "--surface", "rigid", "--rollouts", "2",
                             "--pushes", "", "--duration", "2"], run_env)
    assert r.returncode == 0 and "survival" in r.stdout, r.stderr


def _controller_file(folder: Path, cls: str, code: str | None = None, **extra) -> Path:
    if code is not None:
        (folder / "mine.py").write_text(code)
    doc = {"class": cls, "params": {"a": 1.0}, **extra}
    path = folder / "mine.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize("cls, code, extra, message", [
    ("mine.py", None, {}, "expected path/to/file.py:ClassName"),
    ("nothere.py:C", None, {}, "no such file"),
    ("mine.py:C", "raise RuntimeError('no servo bus')\n", {}, "importing mine.py failed: RuntimeError: no servo bus"),
    ("mine.py:C", "X = 1\n", {}, "has no class 'C'"),
    ("no_such_module_xyz:C", None, {}, "importing no_such_module_xyz failed: ModuleNotFoundError"),
    ("mine.py:C", "class C: pass\n", {"ranges": {"a": {"low": 2.0, "high": 3.0}}}, "params.a = 1 lies outside"),
    ("mine.py:C", "class C: pass\n", {"ranges": {"b": {"low": 0.0, "high": 3.0}}}, "ranges.b: not one of the params"),
    ("mine.py:C", "class C: pass\n", {"colour": "red"}, "unknown key 'colour'"),
    ("mine.py:C", "class C:\n    def __init__(self, p, r, dt):\n        self.dt = dt\n", {},
     "lacks start_pose, reset, step, plan"),
    ("mine.py:C", "import sys\nsys.exit(3)\n", {}, "importing mine.py called sys.exit(3)"),
    ("mine.py:C", "import time\ntime.sleep(60)\n", {"time_limit": {"import": 1}},
     "importing mine.py ran past its limit of 1 s (time_limit.import in the file) and was stopped"),
    ("mine.py:C", "class C: pass\n", {"time_limit": {"tick": 0}}, "time_limit.tick = 0: expected a number in [0.01, 60] s"),
    ("mine.py:C", "class C: pass\n", {"time_limit": {"call": 1}}, "time_limit: unknown key 'call'"),
])
def test_a_bad_controller_file_is_one_line(gait_tuner_cmd, run_env, tmp_path, cls, code, extra, message):
    path = _controller_file(tmp_path, cls, code, **extra)
    r = run(gait_tuner_cmd, ["simulate", "--controller", path, "--surface", "rigid", "--duration", "1"], run_env)
    assert r.returncode == 2, r.stderr
    assert message in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


_STANDS = ("import numpy as np\nfrom gaits.control import HoldPose\n\n\n"
           "def helper():\n    return 1 / 0\n\n\n"
           "class C(HoldPose):\n    def __init__(self, p, robot, dt):\n        super().__init__(np.zeros(20), dt)\n")


@pytest.mark.parametrize("body, message", [
    ("    def step(self, m, command=None):\n        return helper()\n",
     "controller {path}:C: step() at t = 0.00 s raised ZeroDivisionError: division by zero ({path}, line 6)"),
    ("    def start_pose(self):\n        raise KeyError('l_knee')\n",
     "controller {path}:C: start_pose() raised KeyError: 'l_knee' ({path}, line 13)"),
    ("    def step(self, m, command=None):\n        return self.q[:19]\n",
     "the controller ({path}:C) returned targets of shape (19,) at t = 0.00 s; expected (20,)"),
    ("    def step(self, m, command=None):\n        return ['up'] * 20\n",
     "returned targets that are not numbers at t = 0.00 s (e.g. 'up')"),
    ("    def step(self, m, command=None):\n        return self.q + 0j\n",
     "controller {path}:C: step() at t = 0.00 s returned complex targets"),
    ("    def start_pose(self):\n        return None\n",
     "controller {path}:C: start_pose() returned None: expected gaits.control.StartPose(q) with 20 joint angles"),
    ("    def start_pose(self):\n        from gaits.control import StartPose\n        return StartPose(np.zeros(12))\n",
     "controller {path}:C: start_pose() returned 12 angles"),
    ("    def plan(self, n):\n        return None\n", "controller {path}:C: plan() returned None"),
    ("    dt = 0.02\n    def __init__(self, p, robot, dt):\n        super().__init__(np.zeros(20), dt)\n"
     "        self.dt = 0.02\n", "has dt = 0.02: expected the control period it was built with, 0.01 s"),
    ("    def __init__(self, p, robot, dt):\n        super().__init__(np.zeros(20), dt)\n        self.dt = 'fast'\n",
     "has dt = 'fast'"),
    ("    def __init__(self, p, robot, dt):\n        super().__init__(np.zeros(20), dt)\n        self.duration = -1.0\n",
     "has duration = -1.0: expected a positive number of seconds"),
    ("    senses = ('q', 'lidar')\n", "has senses naming 'lidar': not a reading"),
    ("    def step(self, m, command=None):\n        import time\n        time.sleep(30)\n        return self.q\n",
     "controller {path}:C: step() at t = 0.00 s ran past its limit of 1 s a call (time_limit in its file) and was "
     "stopped"),
])
def test_a_mistake_in_the_controllers_code_is_one_line_naming_it(gait_tuner_cmd, run_env, tmp_path, body, message):
    """An exception the user's code raises while walking, or targets of the wrong shape, is the
    user's to fix: one line naming the controller and the line of its file, exit 2 (it was an
    internal error, "please report it", exit 1)."""
    path = _controller_file(tmp_path, "mine.py:C", _STANDS + body)
    r = run(gait_tuner_cmd, ["simulate", "--controller", path, "--surface", "rigid", "--duration", "1"], run_env)
    assert r.returncode == 2, r.stderr
    assert message.format(path=tmp_path / "mine.py") in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_a_walk_past_its_limit_is_stopped_and_named(gait_tuner_cmd, run_env, tmp_path):
    """Each call within its limit, the walk's calls together past theirs."""
    body = "    def step(self, m, command=None):\n        import time\n        time.sleep(0.05)\n        return self.q\n"
    path = _controller_file(tmp_path, "mine.py:C", _STANDS + body, time_limit={"walk": 1})
    r = run(gait_tuner_cmd, ["simulate", "--controller", path, "--surface", "rigid", "--duration", "5"], run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "ran past its limit of 1 s a walk (time_limit in its file)" in r.stderr, r.stderr


def test_a_target_that_is_not_finite_ends_the_walk_as_diverged(gait_tuner_cmd, run_env, tmp_path):
    """A NaN target would reach MuJoCo, which zeroes every servo's target and walks on (the robot
    falls limp, and it read as a fall); the walk ends there instead, diverged, naming the joint."""
    body = ("    def step(self, m, command=None):\n        q = self.q.copy()\n"
            "        q[5] = float('nan') if m.t >= 0.3 else 0.0\n        return q\n")
    path = _controller_file(tmp_path, "mine.py:C", _STANDS + body)
    r = run(gait_tuner_cmd, ["simulate", "--controller", path, "--surface", "rigid", "--duration", "1", "--json"],
            run_env)
    assert r.returncode == 0, r.stderr
    metrics = json.loads(r.stdout)["metrics"]
    assert metrics["outcome"] == "diverged" and not metrics["fell"]
    assert metrics["reason"] == "diverged: the controller's target for r_shoulder_pitch is nan at t = 0.30 s"
    assert "WARNING" not in r.stderr


def test_a_study_names_its_controller_or_a_gait_not_both(gait_tuner_cmd, run_env, tmp_path):
    study = tmp_path / "s.yaml"
    study.write_text(f"controller: {EXAMPLE / 'march.yaml'}\ngait: tlipfm\nsurfaces: [rigid]\n")
    r = run(gait_tuner_cmd, ["tune", study, "--runs", tmp_path / "runs"], run_env)
    assert r.returncode == 2 and "'gait' does not go with 'controller'" in r.stderr
    study.write_text(f"controller: {EXAMPLE / 'march.yaml'}\nsurfaces: [rigid]\n"
                     "space: {controller.height: {low: 0.1, high: 0.3}, controller.nope: {low: 0, high: 1}}\n")
    r = run(gait_tuner_cmd, ["tune", study, "--runs", tmp_path / "runs"], run_env)
    assert r.returncode == 2 and "'controller.nope' is not controller.NAME" in r.stderr
    r = run(gait_tuner_cmd, ["simulate", "--controller", EXAMPLE / "march.yaml", "--params", "tkux-table2"], run_env)
    assert r.returncode == 2 and "not both" in r.stderr
