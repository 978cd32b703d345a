"""What the servos give way by, put back into their targets (ours).

A position servo holds a load by leaving an error: its torque is kp (target - angle) less its
velocity terms (kv, back-EMF, the joint's viscous friction: ``damping`` here, all N m s/rad). A
soft servo gives way far: Bit-Bots' Wolfgang-OP trained its walks on kp 21 N m/rad with 1.7 N m
s/rad of joint damping, where the stance knee carrying 4 N m sags 11 deg and a target lags the
joint by damping / kp = 81 ms. A learned walk learns these errors; the engine plans the angles it
wants, so it asks for them less the errors it can predict:

- **the load**: the ground carries the robot's weight, a vertical force at the plan's ZMP (in
  double support shared by where the ZMP lies between the soles), and each leg's thigh and calf
  hang from it (the gait's masses, at the middle of the thigh and of the shank: ours). With the
  pelvis as the leg's base the joints feel tau_ext = J^T [f; m] for the ground (J the sole's 6 x 6
  Jacobian, f and m the ground's force and moment about the sole point, in the pelvis frame) plus
  each link's weight through its point's Jacobian; the servo must give -tau_ext, so its target
  moves by -tau_ext / kp (``load_share`` of it);
- **the lag**: a target moving at qdot_ref leaves the servo's velocity terms b qdot_ref behind;
  the target leads by (b / kp) qdot_ref (``lag_share`` of it);
- each joint's offset is bounded by what its servo can give: |kp offset| <= its torque.

Static and quasi-static: the body's accelerations are left out. Pure numpy; the chain is the robot file's (``gaits.leg_chain``),
or the ideal leg's for the closed-form legs (the same kinematics, tested).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..leg_chain import LegChain, ideal_chain
from ..trajectory import GRAVITY, JOINT_NAMES

__all__ = ["ServoTerms", "servo_terms", "LoadCompensation"]

_LEGS = {1: slice(JOINT_NAMES.index("l_hip_yaw"), JOINT_NAMES.index("l_hip_yaw") + 6),
         -1: slice(JOINT_NAMES.index("r_hip_yaw"), JOINT_NAMES.index("r_hip_yaw") + 6)}


@dataclass(frozen=True)
class ServoTerms:
    """Per joint (``JOINT_NAMES`` order): the position gain kp [N m/rad], the velocity terms b
    [N m s/rad] and the most torque [N m]; 0 where the robot does not state a servo."""

    kp: np.ndarray
    damping: np.ndarray
    torque: np.ndarray


def servo_terms(robot) -> ServoTerms | None:
    """The servos' terms of a robot file (each joint's ``kp``, ``damping``, ``torque``) or of a
    simulator's robot (``joint_map`` and ``servos``: each a servo law's pieces); None when the robot
    states no position gains."""
    n = len(JOINT_NAMES)
    kp, b, tau = np.zeros(n), np.zeros(n), np.zeros(n)
    joints = getattr(robot, "joints", None)
    if hasattr(joints, "items") and joints and hasattr(next(iter(joints.values())), "kp"):
        for ours, j in joints.items():
            i = JOINT_NAMES.index(ours)
            kp[i], b[i], tau[i] = float(j.kp), float(j.damping), float(j.torque)
    else:
        jmap, servos = getattr(robot, "joint_map", None), getattr(robot, "servos", None)
        if not jmap or not servos:
            return None
        for ours, (theirs, _) in jmap.items():
            if theirs in servos:
                p = servos[theirs].pieces()
                i = JOINT_NAMES.index(ours)
                kp[i], b[i], tau[i] = p.kp, p.kv + p.back_emf + p.damping, p.torque
    if not np.any(kp > 0):
        return None
    return ServoTerms(kp, b, tau)


class LoadCompensation:
    """The targets' offsets for the load and the lag (module docstring)."""

    def __init__(self, leg, terms: ServoTerms, dt: float, load_share: float, lag_share: float,
                 link_masses: tuple[float, float] = (0.0, 0.0)) -> None:
        self.leg = leg
        self.link_masses = (float(link_masses[0]), float(link_masses[1]))     # thigh, calf [kg]
        self.terms = terms
        self.dt = float(dt)
        self.load_share = float(load_share)
        self.lag_share = float(lag_share)
        self.chains: dict[int, LegChain] = {s: (leg.chains.side(s) if leg.chains is not None else ideal_chain(leg, s))
                                            for s in (1, -1)}
        # [rad/N m] 1 / kp, 0 where no gain is stated (no offset there)
        self._compliance = np.divide(1.0, terms.kp, out=np.zeros_like(terms.kp), where=terms.kp > 0)
        self._bound = terms.torque * self._compliance
        self._lead = terms.damping * self._compliance          # [s] each servo's lag, damping / kp
        self._last: np.ndarray | None = None

    def reset(self) -> None:
        self._last = None

    def leg_torques(self, q_leg: np.ndarray, side: int, force_w: float, cop_w: np.ndarray,
                    sole_w: np.ndarray, R_wp: np.ndarray) -> np.ndarray:
        """The torques (6,) on the leg's joints (tau_ext, our joint order): a vertical ground force
        ``force_w`` [N] at ``cop_w`` (3,), the sole point at ``sole_w`` (3,), and the thigh's and
        calf's weight, the pelvis turned ``R_wp`` (world from pelvis)."""
        (px, py, pz), _, axes, pts = self.chains[side].chain_floats(q_leg)
        ux_, uy_, uz_ = R_wp[2, 0], R_wp[2, 1], R_wp[2, 2]     # the world's up in the pelvis frame
        tau = [0.0] * 6
        if force_w:
            fx, fy, fz = force_w * ux_, force_w * uy_, force_w * uz_
            # the moment about the sole point: (cop - sole) x (0, 0, F) in the world, into the pelvis frame
            rx, ry = float(cop_w[0]) - float(sole_w[0]), float(cop_w[1]) - float(sole_w[1])
            mwx, mwy = ry * force_w, -rx * force_w
            mx = R_wp[0, 0] * mwx + R_wp[1, 0] * mwy
            my = R_wp[0, 1] * mwx + R_wp[1, 1] * mwy
            mz = R_wp[0, 2] * mwx + R_wp[1, 2] * mwy
            for i, ((ux, uy, uz), (ax, ay, az)) in enumerate(zip(axes, pts)):
                dx, dy, dz = px - ax, py - ay, pz - az    # the sole's velocity per unit rate of joint i: u x d
                tau[i] = ((uy * dz - uz * dy) * fx + (uz * dx - ux * dz) * fy + (ux * dy - uy * dx) * fz
                          + ux * mx + uy * my + uz * mz)
        hip, knee, ankle = pts[2], pts[3], pts[4]
        for mass, a, b, n in ((self.link_masses[0], hip, knee, 3), (self.link_masses[1], knee, ankle, 4)):
            if mass > 0.0:                          # the joints above the link: the hip's three (and the knee)
                w = -mass * GRAVITY
                cx, cy, cz = (a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2
                for i in range(n):
                    (ux, uy, uz), (ax, ay, az) = axes[i], pts[i]
                    dx, dy, dz = cx - ax, cy - ay, cz - az
                    tau[i] += w * ((uy * dz - uz * dy) * ux_ + (uz * dx - ux * dz) * uy_ + (ux * dy - uy * dx) * uz_)
        return np.array(tau)

    def offsets(self, q: np.ndarray, feet: dict, soles: dict, zmp: np.ndarray, support: int, weight: float,
                R_wp: np.ndarray, foot_size: tuple[float, float]) -> np.ndarray:
        """(20,) what to add to the targets ``q`` this tick; ``weight`` [N] the whole robot's. ``feet``:
        each side's sole centre in the world (x, y, yaw[, z]); ``soles``: each side's sole point (3,)
        in the world (the chain's point below the ankle); ``support``: the side in single support (0:
        both, or standing)."""
        out = np.zeros(len(JOINT_NAMES))
        if self.load_share > 0.0 and weight > 0.0:
            shares = self._shares(feet, zmp, support)
            zx, zy = float(zmp[0]), float(zmp[1])
            hx, hy = foot_size[0] / 2, foot_size[1] / 2
            for side, share in shares.items():
                fx, fy, yaw = float(feet[side][0]), float(feet[side][1]), float(feet[side][2])
                fz = float(feet[side][3]) if len(feet[side]) > 3 else 0.0
                c, s = math.cos(yaw), math.sin(yaw)
                # the ZMP in the sole's axes, clipped to the sole: the centre of pressure of this foot
                lx = min(max(c * (zx - fx) + s * (zy - fy), -hx), hx)
                ly = min(max(-s * (zx - fx) + c * (zy - fy), -hy), hy)
                cop = (fx + c * lx - s * ly, fy + s * lx + c * ly, fz)
                tau = self.leg_torques(q[_LEGS[side]], side, share * weight, cop, soles[side], R_wp)
                out[_LEGS[side]] = -self.load_share * tau * self._compliance[_LEGS[side]]
        if self.lag_share > 0.0 and self._last is not None:
            out += (self.lag_share / self.dt) * self._lead * (q - self._last)
        self._last = np.array(q, dtype=float)
        return np.clip(out, -self._bound, self._bound)

    @staticmethod
    def _shares(feet: dict, zmp: np.ndarray, support: int) -> dict[int, float]:
        """Each sole's share of the weight: all on the support foot in single support; in double
        support by where the ZMP lies on the line between the soles' centres."""
        if support:
            return {support: 1.0, -support: 0.0}
        ax, ay, bx, by = float(feet[1][0]), float(feet[1][1]), float(feet[-1][0]), float(feet[-1][1])
        dx, dy = ax - bx, ay - by
        n = dx * dx + dy * dy
        left = 0.5 if n < 1e-12 else min(max(((float(zmp[0]) - bx) * dx + (float(zmp[1]) - by) * dy) / n, 0.0), 1.0)
        return {1: left, -1: 1.0 - left}
