"""EROS head and arm forward kinematics (Pristovani et al., eqs 1-8, Tables 2-4).

Each joint rotates first and then translates to the next joint, as Tables 2-4
list them ("rotational", then "translation"):

* head:  T = Rz(h1) Tz(d_z1) Ry(h2) Tz(d_z2)                  (Table 2, eqs 1-3)
* right arm: T = Ry(a1) T(0, +d_y1, -d_z1) Rx(a2) Tz(-d_z2) Ry(a3) Tz(-d_z3)   (Table 3, eqs 4-6)
* left arm:  the same with -d_y1                                (Table 4, eqs 7-8)

The printed eq 2 matrix is garbled by the conversion; eq 3 (the head position)
and the position column of eq 5 (R14, R24, R34, with phi) are legible, and the
products above reproduce them exactly (see ``tests/test_limb_kinematics.py``).
Eq 5 names the lateral offset ``d_RA,x,1``; Table 3 calls it ``d_RA,y,1``: it
is the shoulder's lateral offset either way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .leg_kinematics import rot_x, rot_y, rot_z

__all__ = ["HeadGeometry", "ArmGeometry", "head_fk", "arm_fk", "homogeneous"]


@dataclass(frozen=True)
class HeadGeometry:
    """Neck lengths (EROS Table 2)."""

    d_z1: float = 0.030   # [m] torso top to head-pitch axis
    d_z2: float = 0.050   # [m] head-pitch axis to the head's end effector (camera)


@dataclass(frozen=True)
class ArmGeometry:
    """Arm lengths (EROS Tables 3-4)."""

    d_y1: float = 0.080   # [m] torso centre to shoulder, lateral
    d_z1: float = 0.000   # [m] shoulder pitch to shoulder roll, downward
    d_z2: float = 0.080   # [m] upper arm: shoulder roll to elbow
    d_z3: float = 0.100   # [m] forearm: elbow to hand


def homogeneous(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """4x4 homogeneous transforms from rotations (..., 3, 3) and translations (..., 3)."""
    R = np.asarray(R, dtype=float)
    p = np.asarray(p, dtype=float)
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def _trans(v: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    return homogeneous(np.broadcast_to(np.eye(3), shape + (3, 3)), np.broadcast_to(v, shape + (3,)))


def head_fk(q: np.ndarray, head: HeadGeometry = HeadGeometry()) -> np.ndarray:
    """Head transform ^0T_H (..., 4, 4) from (yaw, pitch) angles (..., 2): eqs 1-3."""
    q = np.asarray(q, dtype=float)
    if q.shape[-1] != 2:
        raise ValueError(f"head_fk expects angles of shape (..., 2), got {q.shape}")
    shape = q.shape[:-1]
    zero = np.zeros(shape + (3,))
    T1 = homogeneous(rot_z(q[..., 0]), zero) @ _trans(np.array([0.0, 0.0, head.d_z1]), shape)
    T2 = homogeneous(rot_y(q[..., 1]), zero) @ _trans(np.array([0.0, 0.0, head.d_z2]), shape)
    return T1 @ T2


def arm_fk(q: np.ndarray, side: int | str, arm: ArmGeometry = ArmGeometry()) -> np.ndarray:
    """Arm transform ^0_3T (..., 4, 4) from (pitch, roll, elbow) angles (..., 3): eqs 4-8.

    ``side`` is 'right' (Table 3, +d_y1 as printed) or 'left' (Table 4, -d_y1).
    The paper's frames put the right arm at +y; gait-tuner's robot uses y left,
    so ``tuner`` mirrors the sign when it places the arms.
    """
    q = np.asarray(q, dtype=float)
    if q.shape[-1] != 3:
        raise ValueError(f"arm_fk expects angles of shape (..., 3), got {q.shape}")
    if side in ("right", "r", -1):
        dy = arm.d_y1
    elif side in ("left", "l", 1):
        dy = -arm.d_y1
    else:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    shape = q.shape[:-1]
    zero = np.zeros(shape + (3,))
    T1 = homogeneous(rot_y(q[..., 0]), zero) @ _trans(np.array([0.0, dy, -arm.d_z1]), shape)
    T2 = homogeneous(rot_x(q[..., 1]), zero) @ _trans(np.array([0.0, 0.0, -arm.d_z2]), shape)
    T3 = homogeneous(rot_y(q[..., 2]), zero) @ _trans(np.array([0.0, 0.0, -arm.d_z3]), shape)
    return T1 @ T2 @ T3
