"""Walk commands in simulation: simulate/trajectory --command, the speed test, speed studies."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gaits import SpeedStaircase, TlipfmParams
from tuner.errors import UserError
from tuner.robots import load_robot
from tuner.sim.rollout import Simulator
from tuner.search.study import load_study
from tuner.sim.surfaces import load_surface
from tuner.sim.walk_speed import command_limit, speed_test
from conftest import run_cli

SPEEDY = dict(period=0.3, t1=0.0375, t2=0.2625, h_z=0.025, a=0.0)


def _run(cmd, args, env, cwd=None):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env, cwd=cwd)


def test_simulate_command_json_reports_achieved_beside_commanded(gait_tuner_cmd, run_env):
    r = _run(gait_tuner_cmd, ["simulate", "--params", "tkux-table2", "--surface", "carpet4",
                              "--command", "0.05,0,0", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["command"] == {"vx_mps": 0.05, "vy_mps": 0.0, "wz_radps": 0.0}
    m = out["metrics"]
    assert not m["fell"]
    assert 0.8 * 0.05 <= m["vx_mps"] <= 1.2 * 0.05
    assert abs(m["vy_mps"]) < 0.01 and abs(m["wz_radps"]) < 0.05


@pytest.mark.parametrize("args, text", [
    (["--params", "tkux-table2", "--command", "0.5,0,0"], "beyond max_forward"),
    (["--params", "tkux-table2", "--command", "0.1,0"], "three numbers"),
    (["--params", "cosine-setiono", "--command", "0,0.01,0"], "walks forward and backward only"),
    (["--params", "eros-x24-with", "--command", "0,0,0.5"], "closer than min_gap"),
])
def test_bad_commands_are_one_line_exit_2(gait_tuner_cmd, run_env, args, text):
    r = _run(gait_tuner_cmd, ["simulate", *args], run_env)
    assert r.returncode == 2
    assert text in r.stderr and len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


@pytest.mark.parametrize("command, axis, low, high", [("0.05,0,0", "vx_mps", 0.04, 0.06),
                                                     ("0,0,0.2", "wz_radps", 0.15, 0.3)])
def test_eros_walks_a_command(gait_tuner_cmd, run_env, command, axis, low, high):
    """EROS's paper gait at 8 mm settings walks forward and turns on carpet (measured: 0.049 m/s
    for 0.05, 0.26 rad/s for 0.2)."""
    r = _run(gait_tuner_cmd, ["simulate", "--params", "eros-x8-with", "--surface", "carpet4",
                              f"--command={command}", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)["metrics"]
    assert not m["fell"] and low <= m[axis] <= high


def test_trajectory_command_writes_a_turning_table(gait_tuner_cmd, run_env, tmp_path):
    r = _run(gait_tuner_cmd, ["trajectory", "--params", "tkux-table2", "--command", "0.02,0,0.2",
                              "--out", str(tmp_path), "--no-plot", "--joint-names", "ours"], run_env)
    assert r.returncode == 0, r.stderr
    lines = (tmp_path / "joints.csv").read_text().splitlines()
    assert "command 0.02,0,0.2 (vx m/s, vy m/s, wz rad/s, ramped)" in lines[0]
    header = lines[1].split(",")
    data = np.loadtxt(lines[2:], delimiter=",")
    yaw = data[:, header.index("pelvis_yaw[rad]")]
    # 4 + 12 + 4 steps at 0.64 s and wz ramped: the heading turns sum(fractions) x wz x T
    expected = 0.2 * 0.64 * (2 * sum(k / 5 for k in range(1, 5)) + 12)
    assert yaw[-1] == pytest.approx(expected, rel=0.15)
    assert np.ptp(data[:, header.index("l_hip_yaw[rad]")]) > 0.05


def test_speed_test_holds_stairs_in_order_and_respects_step_limits():
    robot = load_robot("kidsize")
    sim = Simulator(robot, load_surface("carpet4"))
    p = TlipfmParams().replace(**SPEEDY)
    r = speed_test(sim, p, SpeedStaircase("forward", 0.2, levels=4), tolerance=0.3)
    assert r.levels == pytest.approx((0.05, 0.1, 0.15, 0.2))
    held = [a >= 0.7 * v for a, v in zip(r.achieved, r.levels)]
    expect = 0.0
    for ok, v in zip(held, r.levels):
        if not ok:
            break
        expect = v
    assert r.reached == expect and r.reached >= 0.1
    # a staircase beyond the step limits is cut at the last stair the planner allows
    lim = command_limit(p, robot, "left")
    r2 = speed_test(sim, p, SpeedStaircase("left", 3 * lim, levels=6), tolerance=0.3)
    assert max(r2.levels) <= lim + 1e-9 and len(r2.levels) == 2


def test_speed_study_validation(tmp_path):
    base = ("gait: tlipfm\nbase: tkux-table2\nsurfaces: [carpet4]\nspace: {period: {low: 0.3, high: 0.4}}\n"
            "fixed: {t1: 0.04, t2: 0.25}\n")
    cases = {
        "speed:\n  directions: {up: {top: 0.2}}\n": "unknown direction 'up'",
        "speed:\n  directions: {forward: {top: 5}}\n": "speed.directions.forward.top = 5",
        "speed:\n  directions: {forward: {top: 0.2}}\n  steps_per_level: 3\n": "must be even",
        "objectives: [pitch_rms]\nspeed:\n  directions: {forward: {top: 0.2}}\n": "remove 'objectives'",
    }
    for extra, text in cases.items():
        f = tmp_path / "s.yaml"
        f.write_text(base + extra)
        with pytest.raises(UserError, match=text.replace("(", r"\(").replace(".", r"\.")):
            load_study(str(f))
    f.write_text(base + "speed:\n  directions: {forward: {top: 0.2}, left: {top: 0.1, weight: 2}}\n  mode: pareto\n")
    spec = load_study(str(f))
    assert spec.objectives == ("forward", "left", "pitch_rms")
    assert spec.directions == ["maximize", "maximize", "minimize"]


def test_tiny_speed_study_end_to_end(gait_tuner_cmd, run_env, tmp_path):
    study = tmp_path / "tiny.yaml"
    study.write_text(
        "name: tiny-speed\nrobot: kidsize\nsurfaces: [carpet4]\ngait: tlipfm\nbase: tkux-table2\n"
        "fixed: {t1: 0.04, t2: 0.21}\n"
        "space:\n  period: {low: 0.25, high: 0.4}\n  h_z: {low: 0.015, high: 0.04}\n"
        "speed:\n  directions: {forward: {top: 0.3}, turn_left: {top: 1.0, weight: 0.2}}\n  levels: 4\n"
        "trials: 4\n")
    r = _run(gait_tuner_cmd, ["tune", str(study), "--runs", str(tmp_path / "runs")], run_env)
    assert r.returncode == 0, r.stderr
    assert "speed score" in r.stdout and "forward" in r.stdout and "turn_left" in r.stdout
    out = tmp_path / "best.yaml"
    r = _run(gait_tuner_cmd, ["export", str(study), "--runs", str(tmp_path / "runs"), "--out", str(out)], run_env)
    assert r.returncode == 0, r.stderr
    # the exported set walks the forward stair the study says it held
    from optuna import load_study as optuna_load
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend
    st = optuna_load(study_name="tiny-speed", storage=JournalStorage(JournalFileBackend(
        str(tmp_path / "runs" / "tiny-speed.journal"))))
    best = max(st.trials, key=lambda t: t.values[0])
    assert best.user_attrs["speed"]["by_direction"]["forward"] > 0
    r = _run(gait_tuner_cmd, ["simulate", "--params", str(out), "--surface", "carpet4", "--command",
                              f"{best.user_attrs['speed']['by_direction']['forward']},0,0", "--json"], run_env)
    assert r.returncode == 0, r.stderr
