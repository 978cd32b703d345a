"""EROS 6-DoF leg inverse and forward kinematics (Pristovani et al., eqs 9-35, Tables 5-6).

Chain of one leg, from the pelvis frame (x forward, y left, z up; origin midway
between the two hip-joint centres):

    T_pelvis_sole = Trans(d_x1, +-d_y1, -d_z1) Rz(q1) Rx(q2) Ry(q3) Trans(0, 0, -d_z3)
                    Ry(q4) Trans(0, 0, -d_z4) Ry(q5) Rx(q6) Trans(0, 0, -d_z6)

(d_x1 = ``hip_offset_x`` is ours, zero for EROS: a robot whose torso frame is not over its hips.)
q1..q6 = hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll. Angles obey
the right-hand rule about the pelvis axes at the zero pose, so knee flexion is
positive and a positive ankle pitch points the toe down.

Readings of the printed paper (the OCR and the paper itself garble some lines):

* Table 5 lists the translation (0, d_y1, -d_z1) after Rz(q1). We put it before:
  the hip-yaw axis passes through the hip centre, as on every servo humanoid,
  so that yaw turns the foot about the leg and does not swing the hip sideways.
  Tables 5-6 repeat theta indices (``R_y(theta_RL,2)`` for the knee); we read
  them as q4, q5, q6.
* Eqs 10-13 as printed give dP_x = 0 and dP_y = 2 P_y for zero heading, which
  cannot be meant. We read them as the target expressed in the yawed hip frame:
  ``dP = Rz(-q1) P`` (R0 cos(beta), R0 sin(beta) with beta = atan2(P_y, P_x) - q1).
* Eq 17 prints ``R2 = sqrt(dP_x^2 + P6z^2)``; the hip-ankle distance in the
  rolled plane is ``sqrt(dP_x^2 + R1^2)``, which eq 21 (``atan(dP_x / R1)``)
  already assumes. We use R1.
* Eqs 22-24 give the thigh's angle to the hip-ankle line as
  ``atan(l3 sin(gc) / (l3 + l4 cos(gc)))``; the triangle gives
  ``atan2(l4 sin(q4), l3 + l4 cos(q4))`` with q4 = pi - gc (eq 26). We use the
  latter; the two agree only for a straight leg.
* Eqs 25-28 (q3 = ga + gb, q4 = 180 - gc, q5 = q3 + q4, q6 = -q2) hold with the
  paper's own sign convention; in ours they read q3 = -(ga + gb), q5 = -(q3 + q4),
  q6 = -q2, which keeps the sole parallel to the ground.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import math
from typing import Mapping

import numpy as np

from .leg_chain import IKNotConverged, LegChains
from .params import ParamError

__all__ = [
    "LegGeometry",
    "UnreachableTargetError",
    "LEG_JOINTS",
    "leg_ik",
    "leg_fk",
    "refine_ik",
    "leg_ik_pose",
    "rot_x",
    "rot_y",
    "rot_z",
]

LEG_JOINTS = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")


class UnreachableTargetError(ValueError):
    """A foot target lies outside the leg's reach; the message names the sample and distances,
    ``t`` holds the sample's time [s] when the caller gave times."""

    def __init__(self, message: str, t: float | None = None) -> None:
        super().__init__(message)
        self.t = t


@dataclass(frozen=True)
class LegGeometry:
    """Lengths the leg IK and the gait generators need (EROS Table 5 names in brackets).

    Defaults are the built-in kid-size robot (52 cm, like EROS): see ``tuner.robots``.

    The last four fields are ours, not the paper's: where a robot's CoM and sole centre sit
    relative to its pelvis and ankle (read off a user's MJCF by ``tuner.robots``). The
    generators plan the CoM and the sole centres; :func:`gaits.trajectory.assemble` shifts the
    pelvis and the IK's ankle targets by these offsets, so a robot whose CoM sits behind its
    hips, or whose sole centre lies ahead of its ankle, does not walk leaning. All zero for a
    robot built like EROS.
    """

    hip_offset_y: float = 0.037    # [m] pelvis centre to each hip-joint centre, lateral (d_y1)
    hip_offset_z: float = 0.0      # [m] pelvis origin to hip-joint centres, downward (d_z1)
    thigh: float = 0.110           # [m] hip pitch axis to knee axis (d_z3)
    shank: float = 0.110           # [m] knee axis to ankle pitch axis (d_z4)
    ankle_height: float = 0.035    # [m] ankle roll axis to sole (d_z6)
    com_above_pelvis: float = 0.020  # [m] CoM height above the pelvis origin, upright pose
    com_forward: float = 0.0       # [m] CoM ahead of the pelvis origin at the walking crouch (ours)
    com_lateral: float = 0.0       # [m] CoM left of the pelvis origin (ours)
    sole_forward: float = 0.0      # [m] sole centre ahead of the ankle axes (ours)
    sole_outward: float = 0.0      # [m] sole centre outboard of the ankle axes, mirrored per side (ours)
    hip_offset_x: float = 0.0      # [m] hip-joint centres ahead of the pelvis origin (ours: a team robot's
    #                                torso frame need not sit over its hips; EROS puts them under it)
    chains: LegChains | None = None  # the legs as the robot file builds them, where the closed form does not
    #                                  fit (ours, ``leg_chain``): the IK and FK below are then numerical; the
    #                                  numbers above stay the planners' (reach, heights, offsets)

    @property
    def ik(self) -> str:
        """Which IK the legs get: ``closed form`` (the papers') or ``numerical`` (``leg_chain``)."""
        return "closed form" if self.chains is None else "numerical"

    def __post_init__(self) -> None:
        for name in ("com_forward", "com_lateral", "sole_forward", "sole_outward", "hip_offset_x"):
            value = getattr(self, name)
            if not (-0.1 <= value <= 0.1):
                raise ParamError(f"leg.{name} = {value!r} m is out of range [-0.1, 0.1] m")
        for name in ("thigh", "shank", "ankle_height"):
            value = getattr(self, name)
            if not (0.0 < value < 1.0):
                raise ParamError(f"leg.{name} = {value!r} m is out of range (0, 1) m")
        if not (0.0 <= self.hip_offset_y < 0.5):
            raise ParamError(f"leg.hip_offset_y = {self.hip_offset_y!r} m is out of range [0, 0.5) m")

    @property
    def max_hip_height(self) -> float:
        """Sole-to-hip-centre height with the leg straight [m]."""
        return self.thigh + self.shank + self.ankle_height

    def hip_in_pelvis(self, side: int) -> np.ndarray:
        """Hip-joint centre in the pelvis frame; side = +1 left, -1 right."""
        return np.array([self.hip_offset_x, side * self.hip_offset_y, -self.hip_offset_z])

    def sole_in_ankle(self, side: int) -> np.ndarray:
        """Sole centre relative to the point of the sole straight below the ankle [m] (3,); with
        ``chains``, each leg's own (its feet need not mirror each other)."""
        if self.chains is not None:
            return np.array(self.chains.side(side).sole_offset)
        return np.array([self.sole_forward, side * self.sole_outward, 0.0])

    @property
    def com_in_pelvis(self) -> np.ndarray:
        """CoM relative to the pelvis origin [m] (3,)."""
        return np.array([self.com_forward, self.com_lateral, self.com_above_pelvis])


def rot_x(a: np.ndarray) -> np.ndarray:
    """Rotation matrices about x, shape (..., 3, 3)."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def rot_y(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def rot_z(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _side(side: int | str) -> int:
    if side in (1, "left", "l"):
        return 1
    if side in (-1, "right", "r"):
        return -1
    raise ValueError(f"side must be 'left'/'right' (or +1/-1), got {side!r}")


def leg_fk(q: np.ndarray, leg: LegGeometry, side: int | str) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics: joint angles (..., 6) -> (p_pelvis_sole (..., 3), R_pelvis_sole (..., 3, 3)).

    Implements the chain in the module docstring (EROS Table 5/6 with the yaw
    axis through the hip centre).
    """
    q = np.asarray(q, dtype=float)
    if q.shape[-1] != 6:
        raise ValueError(f"leg_fk expects joint angles of shape (..., 6), got {q.shape}")
    s = _side(side)
    if leg.chains is not None:                      # the robot file's chain (leg_chain)
        return leg.chains.side(s).fk_many(q)
    q1, q2, q3, q4, q5, q6 = np.moveaxis(q, -1, 0)
    R_hip = rot_z(q1) @ rot_x(q2)
    R_thigh = R_hip @ rot_y(q3)
    R_shank = R_thigh @ rot_y(q4)
    R_foot = R_shank @ rot_y(q5) @ rot_x(q6)
    down = np.array([0.0, 0.0, -1.0])
    p = (leg.hip_in_pelvis(s)
         + (R_thigh @ down) * leg.thigh
         + (R_shank @ down) * leg.shank
         + (R_foot @ down) * leg.ankle_height)
    return p, R_foot


def leg_ik(p_pelvis_sole: np.ndarray, yaw: np.ndarray | float, leg: LegGeometry,
           side: int | str, *, t: np.ndarray | None = None) -> np.ndarray:
    """Inverse kinematics for a flat foot: sole position + heading -> joint angles (..., 6).

    ``p_pelvis_sole`` (..., 3) is the sole centre in the pelvis frame and ``yaw``
    (...) the foot heading (theta_Heading, eq 9); the sole is kept parallel to
    the pelvis' x-y plane. Vectorised over leading dimensions.

    Raises :class:`UnreachableTargetError` naming the first offending sample (and
    its time if ``t`` is given) when the hip-ankle distance exceeds
    ``thigh + shank``, is shorter than ``|thigh - shank|``, or the ankle would
    not be below the hip (where eq 15's roll angle is undefined).
    """
    p = np.asarray(p_pelvis_sole, dtype=float)
    if p.shape[-1] != 3:
        raise ValueError(f"leg_ik expects targets of shape (..., 3), got {p.shape}")
    yaw = np.broadcast_to(np.asarray(yaw, dtype=float), p.shape[:-1])
    s = _side(side)
    if leg.chains is not None:
        return _chain_ik(p, rot_z(yaw), leg, s, t)
    l3, l4 = leg.thigh, leg.shank
    # eq 9: the yaw joint takes the heading directly
    q1 = yaw.copy()
    # eqs 10-13 (read as a rotation into the yawed hip frame), eq 14 (ankle above the sole)
    p_hip = p - leg.hip_in_pelvis(s)
    c, sn = np.cos(q1), np.sin(q1)
    ax = c * p_hip[..., 0] + sn * p_hip[..., 1]
    ay = -sn * p_hip[..., 0] + c * p_hip[..., 1]
    az = p_hip[..., 2] + leg.ankle_height
    # eqs 15-16: hip roll from the frontal plane, R1 the leg length seen from the front
    q2 = np.arctan2(ay, -az)
    r1 = np.hypot(ay, az)
    # eq 17 (with R1): hip-ankle distance; eqs 18-20: inner knee angle by the law of cosines
    r2 = np.hypot(ax, r1)
    too_far = r2 > (l3 + l4) * (1 + 1e-12)
    too_near = r2 < abs(l3 - l4) * (1 - 1e-12)
    above = az >= 0.0                     # eq 15's roll needs the ankle below the hip
    bad = too_far | too_near | above
    if np.any(bad):
        idx = np.unravel_index(int(np.flatnonzero(bad)[0]), bad.shape) if bad.ndim else ()
        t_bad = float(np.asarray(t)[idx]) if t is not None else None
        when = f" at t = {t_bad:.3f} s" if t is not None else ""
        sample = f" (sample {tuple(int(i) for i in idx)})" if idx else ""
        name = "left" if s == 1 else "right"
        d = float(np.asarray(r2)[idx])
        if bool(np.asarray(above)[idx]):
            raise UnreachableTargetError(
                f"{name} foot target {np.round(p[idx], 4).tolist()} m{sample}{when} is out of reach: "
                f"the ankle would be {float(np.asarray(az)[idx]):.4f} m above the hip centre", t_bad)
        raise UnreachableTargetError(
            f"{name} foot target {np.round(p[idx], 4).tolist()} m{sample}{when} is out of reach: "
            f"hip-ankle distance {d:.4f} m, reachable [{abs(l3 - l4):.4f}, {l3 + l4:.4f}] m", t_bad)
    cos_gc = np.clip((l3 ** 2 + l4 ** 2 - r2 ** 2) / (2 * l3 * l4), -1.0, 1.0)
    gc = np.arccos(cos_gc)
    q4 = np.pi - gc                                   # eq 26
    ga = np.arctan2(ax, r1)                           # eq 21
    gb = np.arctan2(l4 * np.sin(q4), l3 + l4 * np.cos(q4))  # eqs 22-24 (triangle reading)
    q3 = -(ga + gb)                                   # eq 25
    q5 = -(q3 + q4)                                   # eq 27
    q6 = -q2                                          # eq 28
    return np.stack([q1, q2, q3, q4, q5, q6], axis=-1)


def _chain_ik(p: np.ndarray, R: np.ndarray, leg: LegGeometry, side: int, t: np.ndarray | None,
              q0: np.ndarray | None = None) -> np.ndarray:
    """The numerical IK (``leg_chain``) over leading dimensions: sole points (..., 3) and rotations
    (..., 3, 3) -> joints (..., 6), each sample warm-started from the one before (the first from
    ``q0``'s, else the closed form on the planners' numbers: near enough for the Newton steps)."""
    chain = leg.chains.side(side)
    shape = p.shape[:-1]
    P = p.reshape(-1, 3)
    Rs = np.broadcast_to(R, shape + (3, 3)).reshape(-1, 3, 3)
    Q0 = None if q0 is None else np.broadcast_to(q0, shape + (6,)).reshape(-1, 6)
    out = np.empty((len(P), 6))
    prev = None
    for i in range(len(P)):
        start = Q0[i] if Q0 is not None else prev
        if start is None:
            try:
                start = leg_ik_pose(P[i], Rs[i], dataclasses.replace(leg, chains=None), side)
            except UnreachableTargetError:
                start = np.zeros(6)
        try:
            out[i] = prev = chain.solve(P[i], Rs[i], q0=start)
        except IKNotConverged as exc:
            idx = np.unravel_index(i, shape) if shape else ()
            t_bad = float(np.asarray(t)[idx]) if t is not None else None
            when = f" at t = {t_bad:.3f} s" if t is not None else ""
            sample = f" (sample {tuple(int(j) for j in idx)})" if idx else ""
            name = "left" if side == 1 else "right"
            raise UnreachableTargetError(f"{name} {exc}{sample}{when}", t_bad) from None
    return out.reshape(shape + (6,))


def _rotation_error(R_d: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Axis-angle-like error vector (small angles) taking R to R_d, shape (..., 3)."""
    E = R_d @ np.swapaxes(R, -1, -2)
    return 0.5 * np.stack([E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0],
                           E[..., 1, 0] - E[..., 0, 1]], axis=-1)


def refine_ik(q0: np.ndarray, p_pelvis_sole: np.ndarray, R_pelvis_sole: np.ndarray, leg: LegGeometry,
              side: int | str, iterations: int = 4) -> np.ndarray:
    """Full-pose IK by Gauss-Newton from ``q0`` (..., 6): sole position (..., 3) and orientation
    (..., 3, 3) in the pelvis frame (ours, for a sole not parallel to the pelvis, e.g. a leaning
    torso). The flat-foot IK of :func:`leg_ik` is a good start, so a few iterations reach
    machine precision; the Jacobian is a central difference of :func:`leg_fk`.
    """
    if leg.chains is not None:                      # the chain's IK is already full-pose
        return _chain_ik(np.asarray(p_pelvis_sole, dtype=float), np.asarray(R_pelvis_sole, dtype=float), leg,
                         _side(side), None, q0=np.asarray(q0, dtype=float))
    q = np.array(q0, dtype=float)
    h = 1e-6
    for _ in range(iterations):
        p, R = leg_fk(q, leg, side)
        err = np.concatenate([p_pelvis_sole - p, _rotation_error(R_pelvis_sole, R)], axis=-1)
        J = np.empty(q.shape + (6,))
        for j in range(6):
            dq = np.zeros(6)
            dq[j] = h
            pp, Rp = leg_fk(q + dq, leg, side)
            pm, Rm = leg_fk(q - dq, leg, side)
            J[..., :3, j] = (pp - pm) / (2 * h)
            J[..., 3:, j] = (_rotation_error(Rp, R) - _rotation_error(Rm, R)) / (2 * h)
        q = q + np.linalg.solve(J, err[..., None])[..., 0]
    return q


def leg_ik_pose(p_pelvis_sole: np.ndarray, R_pelvis_sole: np.ndarray, leg: LegGeometry, side: int | str,
                q0: np.ndarray | None = None, tol: float | None = None, step_tol: float = 0.0) -> np.ndarray:
    """Closed-form IK for one sample and any sole orientation (ours): the point ``ankle_height``
    below the ankle (3,) and the sole's rotation (3, 3), in the pelvis frame -> the 6 joints.

    The leg's hip axes (yaw, roll, pitch) and ankle axes (pitch, roll) intersect, so the hip seen
    from the ankle, r = R^T (hip - ankle), fixes the knee (law of cosines, flexion positive), the
    ankle roll (atan2 of r's y and z) and the ankle pitch; the hip's Z-X-Y angles follow from
    R_hip = R Rx(-q6) Ry(-(q4 + q5)). Agrees with :func:`leg_fk` to machine precision (tested) and
    with :func:`refine_ik`'s Gauss-Newton where that converges, at a fraction of its cost (the walk
    engine's targets every tick). Raises :class:`UnreachableTargetError` beyond the leg's reach.
    ``tol``, ``step_tol``: the numerical IK's stopping error [m + rad] and step [rad] (``LegChain.solve``;
    None and 0 its defaults).
    """
    s = _side(side)
    R = np.asarray(R_pelvis_sole, dtype=float)
    if leg.chains is not None:                      # numerical (leg_chain), from q0: a walk's last tick
        p = np.asarray(p_pelvis_sole, dtype=float)
        if q0 is None:                              # the closed form on the planners' numbers: near enough
            try:
                q0 = leg_ik_pose(p, R, dataclasses.replace(leg, chains=None), s)
            except UnreachableTargetError:
                q0 = np.zeros(6)
        try:
            chain = leg.chains.side(s)
            return chain.solve(p, R, q0=q0) if tol is None else chain.solve(p, R, q0=q0, tol=tol, step_tol=step_tol)
        except IKNotConverged as exc:
            name = "left" if s == 1 else "right"
            err = UnreachableTargetError(f"{name} {exc}")
            err.best = exc.best
            raise err from None
    # in plain floats (numpy's per-call cost dominates 3 x 3 products; the engine calls this every tick)
    R00, R01, R02, R10, R11, R12, R20, R21, R22 = R.reshape(9).tolist()
    px, py, pz = np.asarray(p_pelvis_sole, dtype=float).reshape(3).tolist()
    ah = leg.ankle_height
    dx, dy, dz = leg.hip_offset_x - (px + R02 * ah), s * leg.hip_offset_y - (py + R12 * ah), \
        -leg.hip_offset_z - (pz + R22 * ah)
    r = (R00 * dx + R10 * dy + R20 * dz, R01 * dx + R11 * dy + R21 * dz, R02 * dx + R12 * dy + R22 * dz)
    l3, l4 = leg.thigh, leg.shank
    C2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    cos4 = (C2 - l3 * l3 - l4 * l4) / (2 * l3 * l4)
    if cos4 > 1 + 1e-12 or cos4 < -1 - 1e-12:
        name = "left" if s == 1 else "right"
        raise UnreachableTargetError(f"{name} foot target {np.round(p_pelvis_sole, 4).tolist()} m is out of reach: "
                                     f"hip-ankle distance {math.sqrt(C2):.4f} m, reachable "
                                     f"[{abs(l3 - l4):.4f}, {l3 + l4:.4f}] m")
    q4 = math.acos(min(max(cos4, -1.0), 1.0))
    wx, wz = -l3 * math.sin(q4), l3 * math.cos(q4) + l4
    q6 = math.atan2(r[1], r[2])
    vz = math.hypot(r[1], r[2])
    if abs(q6) > math.pi / 2:                 # the branch with the ankle roll within +-90 deg
        q6 = math.atan2(-r[1], -r[2])
        vz = -vz
    q5 = math.atan2(wx, wz) - math.atan2(r[0], vz)
    c6, s6 = math.cos(q6), math.sin(q6)
    a = q4 + q5
    ca, sa = math.cos(a), math.sin(a)
    # M = R Rx(-q6) Ry(-(q4 + q5)): the entries the hip's Z-X-Y angles need
    t22 = R21 * s6 + R22 * c6                  # (R Rx(-q6))[2, 2]
    M01, M11, M21 = R01 * c6 - R02 * s6, R11 * c6 - R12 * s6, R21 * c6 - R22 * s6
    M20, M22 = R20 * ca + t22 * sa, -R20 * sa + t22 * ca
    q2 = math.asin(min(max(M21, -1.0), 1.0))
    q1 = math.atan2(-M01, M11)
    q3 = math.atan2(-M20, M22)
    return np.array([q1, q2, q3, q4, q5, q6])


#: the walking crouch: the hips at this share of the straight leg's hip height over the soles (ours)
CROUCH = 0.85


def crouch_angles(leg, joint_map: Mapping[str, tuple[str, int]], crouch: float = CROUCH) -> dict[str, float]:
    """The robot's joint name -> angle [rad] of both legs bent by the IK so the hips stand ``crouch``
    x the straight hip height over the soles (a walking posture), through the map's signs (its
    ``joint_map``: our name -> (their name, sign)). The robot's load, init's sizes and placo's first
    solve start from it."""
    out = {}
    for side, prefix in ((1, "l_"), (-1, "r_")):
        target = leg.hip_in_pelvis(side) + np.array([0.0, 0.0, -crouch * leg.max_hip_height])
        q = leg_ik(target, 0.0, leg, side)
        for name, value in zip(LEG_JOINTS, q):
            theirs, sign = joint_map[prefix + name]
            out[theirs] = sign * float(value)
    return out
