"""EROS head and arm FK against the paper's printed closed forms (eqs 3, 5-8)."""

import numpy as np

from gaits import ArmGeometry, HeadGeometry, arm_fk, head_fk


def test_head_position_matches_eq3():
    rng = np.random.default_rng(1)
    q = rng.uniform(-1.5, 1.5, (500, 2))
    h = HeadGeometry(d_z1=0.03, d_z2=0.05)
    T = head_fk(q, h)
    t1, t2 = q[:, 0], q[:, 1]
    eq3 = np.column_stack([h.d_z2 * np.cos(t1) * np.sin(t2), h.d_z2 * np.sin(t1) * np.sin(t2),
                           h.d_z1 + h.d_z2 * np.cos(t2)])
    assert np.max(np.abs(T[:, :3, 3] - eq3)) < 1e-15


def _eq5_position(q, a, dy):
    t1, t2, t3 = q[:, 0], q[:, 1], q[:, 2]
    phi = a.d_z2 * np.cos(t2) + a.d_z3 * np.cos(t2) * np.cos(t3)
    r14 = -a.d_z1 * np.sin(t1) - np.sin(t1) * phi - a.d_z3 * np.cos(t1) * np.sin(t3)
    r24 = dy + a.d_z2 * np.sin(t2) + a.d_z3 * np.cos(t3) * np.sin(t2)
    r34 = a.d_z3 * np.sin(t1) * np.sin(t3) - np.cos(t1) * phi - a.d_z1 * np.cos(t1)
    return np.column_stack([r14, r24, r34])


def test_arm_positions_match_eq5_and_eq7():
    rng = np.random.default_rng(2)
    q = rng.uniform(-1.5, 1.5, (500, 3))
    a = ArmGeometry(d_y1=0.08, d_z1=0.02, d_z2=0.08, d_z3=0.10)
    right = arm_fk(q, "right", a)
    left = arm_fk(q, "left", a)
    assert np.max(np.abs(right[:, :3, 3] - _eq5_position(q, a, +a.d_y1))) < 1e-15
    assert np.max(np.abs(left[:, :3, 3] - _eq5_position(q, a, -a.d_y1))) < 1e-15
    # eq 5 rotation entries that the conversion left legible
    t1, t2, t3 = q[:, 0], q[:, 1], q[:, 2]
    assert np.allclose(right[:, 1, 1], np.cos(t2), atol=1e-15)                    # R22
    assert np.allclose(right[:, 0, 1], np.sin(t1) * np.sin(t2), atol=1e-15)       # R12
    assert np.allclose(right[:, 2, 1], np.cos(t1) * np.sin(t2), atol=1e-15)       # R32
    assert np.allclose(right[:, 1, 2], -np.cos(t3) * np.sin(t2), atol=1e-15)      # R23


def test_arm_hangs_down_at_zero():
    a = ArmGeometry()
    T = arm_fk(np.zeros(3), "right", a)
    assert np.allclose(T[:3, 3], [0.0, a.d_y1, -(a.d_z1 + a.d_z2 + a.d_z3)])
