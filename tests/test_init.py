"""`gait-tuner init`: a walk made for a robot from its own model (tuner/search/initial.py)."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from conftest import ROOT
from tuner.robots import load_robot
from tuner.search.initial import leg_masses
from tuner.search.study import load_study

MAP = ROOT / "examples" / "robots" / "kid3kg" / "kid3kg.yaml"


def test_the_built_in_robot_gets_tku_xs_masses_back():
    """The built-in robot carries TKU-X's mass distribution: its three masses come back exactly."""
    upper, thigh, calf, sources = leg_masses(load_robot("kidsize"))
    assert (round(upper, 6), round(thigh, 6), round(calf, 6)) == (3.05, 0.2, 0.75)
    assert set(sources) == {"mass_upper", "mass_thigh", "mass_calf"}


def test_a_robots_masses_add_up_to_its_model():
    robot = load_robot(str(MAP))
    upper, thigh, calf, _ = leg_masses(robot)
    assert upper + 2 * (thigh + calf) == pytest.approx(float(np.sum(robot.model().body_mass)))
    assert thigh > 0 and calf > 0 and upper > thigh + calf


def test_init_writes_a_study_and_a_start_that_walk_the_robot(tmp_path, gait_tuner_cmd, run_env):
    out = tmp_path / "init"
    r = subprocess.run(gait_tuner_cmd + ["init", "--robot", str(MAP), "--surface", "grass30", "--out", str(out)],
                       capture_output=True, text=True, env=run_env)
    assert r.returncode == 0, r.stderr
    assert "mass_upper" in r.stdout and "from the model's" in r.stdout and "knee servo's 6.5 rad/s" in r.stdout
    study = out / "kid3kg-grass30-match.yaml"
    spec = load_study(str(study))
    assert spec.kind == "match" and spec.base.mass_upper == pytest.approx(1.96, abs=0.01)
    assert spec.robot == str(MAP.resolve()) and spec.engine is not None
    start = out / "kid3kg-grass30-match-start.yaml"
    r = subprocess.run(gait_tuner_cmd + ["simulate", "--robot", str(MAP), "--params", str(start), "--surface",
                                         "grass30", "--command", "0.1,0,0", "--json"], capture_output=True, text=True,
                       env=run_env)
    m = json.loads(r.stdout)["metrics"]
    assert m["outcome"] == "completed" and 0.08 < m["vx_mps"] < 0.14, m
    r = subprocess.run(gait_tuner_cmd + ["tune", str(study), "--trials", "2", "--workers", "1", "--runs",
                                         str(tmp_path / "runs")], capture_output=True, text=True, env=run_env)
    assert r.returncode == 0, r.stderr[-2000:]
    # two trials of match walks may all stop at their falls: then it says so (it was an internal error)
    assert r.stdout.strip().splitlines()[-1].startswith(("export it with", "no trial of study kid3kg-grass30-match "
                                                                          "completed yet")), r.stdout
    r = subprocess.run(gait_tuner_cmd + ["trials", str(study), "--runs", str(tmp_path / "runs"), "--json"],
                       capture_output=True, text=True, env=run_env)
    assert json.loads(r.stdout)["trials"] == 2


@pytest.mark.parametrize("purpose, kind", [("speed", "speed"), ("push", "challenge")])
def test_init_for_speed_and_push(tmp_path, gait_tuner_cmd, run_env, purpose, kind):
    out = tmp_path / purpose
    r = subprocess.run(gait_tuner_cmd + ["init", "--surface", "carpet4", "--for", purpose, "--out", str(out)],
                       capture_output=True, text=True, env=run_env)
    assert r.returncode == 0, r.stderr
    assert load_study(str(out / f"kidsize-carpet4-{purpose}.yaml")).kind == kind
