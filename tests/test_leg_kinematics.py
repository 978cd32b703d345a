"""EROS leg IK/FK (eqs 9-35): round trips, hand-checked poses, reach errors."""

import numpy as np
import pytest

from gaits import LegGeometry, UnreachableTargetError, leg_fk, leg_ik

LEG = LegGeometry()


def random_flat_foot_joints(rng, n):
    q = np.empty((n, 6))
    q[:, 0] = rng.uniform(-0.6, 0.6, n)      # hip yaw
    q[:, 1] = rng.uniform(-0.5, 0.5, n)      # hip roll
    q[:, 2] = rng.uniform(-1.4, 0.8, n)      # hip pitch
    q[:, 3] = rng.uniform(0.05, 2.6, n)      # knee (flexion positive)
    q[:, 4] = -(q[:, 2] + q[:, 3])           # eq 27: sole level
    q[:, 5] = -q[:, 1]                       # eq 28
    return q


@pytest.mark.parametrize("side", ["left", "right"])
def test_ik_then_fk_returns_target(side):
    rng = np.random.default_rng(7 if side == "left" else 8)
    q_true = random_flat_foot_joints(rng, 6000)
    p, R = leg_fk(q_true, LEG, side)
    # keep the targets whose ankle is below the hip: the walking workspace
    below = (p[:, 2] + LEG.ankle_height) < -0.02
    q_true, p, R = q_true[below], p[below], R[below]
    assert len(q_true) > 3000
    q = leg_ik(p, q_true[:, 0], LEG, side)
    p2, R2 = leg_fk(q, LEG, side)
    assert np.max(np.abs(p2 - p)) < 1e-9          # metres
    assert np.max(np.abs(R2 - R)) < 1e-9          # rotation entries (radians to first order)
    assert np.max(np.abs(q - q_true)) < 1e-9      # unique solution with the knee bent forward
    # the sole stays level with the heading as its only rotation
    yaw = q_true[:, 0]
    assert np.allclose(R2[:, 2, 2], 1.0, atol=1e-12)
    assert np.allclose(np.arctan2(R2[:, 1, 0], R2[:, 0, 0]), yaw, atol=1e-12)


def test_zero_pose_hand_checked():
    p, R = leg_fk(np.zeros(6), LEG, "left")
    assert np.allclose(p, [0.0, 0.037, -(0.110 + 0.110 + 0.035)], atol=1e-15)
    p, _ = leg_fk(np.zeros(6), LEG, "right")
    assert np.allclose(p, [0.0, -0.037, -0.255], atol=1e-15)


def test_right_angle_knee_hand_checked():
    # thigh 45 deg forward, shank 45 deg back: ankle straight below the hip at 2 l cos45
    z = -(2 * 0.110 * np.cos(np.pi / 4)) - 0.035
    q = leg_ik(np.array([0.0, 0.037, z]), 0.0, LEG, "left")
    assert np.allclose(q, [0.0, 0.0, -np.pi / 4, np.pi / 2, -np.pi / 4, 0.0], atol=1e-12)


def test_sideways_target_uses_hip_roll():
    # foot 3 cm outward of the hip, leg otherwise straight: roll = atan(0.03 / 0.22)
    q = leg_ik(np.array([0.0, 0.037 + 0.03, -np.sqrt(0.22 ** 2 - 0.03 ** 2) - 0.035]), 0.0, LEG, "left")
    assert q[1] == pytest.approx(np.arctan2(0.03, np.sqrt(0.22 ** 2 - 0.03 ** 2)), abs=1e-12)
    assert q[5] == pytest.approx(-q[1], abs=1e-15)
    assert q[3] == pytest.approx(0.0, abs=2e-7)


def test_out_of_reach_is_a_clear_error():
    targets = np.array([[0.0, 0.037, -0.20], [0.0, 0.037, -0.30], [0.0, 0.037, -0.20]])
    with pytest.raises(UnreachableTargetError) as err:
        leg_ik(targets, 0.0, LEG, "left", t=np.array([0.0, 0.01, 0.02]))
    msg = str(err.value)
    assert "left foot target" in msg and "(sample (1,))" in msg and "t = 0.010 s" in msg
    assert "reachable [0.0000, 0.2200] m" in msg


def test_too_close_is_a_clear_error():
    leg = LegGeometry(thigh=0.12, shank=0.08)
    with pytest.raises(UnreachableTargetError, match=r"reachable \[0.0400, 0.2000\] m"):
        leg_ik(np.array([0.0, -0.037, -0.035 - 0.01]), 0.0, leg, "right")


def test_shape_errors_name_the_shapes():
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\), got \(5, 2\)"):
        leg_ik(np.zeros((5, 2)), 0.0, LEG, "left")
    with pytest.raises(ValueError, match=r"\(\.\.\., 6\), got \(4,\)"):
        leg_fk(np.zeros(4), LEG, "left")
    with pytest.raises(ValueError, match="side must be"):
        leg_fk(np.zeros(6), LEG, "middle")


def test_ankle_above_hip_is_a_clear_error():
    with pytest.raises(UnreachableTargetError, match="above the hip centre"):
        leg_ik(np.array([0.15, 0.037, 0.05]), 0.0, LEG, "left")


def test_hips_behind_the_pelvis_origin_shift_every_ik_by_that_offset():
    """``hip_offset_x`` (ours, a team robot's torso frame not over its hips): the same joint angles
    put the sole exactly that far further along x, and the IKs (flat foot, any pose) invert it."""
    from gaits.leg_kinematics import leg_ik_pose
    off = LegGeometry(hip_offset_x=-0.02)
    rng = np.random.default_rng(3)
    q = random_flat_foot_joints(rng, 200)
    for side in ("left", "right"):
        p0, R0 = leg_fk(q, LEG, side)
        p1, R1 = leg_fk(q, off, side)
        assert np.allclose(p1 - p0, [-0.02, 0.0, 0.0], atol=1e-15) and np.allclose(R1, R0, atol=0)
        below = (p1[:, 2] + off.ankle_height) < -0.02
        back = leg_ik(p1[below], q[below, 0], off, side)
        assert np.max(np.abs(back - q[below])) < 1e-9
        k = int(np.flatnonzero(below)[0])
        assert np.allclose(leg_ik_pose(p1[k], R1[k], off, side), q[k], atol=1e-9)
    with pytest.raises(Exception, match="hip_offset_x"):
        LegGeometry(hip_offset_x=0.2)
