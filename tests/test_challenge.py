"""The push-recovery challenge's pendulum really hits the robot with the momentum it reports, and a
scenario study runs end to end through the CLI."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import mujoco
import pytest

import gaits
from tuner.params_io import resolve_params
from tuner.robots import load_robot
from tuner.challenge.rules import challenge, drop_height, push_trial, rank
from tuner.sim.rollout import Simulator
from tuner.sim.scene import BOTTLE_MASS
from tuner.sim.surfaces import SURFACES
from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]


def run(cmd, args, env, **kw):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env, **kw)


@pytest.fixture(scope="module")
def trial():
    sim = Simulator(load_robot("kidsize"), SURFACES["rigid"], pendulum=1.5)
    drive = gaits.Drive.of(resolve_params("kidsize-omni-carpet4", None))
    return sim, push_trial(sim, drive, 0.5, 3, keep_trace=True)


def test_the_rules_numbers():
    assert drop_height(1.5, 0.0) == 0.0
    assert drop_height(1.5, 0.5) == pytest.approx(1.5 - math.sqrt(1.5 ** 2 - 0.25))
    assert rank(1.5, 0.5, 5.0, 0.25) == pytest.approx(math.sqrt(drop_height(1.5, 0.5)) / 1.25)


def test_the_pendulum_delivers_the_momentum_it_reports(trial):
    """Measured from the bottle's speed before it meets the robot: sqrt(2 g H) times its mass, within
    4% (the 10 ms sampling of the swing clips its peak)."""
    sim, r = trial
    expected = BOTTLE_MASS * math.sqrt(2 * 9.81 * drop_height(1.5, 0.5))
    assert len(r["pushes"]) == 3
    for push in r["pushes"]:
        assert push["measured_Ns"] == pytest.approx(expected, rel=0.04)


def test_the_bottle_really_touches_the_robot_at_each_push(trial):
    sim, r = trial
    tr = r["trace"]
    m = sim.model
    d = mujoco.MjData(m)
    bottle = m.geom("gt/bottle").id
    robot_root = m.body_rootid[sim._torso]
    mocap = m.body("gt/pivot").mocapid[0]
    for push in r["pushes"]:
        d.mocap_pos[mocap] = push["pivot"]
        touched = False
        for k in range(int((push["t_s"] - 0.2) / 0.01), int((push["t_s"] + 0.2) / 0.01)):
            d.qpos[:] = tr.qpos[k]
            mujoco.mj_forward(m, d)
            for c in d.contact[:d.ncon]:
                other = c.geom2 if c.geom1 == bottle else (c.geom1 if c.geom2 == bottle else None)
                if other is not None and m.body_rootid[m.geom_bodyid[other]] == robot_root:
                    touched = True
        assert touched, push


def test_challenge_through_the_cli(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["challenge", "push", "--rules", "2019", "--params", "kidsize-omni-carpet4", "--surface",
                             "rigid", "--step", "0.25", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["rope_m"] == 1.5 and {"best_distance_m", "momentum_Ns", "rank", "trials"} <= set(out)
    assert all(len(t["pushes"]) == 3 for t in out["trials"] if t["success"])     # a fall ends a trial early
    assert all(1 <= len(t["pushes"]) <= 3 for t in out["trials"])
    assert not out["trials"][-1]["success"] or out["trials"][-1]["distance_m"] >= 1.4
    if out["best_distance_m"] is not None:
        assert out["momentum_Ns"] == pytest.approx(math.sqrt(2 * 9.81 * drop_height(1.5, out["best_distance_m"])))
    bad = run(gait_tuner_cmd, ["challenge", "push", "--params", "kidsize-omni-carpet4", "--rope", "3"], run_env)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1


def tune_and_export(cmd, env, tmp_path, text: str, workers: int):
    """Write the study ``text``, tune it through the CLI, export its best trial: (study, runs, tune's
    stdout, the exported set's path)."""
    study = tmp_path / "tiny.yaml"
    study.write_text(text)
    runs = tmp_path / "runs"
    tuned = run(cmd, ["tune", study, "--workers", str(workers), "--runs", runs], env)
    assert tuned.returncode == 0, tuned.stderr
    out = tmp_path / "best.yaml"
    r = run(cmd, ["export", study, "--runs", runs, "--out", out], env)
    assert r.returncode == 0, r.stderr
    return study, runs, tuned.stdout, out


def test_a_tiny_scenario_study_end_to_end(gait_tuner_cmd, run_env, tmp_path):
    _, _, _, out = tune_and_export(
        gait_tuner_cmd, run_env, tmp_path,
        "gait: tlipfm\nbase: kidsize-omni-carpet4\nsurfaces: [carpet4]\nengine: {}\n"
        "space:\n  engine.k_vel: {low: 0.0, high: 1.0}\n  h_z: {low: 0.02, high: 0.05}\n"
        "scenario: {walks: 2, duration: 4.0, min_survival: 0.5, push_rate: 0.2}\ntrials: 3\nenqueue: [baselines]\n", 2)
    gf = gaits.load_gait_file(out)
    assert gf.engine is not None and 0.0 <= gf.engine.k_vel <= 1.0
    r = run(gait_tuner_cmd, ["simulate", "--params", out, "--surface", "carpet4", "--commands",
                             ROOT / "examples" / "streams" / "match-carpet4.csv", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    assert "online walk engine" in json.loads(r.stdout)["drive"]


def test_a_tiny_challenge_study_end_to_end(gait_tuner_cmd, run_env, tmp_path):
    """A study scored on the push-recovery challenge: its objective is the mean largest D over the
    push seeds, as ``challenge`` itself finds them for the trial's set."""
    study, runs, said, out = tune_and_export(
        gait_tuner_cmd, run_env, tmp_path,
        "gait: tlipfm\nbase: kidsize-engine-carpet4\nsurfaces: [carpet4]\nengine: {k_vel: 0.6}\n"
        "space:\n  engine.k_vel: {low: 0.5, high: 0.9}\ntrials: 2\nenqueue: [baselines]\n"
        "challenge: {rules: 2019, seeds: [0, 1], start: 0.6, step: 0.3}\n", 1)
    assert "push distance" in said
    r = run(gait_tuner_cmd, ["trials", study, "--runs", runs, "--json"], run_env)
    assert r.returncode == 0, r.stderr
    rows = json.loads(r.stdout)["shown"]
    assert len(rows) == 2 and all(row["feasible"] for row in rows)
    gf = gaits.load_gait_file(out)
    assert gf.engine is not None and 0.5 <= gf.engine.k_vel <= 0.9
    sim = Simulator(load_robot("kidsize"), SURFACES["carpet4"], pendulum=1.5)
    found = [challenge(sim, gaits.Drive.of(gf), seed=k, start=0.6, step=0.3)["best_distance_m"] for k in (0, 1)]
    expected = sum(0.3 if d is None else d for d in found) / 2
    assert max(row["score"] for row in rows) == pytest.approx(expected)


def test_a_challenge_trial_that_takes_no_push_scores_below_every_one_that_does():
    from tuner.scenarios.challenge import ChallengeSpec
    from tuner.search.objective import Evaluator
    from tuner.search.study import load_study
    spec = dataclasses.replace(load_study("kidsize-omni-carpet4"), surfaces=("rigid",), kind="challenge",
                               settings=ChallengeSpec(seeds=(0,), start=1.4, step=0.05, rules="2019"))
    res = Evaluator(spec).evaluate(gaits.Drive.of(resolve_params("kidsize-omni-carpet4", None)))
    assert res.values == (pytest.approx(1.35),) and res.fall_constraint < 0
    assert res.per_surface["rigid"]["best_distance_m"] == [None]


@pytest.mark.parametrize("aggregate, expected", [("worst", 0.5), ("mean", (0.5 + 0.875) / 2)])
def test_a_challenge_study_aggregates_the_surfaces_mean_distances(monkeypatch, aggregate, expected):
    import tuner.scenarios.challenge as ch
    from tuner.scenarios.challenge import ChallengeSpec
    from tuner.search.objective import Evaluator
    from tuner.search.study import load_study
    found = {("rigid", 0): 0.4, ("rigid", 1): 0.6, ("carpet4", 0): None, ("carpet4", 1): 1.2}

    def fake(sim, drive, *, seed, start, step):
        d = found[(sim.surface.name, seed)]
        return {"best_distance_m": d, "momentum_Ns": None if d is None else 1.0}
    monkeypatch.setattr(ch, "challenge", fake)
    spec = dataclasses.replace(load_study("kidsize-omni-carpet4"), surfaces=("rigid", "carpet4"), kind="challenge",
                               aggregate=aggregate, settings=ChallengeSpec(seeds=(0, 1), start=0.6, step=0.05,
                                                                                rules="2019"))
    res = Evaluator(spec).evaluate(gaits.Drive.of(resolve_params("kidsize-omni-carpet4", None)))
    # per surface the mean over seeds: rigid (0.4 + 0.6) / 2 = 0.5; carpet4 (0.55, start - step for no
    # push, + 1.2) / 2 = 0.875; then the worst of them, or their mean
    assert res.per_surface["carpet4"]["best_distance_m"] == [None, 1.2]
    assert res.values == (pytest.approx(expected),)


@pytest.mark.parametrize("section, message", [
    ("challenge: {seeds: [0, 0]}", "seeds"),
    ("challenge: {seeds: []}", "seeds"),
    ("challenge: {rope: 3}", "rope = 3"),
    ("challenge: {start: 1.5}", "start = 1.5"),
    ("challenge: {start: 1.2}", "below 0.75 of the rope"),
    ("challenge: {step: 0}", "step = 0"),
    ("challenge: {rules: 2020}", "rules = 2020: expected 2025"),
    ("challenge: {bottle: 1}", "bottle = 1: expected 3, 5 or 10"),
    ("challenge: {rules: 2019, bottle: 3}", "bottle and third are the 2025 rules'"),
    ("challenge: {third: either}", "third = 'either'"),
    ("challenge: {rope: 1.2}", "the 2025 rules' rope is 1.5 to 2 m"),
    ("challenge: {pushes: 3}", "unknown key 'pushes'"),
    ("challenge: [0, 1]", "challenge must be a mapping"),
    ("challenge: {}\nobjectives: [pitch_rms]", "remove 'objectives'"),
    ("challenge: {}\nscenario: {walks: 2}", "does not go with scenario"),
    ("challenge: {}\nrobust: {rollouts: 2}", "does not go with robust"),
    ("challenge: {}\nduration: 5", "remove 'duration'"),
])
def test_a_challenge_section_is_checked(tmp_path, section, message):
    from tuner.errors import UserError
    from tuner.search.study import load_study
    study = tmp_path / "bad.yaml"
    study.write_text("gait: tlipfm\nbase: kidsize-engine-carpet4\nsurfaces: [carpet4]\nengine: {}\n"
                     "space:\n  engine.k_vel: {low: 0.5, high: 0.9}\n" + section + "\n")
    with pytest.raises(UserError, match=re.escape(message)):
        load_study(str(study))


def test_the_engine_says_which_limits_its_re_plans_sat_on():
    """A pushed engine walk re-plans, and the trace counts, per limit, the re-plans whose step sat on
    it (the figures ``bench_engine.py --parts limits`` reports)."""
    sim = Simulator(load_robot("kidsize"), SURFACES["rigid"], pendulum=1.5)
    drive = gaits.Drive.of(resolve_params("kidsize-engine-carpet4", None))
    tr = push_trial(sim, drive, 0.9, 0, keep_trace=True)["trace"]
    b = tr.meta["binding"]
    assert b["replans"] == tr.meta["replans"] > 0
    assert set(b) == {"replans", "reach", "sole", "timing", "speed"}
    assert all(0 <= b[k] <= b["replans"] for k in b)


def test_an_engine_walks_a_stream_beyond_its_envelope_clipped_and_says_so(gait_tuner_cmd, run_env):
    """robustness --commands used to plan the engine set's stream as a table first and refuse it
    (the footstep planner's step limits), although the engine clips a command to its envelope."""
    r = run(gait_tuner_cmd, ["robustness", "--params", "kidsize-engine-grass50", "--surface", "grass50", "--commands",
                             ROOT / "examples" / "streams" / "match-grass50.csv", "--rollouts", 1, "--workers", 1,
                             "--pushes", "", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    notes = [ln for ln in r.stderr.splitlines() if "clipped to its envelope" in ln]
    assert len(notes) == 1 and "left 0.06 m/s (envelope 0.0543)" in notes[0], r.stderr
    out = json.loads(r.stdout)
    assert out["rollouts"] == 1
    tk = out["tracking_steady"]                     # the stream's steady-step tracking, per kind of segment
    assert tk is None or set(tk) == {"median", "iqr", "forward", "backward", "sideways", "turning"}
    assert (tk is not None) == (out["survival"] > 0)


def test_an_explicit_push_comes_from_the_direction_asked():
    """``push_trial(pushes=...)`` (ours, for analysis): one push, 90 deg against the heading, moves the
    robot to its left; its record says the direction and the momentum sqrt(2 g H) the drop gives."""
    sim = Simulator(load_robot("kidsize"), SURFACES["rigid"], pendulum=1.5)
    drive = gaits.Drive.of(resolve_params("kidsize-omni-carpet4", None))
    r = push_trial(sim, drive, 0.4, 0, keep_trace=True, pushes=[(3.0, 90.0)])
    tr = r["trace"]
    assert [p["direction_deg"] for p in r["pushes"]] == [pytest.approx(90.0)]
    assert r["pushes"][0]["measured_Ns"] == pytest.approx(BOTTLE_MASS * math.sqrt(2 * 9.81 * drop_height(1.5, 0.4)),
                                                          rel=0.04)
    assert tr.t[-1] == pytest.approx(6.0, abs=0.02)           # 3 s after the last push
    k0, k1 = (int(round(t / sim.control_period)) for t in (2.95, 3.15))
    moved = tr.p_torso[k1, :2] - tr.p_torso[k0, :2]
    left = [-math.sin(tr.yaw[k0]), math.cos(tr.yaw[k0])]
    heading = [math.cos(tr.yaw[k0]), math.sin(tr.yaw[k0])]
    assert moved @ left > 0.01 and abs(moved @ heading) < moved @ left
    with pytest.raises(ValueError, match="4 s or more"):
        push_trial(sim, drive, 0.4, 0, pushes=[(3.0, 0.0), (5.0, 90.0)])


def test_push_by_direction_raises_d_until_a_push_time_fails(monkeypatch):
    """Per direction, D grows by the step until one of the push times fails; the best is the last D
    every push time survived (a stand-in trial that fails beyond a known D per direction)."""
    import tuner.challenge.rules as ch
    limit = {0.0: 0.75, 90.0: 0.45, 180.0: 0.35}
    calls = []

    class Fell:
        fell, t_fall = True, 4.2

    def fake(sim, drive, distance, seed, keep_trace=False, pushes=None):
        (t, d), = pushes
        calls.append((d, distance, t))
        ok = distance <= limit[d] + (0.1 if t == 3.0 else 0.0)     # the later push time binds
        return {"success": ok, "reason": "completed" if ok else "fell at 4.2 s", "trace": Fell()}
    monkeypatch.setattr(ch, "push_trial", fake)
    sim = type("S", (), {"rope": 1.5})()
    rows = ch.push_by_direction(sim, None, directions=(0.0, 90.0, 180.0), push_times=(3.0, 3.1), start=0.4, step=0.1)
    assert [r["best_distance_m"] for r in rows] == [0.7, 0.4, None]
    assert [r["first_failure"]["distance_m"] for r in rows] == [0.8, 0.5, 0.4]
    assert [r["first_failure"]["push_s"] for r in rows] == [3.1, 3.1, 3.1]
    assert rows[0]["momentum_Ns"] == pytest.approx(BOTTLE_MASS * math.sqrt(2 * 9.81 * drop_height(1.5, 0.7)))
    assert rows[2]["momentum_Ns"] is None
    assert (0.0, 0.8, 3.0) in calls and (0.0, 0.9, 3.0) not in calls    # stops at the first failure


def test_challenge_by_direction_through_the_cli(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["challenge", "push", "--rules", "2019", "--params", "kidsize-omni-carpet4", "--surface",
                             "rigid", "--by-direction", "--directions", "90", "--step", "0.5", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    (row,) = out["by_direction"]
    assert row["direction_deg"] == 90.0 and out["rope_m"] == 1.5
    assert row["best_distance_m"] in (None, 0.4, 0.9, 1.4)
    if row["first_failure"] is not None:
        assert row["first_failure"]["distance_m"] == pytest.approx((row["best_distance_m"] or -0.1) + 0.5)
    bad = run(gait_tuner_cmd, ["challenge", "push", "--rules", "2019", "--params", "kidsize-omni-carpet4",
                               "--by-direction", "--directions", "left"], run_env)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "--directions" in bad.stderr
    for twice in ("0,0", "90,-270", "0,360"):
        again = run(gait_tuner_cmd, ["challenge", "push", "--rules", "2019", "--params", "kidsize-omni-carpet4",
                                     "--by-direction", "--directions", twice], run_env)
        assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1 and "given already" in again.stderr
    alone = run(gait_tuner_cmd, ["challenge", "push", "--params", "kidsize-omni-carpet4", "--directions", "90"], run_env)
    assert alone.returncode == 2 and len(alone.stderr.strip().splitlines()) == 1 and "--by-direction" in alone.stderr



# --- the 2025 rules ---------------------------------------------------------------------------

def test_the_2025_trial_pushes_from_the_front_from_behind_then_the_third_side():
    from tuner.challenge.rules import PUSH_TIMES_2025, pushes_2025
    for third, last in (("front", 180.0), ("back", 0.0)):
        p = pushes_2025(7, 0.4, third)
        assert all(abs(d - want) <= 10.0 for (_, d), want in zip(p, (180.0, 0.0, last)))
        assert all(base <= t < base + 0.6 for (t, _), base in zip(p, PUSH_TIMES_2025))
        assert all(b - a >= 4.0 for (a, _), (b, _) in zip(p, p[1:]))
    assert pushes_2025(7, 0.4, "front") == pushes_2025(7, 0.4, "front") != pushes_2025(8, 0.4, "front")
    with pytest.raises(ValueError):
        pushes_2025(0, 0.4, "either")


@pytest.mark.parametrize("t_fall, absorbed, full, partial", [
    (None, [True, True, True], True, True),       # up to the end
    (12.5, [True, True, False], False, True),     # fell after the third: two of three, partial
    (7.9, [True, False, False], False, False),    # fell between the second and the third
    (4.0, [False, False, False], False, False),   # fell after the first
])
def test_absorbed_pushes_and_partial_success(t_fall, absorbed, full, partial):
    from tuner.challenge import rules as C
    trial = {"pushes": [{"t_s": 3.2}, {"t_s": 7.8}, {"t_s": 12.3}], "t_fall_s": t_fall}
    got = C.absorbed(trial)
    assert got == absorbed and (sum(got) == 3) == full and (sum(got) >= 2) == partial


@pytest.mark.parametrize("outcome, fell, survived, absorbed", [
    ("completed", False, True, 3),
    ("fell", True, False, 1),
    ("diverged", False, False, 1),      # not a fall, yet not standing: no push after it absorbed
    ("impossible", False, False, 1),
])
def test_a_2025_trial_counts_a_push_absorbed_only_while_the_walk_still_stood(monkeypatch, outcome, fell,
                                                                              survived, absorbed):
    """A walk that diverged or became impossible between the second and third push has absorbed the
    first push only, not the second and third (before, only a fall ended a trial: a diverged walk took all three)."""
    import numpy as np
    from types import SimpleNamespace
    from tuner.challenge import rules as C
    end = 14.0 if survived else 9.0          # between the second push (7.6-8.2 s) and the third
    trace = SimpleNamespace(survived=survived, fell=fell, t_fall=end if fell else None, outcome=outcome,
                            t=np.linspace(0.0, end, 11))

    def fake_push_trial(sim, drive, distance, seed, keep_trace=False, pushes=None, record=None):
        return {"pushes": [{"t_s": t} for t, _ in pushes], "success": survived, "trace": trace}
    monkeypatch.setattr(C, "push_trial", fake_push_trial)
    trial = C.trial_2025(None, None, 0.5, 0, "front")
    assert trial["absorbed"] == absorbed and trial["success"] == (absorbed == 3)
    assert trial["outcome"] == outcome and (trial["t_fall_s"] is None) == survived


def test_m_by_the_2025_formula():
    from tuner.challenge.rules import rank_2025
    # L 1.5 m, D 0.5 m: H = 1.5 - sqrt(2.0) = 0.0857864 m; h_c 0.25, h_i 0.25, m_B 3, m_R 5
    H = 1.5 - math.sqrt(2.0)
    assert rank_2025(1.5, 0.5, 3.0, 5.0, 0.25, 0.25) == pytest.approx(math.sqrt(H) / 0.25 * 0.6)
    assert rank_2025(1.5, 0.5, 3.0, 5.0, 0.25, 0.2) == pytest.approx(math.sqrt(H) / 0.25 * 0.6 * 0.8)


@pytest.mark.parametrize("kg", [3, 5, 10])
def test_each_bottle_delivers_m_sqrt_2gh_at_the_robots_com_height(kg):
    """The 2025 bottles, hung by their centre of mass: the momentum measured from the swing is m
    sqrt(2 g H) within 4%, and the bottle's centre meets the robot at its CoM height."""
    from tuner.sim.scene import BOTTLES
    sim = Simulator(load_robot("kidsize"), SURFACES["carpet4"], pendulum=1.5, bottle=BOTTLES[kg])
    drive = gaits.Drive.of(resolve_params("kidsize-engine-carpet4", None))
    r = push_trial(sim, drive, 0.3, 0, keep_trace=True, pushes=[(3.0, 0.0)])
    (push,) = r["pushes"]
    assert push["measured_Ns"] == pytest.approx(kg * math.sqrt(2 * 9.81 * drop_height(1.5, 0.3)), rel=0.04)
    assert push["pivot"][2] - 1.5 == pytest.approx(r["com_height_m"], abs=1e-9)
    assert sim.model.body("gt/bottle").mass[0] == pytest.approx(kg) or \
        sim.model.body_subtreemass[sim.model.body("gt/bottle").id] == pytest.approx(kg)


def test_the_2025_challenge_through_the_cli(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["challenge", "push", "--params", "kidsize-engine-carpet4", "--surface", "carpet4",
                             "--step", "0.3", "--third", "back", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["rules"] == "2025" and out["bottle_kg"] == 3.0 and out["max_distance_m"] == pytest.approx(1.125)
    assert all(t["third"] == "back" and len(t["pushes"]) <= 3 for t in out["trials"])
    full = out["full"]
    if full["distance_m"] is not None:
        assert full["momentum_Ns"] == pytest.approx(3 * math.sqrt(2 * 9.81 * drop_height(1.5, full["distance_m"])))
        assert full["M"] == pytest.approx(math.sqrt(full["drop_m"]) / out["com_height_m"] * 3 / out["robot_mass_kg"])
    for args, words in ((["--rules", "2019", "--bottle", "5"], "--bottle is for the 2025 rules"),
                        (["--rope", "1.2"], "the 2025 rules' rope is 1.5 to 2 m"),
                        (["--by-direction"], "add --rules 2019")):
        bad = run(gait_tuner_cmd, ["challenge", "push", "--params", "kidsize-engine-carpet4", *args], run_env)
        assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and words in bad.stderr, bad.stderr


def test_the_2025_challenge_refuses_the_2019_bottle():
    from tuner.challenge.rules import challenge_2025
    sim = Simulator(load_robot("kidsize"), SURFACES["carpet4"], pendulum=1.5)      # the default: the 2019 bottle
    with pytest.raises(ValueError, match="the 2019 trial's"):
        challenge_2025(sim, gaits.Drive.of(resolve_params("kidsize-engine-carpet4", None)))


def test_the_shipped_trained_push_set_keeps_the_trunk_where_the_engine_alone_falls():
    """kidsize-engine-push-residual (docs/walk.md): kidsize-engine-push with a residual trained on
    push trials on carpet4 and grass30. One push of D 0.5 m from behind while stepping in place (3.9 N s): the engine alone
    pitches past 20 deg within 0.3 s and falls; with the residual the torso stays within 5 deg and
    the robot stands to the end. Its description says how it was made."""
    import numpy as np
    from tuner.params_io import resolve_drive
    from tuner.sim.scene import BOTTLES
    from tuner.sim.surfaces import load_surface
    shipped = resolve_params("kidsize-engine-push-residual", None)
    assert shipped.residual is not None and "gait-tuner train kidsize-engine-push" in shipped.description
    assert shipped.params == resolve_params("kidsize-engine-push", None).params
    sim = Simulator(load_robot("kidsize"), load_surface("carpet4"), pendulum=1.5, bottle=BOTTLES[3])
    peaks = {}
    for name in ("kidsize-engine-push", "kidsize-engine-push-residual"):
        drive = dataclasses.replace(resolve_drive(name, None), command=None, stream=None)
        t = push_trial(sim, drive, 0.5, 0, keep_trace=True, pushes=[(3.0, 0)])
        tr = t["trace"]
        time, pitch = np.asarray(tr.t), np.degrees(np.asarray(tr.pitch))
        hit = t["pushes"][0]["t_s"]
        before = pitch[(time < hit) & (time > hit - 0.5)].mean()
        peaks[name] = (float(np.max(np.abs(pitch[(time >= hit) & (time <= hit + 0.3)] - before))), tr.fell)
    assert peaks["kidsize-engine-push"][0] > 20 and peaks["kidsize-engine-push"][1]
    assert peaks["kidsize-engine-push-residual"][0] < 5 and not peaks["kidsize-engine-push-residual"][1]


@pytest.mark.slow
def test_the_shipped_trained_push_set_is_what_its_two_train_commands_write(tmp_path):
    """The description's two commands, run again, write the shipped residual to the last digit
    (train is deterministic from its seed; ten minutes on 2 cores)."""
    from conftest import run_in_process
    first, second = tmp_path / "r3.yaml", tmp_path / "r4.yaml"
    common = ["--robot", "kidsize", "--surface", "carpet4,grass30", "--objective", "push", "--iterations", "30",
              "--walks", "4", "--workers", "2"]
    assert run_in_process(["train", "kidsize-engine-push", *common, "--distance", "0.5", "--out", first]).returncode == 0
    assert run_in_process(["train", first, *common, "--distance", "0.55", "--seed", "1", "--out", second]).returncode == 0
    assert gaits.load_gait_file(second).residual == resolve_params("kidsize-engine-push-residual", None).residual


def test_the_shipped_trained_forward_set_survives_a_held_fast_walk_the_set_alone_does_not(gait_tuner_cmd, run_env):
    """kidsize-engine-forward-residual (docs/walk.md): kidsize-engine-carpet4 with a residual trained on
    a held 0.3 m/s. Four randomised walks (evaluation seed 11) holding 0.35 m/s on carpet4: the set
    alone survives one, with the residual all four."""
    got = {}
    for name in ("kidsize-engine-carpet4", "kidsize-engine-forward-residual"):
        r = run_cli(gait_tuner_cmd, ["robustness", "--params", name, "--robot", "kidsize", "--surface", "carpet4",
                                     "--command", "0.35,0,0", "--rollouts", "4", "--pushes", "", "--seed", "11",
                                     "--workers", "1", "--json"], run_env)
        assert r.returncode == 0, r.stderr
        got[name] = json.loads(r.stdout)["survival"]
    assert got == {"kidsize-engine-carpet4": 0.25, "kidsize-engine-forward-residual": 1.0}
    shipped = resolve_params("kidsize-engine-forward-residual", None)
    assert shipped.params == resolve_params("kidsize-engine-carpet4", None).params
    assert "--objective command --command 0.3,0,0" in shipped.description


@pytest.mark.slow
def test_the_shipped_trained_forward_set_is_what_its_train_command_writes(tmp_path):
    """The description's command, run again, writes the shipped residual to the last digit."""
    from conftest import run_in_process
    out = tmp_path / "r.yaml"
    args = ["train", "kidsize-engine-carpet4", "--robot", "kidsize", "--surface", "carpet4", "--objective", "command",
            "--command", "0.3,0,0", "--iterations", "30", "--walks", "6", "--step", "0.005", "--noise", "0.02",
            "--workers", "2", "--out", out]
    assert run_in_process(args).returncode == 0
    assert gaits.load_gait_file(out).residual == resolve_params("kidsize-engine-forward-residual", None).residual
