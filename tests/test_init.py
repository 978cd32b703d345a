"""`gait-tuner init`: a walk made for a robot from its own model (tuner/search/initial.py)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import yaml

from conftest import ROOT
from tuner.robots import load_robot
from tuner.search.initial import GAIN_MARGIN, REACH_MAX, SPEED_MARGIN, initial_walk, leg_gains, leg_masses
from tuner.sim.surfaces import load_surface
from tuner.search.study import load_study
from conftest import run_cli, run_in_process

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
    r = run_cli(gait_tuner_cmd, ["init", "--robot", str(MAP), "--surface", "grass30", "--out", str(out)], run_env)
    assert r.returncode == 0, r.stderr
    assert "warning" not in r.stderr, r.stderr            # it stands in the start's pose
    assert "mass_upper" in r.stdout and "from the model's" in r.stdout and "servo's 6.5 rad/s" in r.stdout
    # kid3kg's MJCF states its servos' gains: init keeps them; the study walks a map beside it that
    # extends the team's as it is (every later command walks the set on it)
    assert "the robot's own (its file or its map states them)" in r.stdout
    copy = out / "kid3kg-grass30-match-robot.yaml"
    assert yaml.safe_load(copy.read_text()) == {"extends": os.path.relpath(MAP.resolve(), out.resolve())}
    study = out / "kid3kg-grass30-match.yaml"
    spec = load_study(str(study))
    assert spec.kind == "match" and spec.base.mass_upper == pytest.approx(1.96, abs=0.01)
    assert spec.robot == str(copy.resolve()) and spec.engine is not None
    assert load_robot(str(copy)).name == "kid3kg"
    # its journal beside it (runs: runs): tune, trials, export find it from any folder
    assert spec.runs == out / "runs"
    from conftest import run_in_process
    r2 = run_in_process(["trials", str(study)], cwd=tmp_path / "init")
    assert r2.returncode == 2 and f"in {out / 'runs' / 'kid3kg-grass30-match.journal'}" in r2.stderr, r2.stderr
    # a held-out stream of the walks it tunes for (its speeds, the evaluation draws), and the lines
    # that follow tune: export, then robustness on the robot the study walks with that stream
    from tuner.streams import load_stream
    stream = load_stream(out / "kid3kg-grass30-match-stream.csv")
    assert stream.t[-1] == pytest.approx(60.0) and np.max(stream.commands[:, 0]) <= 0.2 + 1e-9
    assert np.max(np.abs(stream.commands[:, 1])) <= 0.05 + 1e-9 and np.max(np.abs(stream.commands[:, 2])) <= 0.5 + 1e-9
    assert f"gait-tuner robustness --robot {copy} --params {out / 'best.yaml'} --surface grass30 --commands " \
           f"{out / 'kid3kg-grass30-match-stream.csv'}" in r.stdout
    # the study's engine caps its targets at the servos' speed, as its start set does
    assert spec.engine.servo_share == 0.95 and spec.settings.servo_share == 1.0
    assert spec.settings.scenario.forward == 0.2
    # the start at shorter periods is tried first too: written beside it, listed as the study's baselines
    rungs = sorted(out.glob("kid3kg-grass30-match-start-*ms.yaml"), key=lambda p: -int(p.stem.split("-")[-1][:-2]))
    assert yaml.safe_load(study.read_text())["baselines"] == [p.name for p in rungs] and len(rungs) >= 1
    ours = [b for b in spec.baselines if b.mass_upper == spec.base.mass_upper]
    assert len(ours) == len(rungs) and all(b.period < spec.base.period for b in ours)
    assert "also tried" in r.stdout
    start = out / "kid3kg-grass30-match-start.yaml"
    r = run_cli(gait_tuner_cmd, ["simulate", "--robot", str(MAP), "--params", str(start), "--surface",
                                         "grass30", "--command", "0.1,0,0", "--json"], run_env)
    m = json.loads(r.stdout)["metrics"]
    assert m["outcome"] == "completed" and 0.08 < m["vx_mps"] < 0.14, m
    r = run_cli(gait_tuner_cmd, ["tune", str(study), "--trials", "2", "--workers", "1", "--runs",
                                         str(tmp_path / "runs")], run_env)
    assert r.returncode == 0, r.stderr[-2000:]
    # two trials of match walks may all stop at their falls: then it says so (it was an internal error)
    assert r.stdout.strip().splitlines()[-1].startswith(("export it with", "no trial of study kid3kg-grass30-match "
                                                                          "completed yet",
                                                         "no feasible trial of study kid3kg-grass30-match")), r.stdout
    r = run_cli(gait_tuner_cmd, ["trials", str(study), "--runs", str(tmp_path / "runs"), "--json"], run_env)
    shown = json.loads(r.stdout)["shown"]
    # two walked (the CasADi seed, the start); the shorter-period starts wait for the next run
    assert [t["state"] for t in shown].count("waiting") == len(rungs) and len(shown) == 2 + len(rungs)
    assert {t["start"] for t in shown if t["state"] != "waiting"} == {"casadi seed", "baseline 0"}


@pytest.mark.parametrize("purpose, kind", [("speed", "speed"), ("push", "challenge")])
def test_init_for_speed_and_push(tmp_path, gait_tuner_cmd, run_env, purpose, kind):
    out = tmp_path / purpose
    r = run_cli(gait_tuner_cmd, ["init", "--surface", "carpet4", "--for", purpose, "--out", str(out)], run_env)
    assert r.returncode == 0, r.stderr
    assert load_study(str(out / f"kidsize-carpet4-{purpose}.yaml")).kind == kind


def test_gains_are_sized_to_the_weight_only_where_nothing_states_them(tmp_path):
    """A URDF has no servo gains: the legs' stiffness is GAIN_MARGIN x m g z_c, written as the P
    register that gives it on the default MX-64 at its voltage (its back-EMF damps it; a pd preset's
    kp and a kv keeping its damping ratio); a map that states the legs' kp (or a preset) keeps it;
    the built-in robot keeps its own."""
    import dataclasses

    import test_urdf as U
    from tuner.servos import preset
    path = U.workspace(tmp_path, U.mesh_urdf())
    robot = load_robot(str(path))
    assert "legs" in robot.preset_gains
    mass = float(np.sum(robot.model().body_mass))
    gains, why = leg_gains(robot, mass, 0.2)
    expected = 5.0 * round(GAIN_MARGIN * mass * 9.81 * 0.2 / 5.0)
    knee = robot.servo_of("l_knee")
    assert gains["p_gain"] == pytest.approx(expected / (knee.gain / knee.p_gain), abs=0.05)
    assert f"{mass:.2f} kg x 9.81 x 0.200 m" in why and "P " in why
    old = dataclasses.replace(robot, servos={k: preset("MX-64-pd") for k in robot.servos})
    pd_gains, _ = leg_gains(old, mass, 0.2)
    assert pd_gains["kp"] == expected and pd_gains["kv"] == pytest.approx(0.5 * np.sqrt(expected / 40.0), abs=0.005)
    stated = U.workspace(tmp_path / "stated", U.mesh_urdf(), extra="servo: {knees: {kp: 70}}\n")
    assert "legs" not in load_robot(str(stated)).preset_gains
    assert leg_gains(load_robot(str(stated)), mass, 0.2)[0] == {}
    assert leg_gains(load_robot("kidsize"), 4.95, 0.19)[0] == {}
    assert load_robot(str(MAP)).preset_gains == ()


def test_init_writes_the_sized_gains_into_a_copy_of_the_map(tmp_path, gait_tuner_cmd, run_env):
    """The study walks a copy of the team's map (paths rebased) with the legs' gains in its servo:
    section; the team's own map is not touched."""
    import test_urdf as U
    path = U.workspace(tmp_path, U.mesh_urdf())
    before = path.read_text()
    out = tmp_path / "elsewhere" / "init"
    r = run_cli(gait_tuner_cmd, ["init", "--robot", str(path), "--surface", "rigid", "--out", str(out)], run_env)
    assert r.returncode == 0, r.stderr
    assert "legs p_gain" in r.stdout and "sized to the weight" in r.stdout
    copy = out / f"{load_robot(str(path)).name}-rigid-match-robot.yaml"
    spec = load_study(str(next(out.glob("*-match.yaml"))))
    assert spec.robot == str(copy.resolve())
    robot = load_robot(str(copy))
    knee = robot.servos[robot.joint_map["l_knee"][0]]
    assert knee.kp > 5 and abs(knee.kp - 5 * round(knee.kp / 5)) < 0.05 and knee.p_gain != 32.0
    assert "legs" not in robot.preset_gains
    assert path.read_text() == before
    # it extends the team's map: an edit there (the arms' servo) reaches the study's robot, the
    # sized legs stay
    assert "extends" in yaml.safe_load(copy.read_text())
    path.write_text(before + "\nfoot_sensors: false\n")
    edited = load_robot(str(copy))
    assert not edited.foot_sensors and edited.servos[edited.joint_map["l_knee"][0]].kp == pytest.approx(knee.kp)


def test_the_start_period_gives_the_top_speed_within_its_reach():
    """A period the knee rule would make too long for the top speed's steps is shortened to
    REACH_MAX leg lengths at SPEED_MARGIN x the speed, and says what share of the knee it asks; the
    envelope then reaches the speed; a speed the knee cannot give is one line."""
    from tuner.errors import UserError
    robot = load_robot(str(MAP))
    legs = robot.leg.thigh + robot.leg.shank
    iw = initial_walk(robot, str(MAP), load_surface("grass30"), top_speed=0.2)
    assert iw.params.period == pytest.approx(REACH_MAX * legs / (SPEED_MARGIN * 0.2), abs=1e-3)
    assert "of its servo's 6.5 rad/s" in iw.sources["period"]
    assert iw.params.reach_forward * legs / iw.params.period >= 0.2 * SPEED_MARGIN - 1e-3
    assert iw.study["scenario"]["forward"] == 0.2
    slow = initial_walk(robot, str(MAP), load_surface("grass30"), top_speed=0.1)
    assert slow.params.period > iw.params.period and "at most half of it" in slow.sources["period"]
    with pytest.raises(UserError, match="asks the knee servo for"):
        initial_walk(robot, str(MAP), load_surface("grass30"), top_speed=0.6)


def test_the_period_searched_reaches_down_to_the_knees_limit():
    """The study searches periods down to the one whose swing asks the knee KNEE_MAX of its servo's
    speed for the start's lift (pi h_z / t_ssp over the shorter link), up to 1.1 x the start's."""
    import math
    from tuner.search.initial import KNEE_MAX, T1_SHARE, T2_SHARE
    robot = load_robot(str(MAP))
    iw = initial_walk(robot, str(MAP), load_surface("grass30"), top_speed=0.1)
    knee = robot.servos[robot.joint_map["l_knee"][0]].speed
    lever = min(robot.leg.thigh, robot.leg.shank)
    fastest = math.pi * iw.params.h_z / (KNEE_MAX * knee * lever) / (T2_SHARE - T1_SHARE)
    rng = iw.study["space"]["period"]
    assert rng["low"] == pytest.approx(fastest, abs=1e-4) and rng["low"] < 0.7 * iw.params.period
    assert rng["high"] == pytest.approx(1.1 * iw.params.period, abs=1e-4)
    # the step's timing: shares of the period drawn around TKU-X's, every draw t1 < t2 < period with a
    # single support of SSP_MIN of its period (as times, t2 passed a short period in 6-20 % of draws)
    from tuner.search.initial import SSP_MIN
    t1, t2 = iw.study["space"]["t1"], iw.study["space"]["t2"]
    assert t1["of"] == t2["of"] == "period"
    assert t1["low"] <= T1_SHARE <= t1["high"] and t2["low"] <= T2_SHARE <= t2["high"] < 1
    assert t2["low"] - t1["high"] >= SSP_MIN - 1e-9


def test_the_start_is_also_tried_at_the_periods_the_knee_carries_at_higher_shares():
    """The ladder: the start at the periods whose swing asks the knee LADDER_SHARES of its servo's
    speed (pi h_z / t_ssp over the shorter link), t1 and t2 at TKU-X's shares, only where shorter than
    the start's period; everything else as the start."""
    import math
    from tuner.search.initial import LADDER_SHARES, T1_SHARE, T2_SHARE
    robot = load_robot(str(MAP))
    iw = initial_walk(robot, str(MAP), load_surface("grass30"), top_speed=0.1)
    knee = robot.servos[robot.joint_map["l_knee"][0]].speed
    lever = min(robot.leg.thigh, robot.leg.shank)
    assert [s for s, _ in iw.ladder] == list(LADDER_SHARES)
    for share, rung in iw.ladder:
        t_ssp = rung.t2 - rung.t1
        assert math.pi * rung.h_z / t_ssp / lever / knee == pytest.approx(share, rel=2e-3)
        assert rung.t1 / rung.period == pytest.approx(T1_SHARE, rel=2e-3)
        assert rung.t2 / rung.period == pytest.approx(T2_SHARE, rel=2e-3)
        assert rung.period < iw.params.period
        assert rung.replace(period=iw.params.period, t1=iw.params.t1, t2=iw.params.t2) == iw.params
    # a start already shortened for a top speed: only the rungs shorter than it
    fast = initial_walk(robot, str(MAP), load_surface("grass30"), top_speed=0.3)
    asked = math.pi * fast.params.h_z / (fast.params.t2 - fast.params.t1) / lever / knee
    assert [s for s, _ in fast.ladder] == [s for s in LADDER_SHARES if s > asked * 1.01]
    assert len(fast.ladder) < len(iw.ladder)


def test_init_says_when_the_robot_falls_standing(tmp_path):
    """Legs whose servos cannot hold the robot's weight (0.4 N m): init still writes its files, and
    says on stderr that the robot falls standing in the start's pose, so a study would keep nothing."""
    text = MAP.read_text().replace("  legs: {speed: 6.5}", "  legs: {speed: 6.5, kp: 40, torque: 0.4}")
    text = text.replace("mjcf: kid3kg.xml", f"mjcf: {MAP.parent / 'kid3kg.xml'}")
    weak = tmp_path / "weak.yaml"
    weak.write_text(text)
    r = run_in_process(["init", "--robot", weak, "--surface", "rigid", "--out", tmp_path / "init"])
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "init" / "kid3kg-rigid-match.yaml").exists()
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: standing still in the start set's pose the robot "
                                                   "falls (fell at t = "), r.stderr


def test_init_puts_soft_servos_give_back_into_the_engines_targets(tmp_path):
    """The tests' own stand-in for a team robot on soft servos (kid3kg, the legs kp 11 N m/rad with
    0.9 N m s/rad of damping: Bit-Bots' Wolfgang-OP training servos scaled to its weight): init says how
    far the knee gives on one foot, turns the engine's load and lag shares on, sets the step to four
    times the knee's lag, and searches both shares; its start walks 0.15 m/s to the end on rigid,
    where the same start without them falls backward (docs/walk.md)."""
    from tuner.search.initial import GIVE_LIMIT, LAG_STEPS, LOAD_SHARE, knee_lag
    text = MAP.read_text().replace("  legs: {speed: 6.5}", "  legs: {law: pd, kp: 11, kv: 0, torque: 4, speed: 20, "
                                   "damping: 0.9, armature: 0.012, frictionloss: 0.05}")
    soft = tmp_path / "soft.yaml"
    soft.write_text(text.replace("mjcf: kid3kg.xml", f"mjcf: {MAP.parent / 'kid3kg.xml'}"))
    r = run_in_process(["init", "--robot", soft, "--surface", "rigid", "--out", tmp_path / "init"])
    assert r.returncode == 0, r.stderr
    give = [line for line in r.stdout.splitlines() if line.strip().startswith("load_share")]
    assert len(give) == 1 and "(l_knee) on one foot in the start pose" in give[0], r.stdout
    assert float(give[0].split("give way ")[1].split(" deg")[0]) > np.degrees(GIVE_LIMIT)
    start = tmp_path / "init" / "kid3kg-rigid-match-start.yaml"
    doc = yaml_load(start)
    robot = load_robot(str(soft))
    assert doc["engine"]["load_share"] == LOAD_SHARE
    assert doc["params"]["period"] == pytest.approx(LAG_STEPS * knee_lag(robot), abs=1e-3)
    study = load_study(tmp_path / "init" / "kid3kg-rigid-match.yaml")
    assert {"engine.load_share", "engine.lag_share"} <= {r.name for r in study.space}
    space = yaml_load(tmp_path / "init" / "kid3kg-rigid-match.yaml")["space"]
    # no step shorter than three lags, and no draw without a single support (a "walk" that never steps)
    assert space["period"]["low"] >= 3 * knee_lag(robot) - 1e-4
    assert space["t2"]["low"] - space["t1"]["high"] > 0.2 * space["period"]["low"], space
    off = tmp_path / "off.yaml"
    doc["engine"].update(load_share=0.0, lag_share=0.0)
    off.write_text(yaml_dump(doc))
    outcomes = {}
    for name, path in (("on", start), ("off", off)):
        r = run_in_process(["simulate", "--robot", soft, "--params", path, "--surface", "rigid", "--command", "0.15,0,0",
                     "--json"])
        assert r.returncode == 0, r.stderr
        outcomes[name] = json.loads(r.stdout)["metrics"]["outcome"]
    assert outcomes == {"on": "completed", "off": "fell"}


def yaml_load(path):
    import yaml
    return yaml.safe_load(path.read_text())


def yaml_dump(doc):
    import yaml
    return yaml.safe_dump(doc, sort_keys=False)


def test_the_built_in_robot_keeps_the_plain_engine():
    """The built-in robot's knee gives 6.8 deg on one foot on its MX-64 servos, under the limit: its
    start keeps the engine without the servos' give (its shipped sets and studies walk so)."""
    from tuner.search.initial import GIVE_LIMIT, servo_give
    robot = load_robot("kidsize")
    iw = initial_walk(robot, "kidsize", load_surface("carpet4"))
    joint, give = servo_give(robot, iw.params)
    assert joint == "l_knee" and np.radians(5) < give < GIVE_LIMIT
    assert iw.engine.load_share == 0 and iw.engine.lag_share == 0 and "load_share" not in iw.sources
