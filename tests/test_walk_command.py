"""Walk commands, footstep plans and the TLIPFM walk along them (pure math, no simulator)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from gaits.footstep_planner import (PlanError, StepLimits, compose, plan_footsteps, relative,
                                    sole_gap)
from gaits.params import ParamError
from gaits.tlipfm import TlipfmParams, com_trajectory, generate, natural_zmp, pendulum_constants
from gaits.walk_command import CommandRamp, SpeedStaircase, WalkCommand, parse_command


def _steady(c, n=12):
    cmd = np.tile(np.asarray(c, dtype=float), (n, 1))
    cmd[-1] = 0.0
    return cmd


# --- commands -------------------------------------------------------------------------------

def test_parse_command_and_errors():
    assert parse_command("0.2, 0, -0.5") == WalkCommand(0.2, 0.0, -0.5)
    with pytest.raises(ParamError, match="three numbers"):
        parse_command("0.2,0")
    with pytest.raises(ParamError, match="vy = 'x' is not a number"):
        parse_command("0.2,x,0")
    with pytest.raises(ParamError, match=r"vx = 5 m/s is out of range \[-2, 2\] m/s"):
        parse_command("5,0,0")
    with pytest.raises(ParamError, match="finite"):
        parse_command("nan,0,0")


def test_ramp_semantics():
    r = CommandRamp(WalkCommand(0.2, 0.0, 0.0), ramp_steps=3, hold_steps=6, settle_steps=2)
    f = r.fractions()
    np.testing.assert_allclose(f, [0.25, 0.5, 0.75, 1, 1, 1, 1, 1, 1, 0.75, 0.5, 0.25, 0.0])
    np.testing.assert_allclose(r.per_step()[:, 0], 0.2 * f)
    assert np.all(r.per_step()[:, 1:] == 0)
    # steady window: inside the hold, after the settle steps, whole cycles
    assert r.steady_steps() == (5, 9)
    assert CommandRamp(WalkCommand(0.1), ramp_steps=0, hold_steps=7, settle_steps=0).steady_steps() == (0, 6)
    with pytest.raises(ParamError, match="settle_steps"):
        CommandRamp(WalkCommand(0.1), hold_steps=4, settle_steps=3)


def test_staircase_semantics():
    s = SpeedStaircase("left", top=0.12, levels=3, steps_per_level=2, lead_steps=1)
    np.testing.assert_allclose(s.level_values(), [0.04, 0.08, 0.12])
    per = s.per_step()
    np.testing.assert_allclose(per[:, 1], [0.04, 0.04, 0.04, 0.08, 0.08, 0.12, 0.12, 0.0])
    assert np.all(per[:, [0, 2]] == 0)
    assert s.level_steps(1) == (3, 5)
    assert s.unit == "m/s" and SpeedStaircase("turn_left", 1.0).unit == "rad/s"
    with pytest.raises(ParamError, match="even"):
        SpeedStaircase("forward", 0.3, steps_per_level=3)
    with pytest.raises(ParamError, match="direction 'up'"):
        SpeedStaircase("up", 0.3)


# --- footstep plans --------------------------------------------------------------------------

def test_pose_algebra():
    a = np.array([1.0, 2.0, 0.3])
    b = np.array([0.2, -0.1, 0.5])
    np.testing.assert_allclose(relative(a, compose(a, b)), b, atol=1e-12)


def _sole_gap_numpy(pa, pb, length, width):
    """The sole gap as numpy writes it (the planner's own form before it ran in plain floats): the
    corners by a rotation matrix, the separating axes and the distances by dot products and norms."""
    def rect(pose):
        c, s = math.cos(pose[2]), math.sin(pose[2])
        corners = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * [length / 2, width / 2]
        return pose[:2] + corners @ np.array([[c, s], [-s, c]])
    P, Q = rect(pa), rect(pb)
    apart = False
    for poly in (P, Q):
        for i in range(4):
            e = poly[(i + 1) % 4] - poly[i]
            n = np.array([-e[1], e[0]])
            apart |= bool((P @ n).max() < (Q @ n).min() or (Q @ n).max() < (P @ n).min())
    if not apart:
        return 0.0
    d = math.inf
    for X, Y in ((P, Q), (Q, P)):
        for p in X:
            for i in range(4):
                a, ab = Y[i], Y[(i + 1) % 4] - Y[i]
                u = np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0)
                d = min(d, float(np.linalg.norm(p - (a + u * ab))))
    return d


def test_sole_gap_is_the_numpy_reference_on_random_soles():
    rng = np.random.default_rng(3)
    overlapping = 0
    for _ in range(400):
        pa = np.array([*rng.uniform(-0.1, 0.1, 2), rng.uniform(-np.pi, np.pi)])
        pb = np.array([*rng.uniform(-0.1, 0.1, 2), rng.uniform(-np.pi, np.pi)])
        ours, ref = sole_gap(pa, pb, 0.1, 0.055), _sole_gap_numpy(pa, pb, 0.1, 0.055)
        assert ours == pytest.approx(ref, abs=1e-15), (pa, pb)
        overlapping += ref == 0.0
    assert 50 < overlapping < 350                    # both kinds of pair were drawn


def test_sole_gap_hand_checked():
    # side by side, 0.09 m apart centre to centre, 0.055 m wide: 0.035 m between the edges
    assert sole_gap(np.array([0, 0.045, 0]), np.array([0, -0.045, 0]), 0.1, 0.055) == pytest.approx(0.035)
    assert sole_gap(np.zeros(3), np.array([0.05, 0.0, 0.3]), 0.1, 0.055) == 0.0
    # one turned 90 deg: its half-length now lies across y
    assert sole_gap(np.zeros(3), np.array([0.0, 0.2, math.pi / 2]), 0.1, 0.055) == pytest.approx(
        0.2 - 0.0275 - 0.05)


def test_straight_plan_is_eqs_6_to_8():
    p = TlipfmParams()
    plan = plan_footsteps(_steady([p.step_length / p.period, 0, 0], p.n_steps), p.period,
                          p.half_width, p.first_support)
    n = np.arange(p.n_steps)
    np.testing.assert_allclose(plan.support[:, 0], p.step_length * n, atol=1e-12)
    np.testing.assert_allclose(plan.support[:, 1], p.first_support * p.half_width * np.where(n % 2 == 0, 1, -1))
    assert np.all(plan.support[:, 2] == 0)


def test_turning_plan_accumulates_yaw_and_keeps_feet_apart():
    T, W, wz = 0.4, 0.045, 0.5
    plan = plan_footsteps(_steady([0.0, 0.0, wz], 21), T, W, -1)
    # the left foot (moving first) opens by 2 wz T, the right closes: every cycle turns 2 wz T
    yaws = plan.swing_target[:, 2]
    np.testing.assert_allclose(yaws[0:20:2], 2 * wz * T * np.arange(1, 11), atol=1e-12)
    np.testing.assert_allclose(yaws[1:20:2], 2 * wz * T * np.arange(1, 11), atol=1e-12)
    # turning in place: the mid point between the feet stays put
    mid = (plan.swing_target[-1, :2] + plan.support[-1, :2]) / 2
    np.testing.assert_allclose(mid, [0.0, 0.0], atol=1e-12)
    lim = StepLimits()
    for k in range(plan.n_steps):
        assert sole_gap(plan.support[k], plan.swing_target[k], lim.sole_length, lim.sole_width) >= lim.min_gap


def test_sideways_plan_opens_then_closes():
    T, W, vy = 0.4, 0.045, 0.05
    plan = plan_footsteps(_steady([0.0, vy, 0.0], 10), T, W, -1)
    width = [abs(relative(plan.support[k], plan.swing_target[k])[1]) for k in range(9)]
    # left foot steps out by 2 vy T, right foot steps back in to the nominal stance
    np.testing.assert_allclose(width, [2 * W + 2 * vy * T if k % 2 == 0 else 2 * W for k in range(9)])
    # mean velocity over whole cycles is the command
    y_end = (plan.swing_target[7, 1] + plan.support[7, 1]) / 2
    assert y_end / (8 * T) == pytest.approx(vy)


def test_plan_rejects_with_the_step_that_fails():
    cmd = np.array([[0.05, 0, 0], [0.05, 0, 0], [0.5, 0, 0], [0, 0, 0]])
    with pytest.raises(PlanError, match=r"step 2 \(left foot, command 0.5,0,0\): lands 0.200 m ahead"):
        plan_footsteps(cmd, 0.4, 0.045, -1)
    with pytest.raises(PlanError, match="max_turn"):
        plan_footsteps(_steady([0, 0, 1.0]), 0.4, 0.045, -1)
    with pytest.raises(PlanError, match="min_gap"):
        plan_footsteps(_steady([0, 0, 0]), 0.4, 0.02, -1)   # stance narrower than the soles


def test_swing_foot_lands_where_planned():
    p = TlipfmParams(period=0.4, t1=0.08, t2=0.32, h_z=0.02)
    cmd = _steady([0.08, 0.02, 0.3], 10)
    traj = generate(p, commands=cmd)
    plan = plan_footsteps(cmd, p.period, p.half_width, p.first_support)
    for k in range(plan.n_steps):
        i = int(round((p.t_start + (k + 1) * p.period) / traj.dt)) - 1
        sw = 0 if plan.support_side[k] == -1 else 1
        foot = (traj.p_world_foot_l, traj.p_world_foot_r)[sw][i]
        np.testing.assert_allclose(foot[:2], plan.swing_target[k, :2], atol=1e-9)
        assert traj.yaw_world_feet[i, sw] == pytest.approx(plan.swing_target[k, 2])
    # the pelvis yaw is the mean of the feet's, and the hip-yaw joints take the difference
    np.testing.assert_allclose(traj.yaw_world_pelvis, traj.yaw_world_feet.mean(axis=1))
    np.testing.assert_allclose(traj.joint("l_hip_yaw"), traj.yaw_world_feet[:, 0] - traj.yaw_world_pelvis,
                               atol=1e-12)


def test_constant_command_reproduces_the_straight_walk():
    p = TlipfmParams(flywheel_accel=5.0)
    a = generate(p)
    b = generate(p, commands=_steady([p.step_length / p.period, 0, 0], p.n_steps))
    for name in ("q_ref", "p_world_com", "p_world_zmp_ref", "p_world_foot_l", "p_world_foot_r"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), atol=1e-12, err_msg=name)
    assert np.array_equal(a.support, b.support)


@pytest.mark.parametrize("model", ["lipm", "tlipfm"])
def test_turning_com_matches_numerical_integration(model):
    """x'' = (x - p_zmp - shift) / T_TF^2 per world axis, integrated with a tight RK45."""
    p = TlipfmParams(period=0.4, t1=0.08, t2=0.32, flywheel_accel=3.0, model=model)
    cmd = _steady([0.06, 0.02, 0.4], 12)
    plan = plan_footsteps(cmd, p.period, p.half_width, p.first_support)
    t = np.arange(0, p.t_start + 12 * p.period + p.t_end, 0.002)
    com = com_trajectory(p, t, plan=plan)
    const = pendulum_constants(p)

    def zmp_at(tt):
        z = natural_zmp(p, np.array([tt]), plan)[0]
        n = int(np.clip(math.floor((tt - p.t_start) / p.period), 0, 11))
        th = plan.support[n, 2]
        return z + const.zmp_shift * np.array([math.cos(th), math.sin(th)])

    def rhs(tt, y):
        z = zmp_at(tt)
        return [y[2], y[3], (y[0] - z[0]) / const.T ** 2, (y[1] - z[1]) / const.T ** 2]

    y0 = [com.pos[0, 0], com.pos[0, 1], com.vel[0, 0], com.vel[0, 1]]
    horizon = p.t_start + 6 * p.period        # the unstable mode grows; six steps are plenty
    sel = t <= horizon
    sol = solve_ivp(rhs, (0, horizon), y0, t_eval=t[sel], rtol=1e-10, atol=1e-12, max_step=0.002)
    assert np.max(np.abs(sol.y[:2].T - com.pos[sel])) < 2e-5
    # and the CoM comes to rest between the last two feet (exponentially, within t_end)
    th = plan.support[-1, 2]        # (with the flywheel's constant ZMP shift along the heading)
    mid = (plan.support[-1, :2] + plan.swing_target[-1, :2]) / 2 + const.zmp_shift * np.array(
        [math.cos(th), math.sin(th)])
    assert np.hypot(*com.vel[-1]) < 1e-3
    np.testing.assert_allclose(com.pos[-1], mid, atol=2e-4)


def test_command_generate_rejects_unreachable():
    with pytest.raises(PlanError, match="max_forward"):
        generate(TlipfmParams(), commands=_steady([0.3, 0, 0]))


def test_torso_lean_keeps_the_soles_where_planned():
    from gaits.leg_kinematics import LegGeometry, leg_fk, rot_y, rot_z
    from gaits.trajectory import JOINT_NAMES
    leg = LegGeometry()
    lean = 0.15
    p = TlipfmParams(period=0.4, t1=0.08, t2=0.32, torso_pitch=lean)
    traj = generate(p, leg, commands=_steady([0.08, 0.0, 0.3], 8))
    for side, name, foot in ((1, "l", traj.p_world_foot_l), (-1, "r", traj.p_world_foot_r)):
        i = JOINT_NAMES.index(f"{name}_hip_yaw")
        pos, R = leg_fk(traj.q_ref[:, i:i + 6], leg, side)
        R_pelvis = rot_z(traj.yaw_world_pelvis) @ rot_y(lean)
        world = np.einsum("kij,kj->ki", R_pelvis, pos) + traj.p_world_pelvis
        np.testing.assert_allclose(world, foot, atol=1e-9)
        R_sole = R_pelvis @ R
        yaw = traj.yaw_world_feet[:, 0 if side == 1 else 1]
        np.testing.assert_allclose(R_sole, rot_z(yaw), atol=1e-9)


def test_unreachable_target_carries_its_time():
    from gaits.leg_kinematics import LegGeometry, UnreachableTargetError, leg_ik
    targets = np.array([[0.0, 0.037, -0.2], [0.0, 0.037, -0.5]])
    with pytest.raises(UnreachableTargetError) as info:
        leg_ik(targets, 0.0, LegGeometry(), "left", t=np.array([0.0, 0.25]))
    assert info.value.t == 0.25 and "t = 0.250 s" in str(info.value)
