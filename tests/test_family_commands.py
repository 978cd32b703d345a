"""Walk commands for EROS (lateral and turning via points) and the cosine law (forward and
backward per-step steps): exact geometry of the plans they walk (issue 9, item 1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import gaits
from gaits import CommandRamp, PlanError, StepLimits, WalkCommand, cosine_law, eros
from gaits.footstep_planner import plan_footsteps, sole_gap

from conftest import run_cli

WIDE = gaits.load_baseline("eros-x8-with").params          # 95 mm stance: room to turn
LIMITS = StepLimits(sole_length=0.10, sole_width=0.055)


def _eros_plan(p, commands):
    return plan_footsteps(commands, eros.step_period(p), p.stance_width / 2,
                          -1 if p.first_swing == "left" else 1, LIMITS)


def test_eros_constant_forward_command_is_the_papers_straight_walk():
    for name in ("eros-x16-with", "eros-x8-without"):
        p = gaits.load_baseline(name).params
        cmd = np.zeros((p.n_steps, 3))
        cmd[:-1, 0] = p.step_x / eros.step_period(p)          # the last step sets the foot beside
        straight, commanded = eros.generate(p), eros.generate(p, commands=cmd)
        assert np.allclose(commanded.q_ref, straight.q_ref, atol=1e-12)
        assert np.allclose(commanded.p_world_pelvis, straight.p_world_pelvis, atol=1e-12)


def test_eros_step_starts_are_the_step_via_points():
    for p in (WIDE, WIDE.replace(double_support=0.0), WIDE.replace(landing_deceleration=False)):
        chain = eros.via_points(p)
        ref = eros.eros_references(p)
        firsts = [i for i, tr in enumerate(chain)
                  if tr.kind == ("dsp" if eros.dsp_ticks(p) else "lift")][::(2 if eros.dsp_ticks(p) else 1)]
        starts = eros.step_starts(p, p.n_steps)
        assert np.allclose(starts[:-1], ref.via_ticks[firsts] * p.tick)
        assert starts[1] - starts[0] == pytest.approx(eros.step_period(p))


@pytest.mark.parametrize("command", [(0.0, 0.0, 0.2), (0.0, 0.02, 0.0), (0.0, -0.02, 0.0),
                                     (0.04, 0.0, 0.15), (-0.04, 0.0, -0.15)])
def test_eros_feet_land_where_planned_and_never_meet(command):
    p = WIDE.replace(n_steps=21)
    cmd = CommandRamp(WalkCommand(*command)).per_step()
    plan = _eros_plan(p, cmd)
    ref = eros.eros_references(p, plan)
    chain = eros.via_points(p, plan)
    lands = [i for i, tr in enumerate(chain) if tr.kind == "land"]
    assert len(lands) == plan.n_steps
    for k, i in enumerate(lands):
        s = ref.state[ref.via_ticks[i + 1]]
        pose = s[[eros.XL, eros.YL, eros.AL]] if chain[i].swing == 1 else s[[eros.XR, eros.YR, eros.AR]]
        assert np.allclose(pose, plan.swing_target[k], atol=1e-12)
        assert s[eros.ZL] == 0.0 and s[eros.ZR] == 0.0
    # the whole walk, tick by tick: the soles keep the planner's minimum gap
    gaps = [sole_gap(r[[eros.XL, eros.YL, eros.AL]], r[[eros.XR, eros.YR, eros.AR]],
                     LIMITS.sole_length, LIMITS.sole_width) for r in ref.state[::3]]
    assert min(gaps) >= LIMITS.min_gap - 1e-9


def test_eros_turning_yaw_accumulates_and_the_hip_yaw_turns_the_feet():
    p = WIDE
    ramp = CommandRamp(WalkCommand(0.0, 0.0, 0.2))
    traj = gaits.generate(p, commands=ramp.per_step(), limits=LIMITS)
    expected = 0.2 * eros.step_period(p) * ramp.fractions().sum()
    assert traj.yaw_world_pelvis[-1] == pytest.approx(expected, rel=1e-9)
    assert traj.yaw_world_feet[-1] == pytest.approx([expected, expected], rel=1e-9)
    hip_yaw = traj.joint("l_hip_yaw") - traj.joint("r_hip_yaw")
    assert np.max(np.abs(hip_yaw)) > 0.2         # the feet turn against each other mid-walk
    assert np.allclose(traj.q_ref[-1], traj.q_ref[0], atol=1e-9)   # standing as it started


def test_eros_sway_is_across_the_heading():
    """Turned 90 deg, the hip's sway moves it along the world x axis, not y."""
    p = WIDE
    plan = _eros_plan(p, np.tile([0.0, 0.0, 0.3], (6, 1)))
    ref = eros.eros_references(p, plan)
    traj = gaits.generate(p, commands=plan.commands, limits=LIMITS)
    s = ref.state
    body = np.column_stack([s[:, eros.BX], s[:, eros.BW]])
    offset = traj.p_world_pelvis[:, :2] - body
    heading = np.column_stack([np.cos(s[:, eros.BA]), np.sin(s[:, eros.BA])])
    assert np.max(np.abs(np.sum(offset * heading, axis=1))) < 1e-12       # no along-heading part
    assert np.allclose(np.hypot(*offset.T), np.abs(s[:, eros.BY]), atol=1e-12)


def test_eros_side_step_follows_eq_37s_profile():
    p = WIDE.replace(double_support=0.0, landing_deceleration=False)
    plan = _eros_plan(p, np.tile([0.0, 0.03, 0.0], (4, 1)))
    chain = eros.via_points(p, plan)
    ref = eros.eros_references(p, plan)
    i = next(i for i, tr in enumerate(chain) if tr.kind == "lift" and tr.swing == 1)
    a, b = ref.via_ticks[i], ref.via_ticks[i + 1]
    y = ref.state[a + 1:b + 1, eros.YL]
    theta = chain[i].theta
    y0, y1 = chain[i].start[eros.YL], chain[i].end[eros.YL]
    assert y1 - y0 == pytest.approx(0.5 * 2 * 0.03 * eros.step_period(p))   # halfway at the apex
    assert np.allclose(y, y0 + (1 - np.cos(theta)) * (y1 - y0), atol=1e-12)


def test_eros_rejects_a_step_the_feet_cannot_take_naming_it():
    with pytest.raises(PlanError, match=r"step \d+ \(left foot.*max_turn"):
        gaits.generate(WIDE, commands=np.tile([0.0, 0.0, 1.0], (4, 1)), limits=LIMITS)
    narrow = gaits.load_baseline("eros-x24-with").params           # 65 mm stance
    with pytest.raises(PlanError, match="closer than min_gap"):
        gaits.generate(narrow, commands=np.tile([0.0, 0.0, 0.25], (6, 1)), limits=LIMITS)


def test_cosine_constant_command_is_the_papers_walk():
    p = gaits.load_baseline("cosine-setiono").params
    n = p.n_full + 2
    straight = cosine_law.generate(p)
    commanded = cosine_law.generate(p, commands=np.tile([p.step / p.motion_time, 0.0, 0.0], (n, 1)))
    assert np.array_equal(straight.q_ref, commanded.q_ref)


def test_cosine_per_step_commands_forward_and_backward():
    p = gaits.load_baseline("cosine-setiono").params.replace(motion_time=1.0)
    cmd = np.array([[0.02, 0, 0], [0.04, 0, 0], [-0.03, 0, 0], [0.0, 0, 0]])
    traj = cosine_law.generate(p, commands=cmd, dt=0.01)
    starts = cosine_law.step_starts(p, len(cmd))
    i = np.searchsorted(traj.t, starts - 1e-9)
    hip = traj.p_world_pelvis[:, 0]
    assert np.allclose(hip[i], np.concatenate([[0.0], np.cumsum(cmd[:, 0] * p.motion_time)]), atol=1e-9)
    # mid-motion of the backward step, the tilted (supporting) foot is ahead of the hip
    k = i[2] + int(0.5 / 0.01)
    front = max(traj.p_world_foot_l[k, 0], traj.p_world_foot_r[k, 0])
    assert front - hip[k] == pytest.approx(0.03, abs=1e-9)
    assert traj.meta["schedule"] == ["starting", "full", "full", "ending"]


def test_cosine_rejects_side_steps_turns_and_long_steps_naming_the_step():
    p = gaits.load_baseline("cosine-setiono").params
    with pytest.raises(PlanError, match=r"step 1 \(command 0,0.01,0\): .*forward and backward only"):
        cosine_law.generate(p, commands=np.array([[0.0, 0, 0], [0.0, 0.01, 0], [0.0, 0, 0]]))
    with pytest.raises(PlanError, match=r"step 2 .*max_forward"):
        cosine_law.generate(p, commands=np.array([[0.01, 0, 0]] * 2 + [[0.05, 0, 0], [0, 0, 0]]),
                            limits=StepLimits(max_forward=0.1))
    with pytest.raises(PlanError, match="n_steps >= 2"):
        cosine_law.generate(p, commands=np.zeros((1, 3)))


def test_every_family_says_what_it_walks():
    assert {f.name for f in gaits.all_families()} == set(gaits.families())
    assert gaits.family("cosine").command_axes == (True, False, False)
    assert [d for d in gaits.DIRECTIONS if gaits.walks_direction("cosine", d)] == ["forward", "backward"]
    assert all(gaits.walks_direction("eros", d) for d in gaits.DIRECTIONS)
    for fam in gaits.families():
        p = gaits.family_class(fam)()
        assert gaits.step_starts(p, 3)[1] - gaits.step_starts(p, 3)[0] == pytest.approx(gaits.step_period(p))
    assert math.isclose(gaits.step_period(gaits.TlipfmParams()), gaits.TlipfmParams().period)


def test_params_says_which_commands_a_family_walks(gait_tuner_cmd, run_env):
    for fam, text in (("cosine", "forward and backward (vx) only"), ("eros", "quarter-circle via points"),
                      ("tlipfm", "any (vx, vy, wz)")):
        r = run_cli(gait_tuner_cmd, ['params', fam], run_env, timeout=60)
        walk, online = r.stdout.splitlines()[-2:]
        assert r.returncode == 0 and walk.startswith("walk command (--command): ") and text in walk
        assert online.startswith("online (an engine: section): ")
        assert ("gaits/engine/" in online) == (fam == "tlipfm")


def test_tiny_eros_speed_study_end_to_end(gait_tuner_cmd, run_env, tmp_path):
    """A speed study of the EROS family through the real CLI; a cosine-law study may not ask for
    a direction the family does not walk."""
    study = tmp_path / "eros-speed.yaml"
    study.write_text("name: eros-tiny-speed\nrobot: kidsize\nsurfaces: [carpet4]\ngait: eros\nbase: eros-x8-with\n"
                     "space:\n  t_mn: {low: 0.05, high: 0.09}\n  double_support: {low: 0.3, high: 0.5}\n"
                     "speed:\n  directions: {forward: {top: 0.1}, left: {top: 0.03, weight: 2}}\n  levels: 4\n"
                     "trials: 4\n")
    r = run_cli(gait_tuner_cmd, ['tune', str(study), '--runs', str(tmp_path / 'runs'), '--workers', '1'], run_env,
                timeout=600)
    assert r.returncode == 0, r.stderr
    assert "highest stairs held: forward" in r.stdout and "left" in r.stdout
    bad = tmp_path / "cosine-speed.yaml"
    bad.write_text("name: c\ngait: cosine\nsurfaces: [carpet4]\nspace: {motion_time: {low: 1, high: 2}}\n"
                   "speed:\n  directions: {left: {top: 0.01}}\n")
    r = run_cli(gait_tuner_cmd, ['tune', str(bad), '--runs', str(tmp_path / 'runs')], run_env, timeout=120)
    assert r.returncode == 2 and "gait 'cosine' does not walk left" in r.stderr


def test_an_unreachable_eros_step_is_rejected_naming_it():
    """Step limits wider than the leg: the IK fails, and the error names the step it fails in."""
    from tuner.robots import load_robot
    robot = load_robot("kidsize")
    cmd = np.array([[0.05, 0, 0], [0.05, 0, 0], [0.5, 0, 0], [0.5, 0, 0], [0, 0, 0]])
    with pytest.raises(PlanError, match=r"^step 2 of the command walk is out of the leg's reach"):
        gaits.family("eros").walk(WIDE, robot, 0.01, cmd,
                                  limits=StepLimits(max_forward=0.5, sole_length=0.10, sole_width=0.055))


def test_the_gap_rule_follows_a_narrow_stance():
    """The soles keep 10 mm, or the set's own standing gap if narrower: EROS's 65 mm stance
    (5 mm between the robot's 60 mm soles) walks a forward command, and no turn."""
    from tuner.robots import load_robot
    from gaits import command_walk
    robot = load_robot("kidsize")
    narrow = gaits.load_baseline("eros-x24-with").params
    eros_family = gaits.family("eros")
    assert eros_family.step_limits(narrow, robot).min_gap == pytest.approx(narrow.stance_width - robot.foot_size[1])
    assert eros_family.step_limits(WIDE, robot).min_gap == StepLimits().min_gap
    traj = command_walk(narrow, robot, WalkCommand(0.02, 0.0, 0.0), 0.01)
    assert traj.p_world_pelvis[-1, 0] > 0.2
    with pytest.raises(PlanError, match=r"step 0 .*4\.\d\d mm apart during the swing, closer than min_gap = 5\.00 mm"):
        command_walk(narrow, robot, WalkCommand(0.0, 0.0, 0.05), 0.01)
