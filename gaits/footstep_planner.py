"""Footsteps for a walk command: one support pose and one swing target per step (ours).

The papers walk straight ahead: TLIPFM puts its support feet at p^c_n = (n S_L,
+-S_W) (eqs 6-8). We generalise the same scheme to a command (vx, vy, wz) per step
n, held for one step period T:

* The *mid frame* of step n is the support foot's pose moved half the stance width
  toward the swing side: M_n = F_n o Trans(0, s W), with s = +1 if the left foot
  swings, -1 if the right does, and W the half stance width.
* The swing foot lands at M_n o Trans(vx T, dy) o Rot(dtheta) o Trans(0, s W).
  Forward, the foot lands vx T ahead of the support foot, which is the paper's
  S_L = vx T (a constant command reproduces eqs 6-8 exactly, tested).
* Sideways and turning open before they close: a foot steps out by dy = 2 vy T,
  or turns by dtheta = 2 wz T, only when it is the foot on the side of the motion
  (s vy > 0, s wz > 0); the other foot then steps back to the nominal stance.
  The mean velocity over a cycle is the command, and the feet never come closer
  than the nominal stance, the scheme of most RoboCup walk engines.

Every step is checked against :class:`StepLimits` (forward, backward, outward
and turning reach of one step, and the gap between the two soles, with the soles
as rectangles, along the whole swing), and a plan that breaks one is rejected
with a :class:`PlanError` naming the step, the foot and the limit.

Poses are (x [m], y [m], yaw [rad]) in the world frame, x forward at the start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import ParamError

__all__ = ["StepLimits", "FootstepPlan", "PlanError", "plan_footsteps", "compose", "relative",
           "sole_gap", "swing_fraction"]


class PlanError(ParamError):
    """A command cannot be walked: the message names the step, the foot and the limit."""


@dataclass(frozen=True)
class StepLimits:
    """What one step may do, in the support foot's frame (ours; defaults for the kid-size robot)."""

    max_forward: float = 0.10      # [m] swing foot ahead of the support foot
    max_backward: float = 0.07     # [m] swing foot behind the support foot
    max_outward: float = 0.06      # [m] stance widening of one outward side step
    max_turn: float = 0.6          # [rad] foot turned against the support foot
    min_gap: float = 0.01          # [m] closest distance between the two soles, whole swing
    sole_length: float = 0.10      # [m] sole rectangle used for the gap
    sole_width: float = 0.055      # [m]

    def __post_init__(self) -> None:
        for name, lo, hi in (("max_forward", 0.0, 0.5), ("max_backward", 0.0, 0.5),
                             ("max_outward", 0.0, 0.3), ("max_turn", 0.0, 1.6),
                             ("min_gap", 0.0, 0.1), ("sole_length", 0.01, 0.5),
                             ("sole_width", 0.01, 0.3)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
                raise ParamError(f"step limit {name} = {v!r} is out of range [{lo:g}, {hi:g}]")


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Planar pose composition a o b, poses (x, y, yaw) of shape (3,)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose of b in a's frame: a^-1 o b."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, b[2] - a[2]])


def _rectangle(pose, length: float, width: float) -> list[tuple[float, float]]:
    """A sole's corners in order (world x, y) [m], as plain floats: the planner asks for 32 distances
    a swing sample, and numpy's per-call cost on 2-vectors there was 8 % of the time of five test
    files that walk (12.7 of 160 s, profiled)."""
    x, y, yaw = float(pose[0]), float(pose[1]), float(pose[2])
    c, s = math.cos(yaw), math.sin(yaw)
    out = []
    for sx, sy in ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)):
        u, v = sx * length / 2, sy * width / 2
        out.append((x + u * c - v * s, y + u * s + v * c))
    return out


def _segment_point_distance(p, a, b) -> float:
    """Distance from point p to segment ab (2-D, plain floats) [m]."""
    abx, aby = b[0] - a[0], b[1] - a[1]
    u = ((p[0] - a[0]) * abx + (p[1] - a[1]) * aby) / max(abx * abx + aby * aby, 1e-18)
    u = min(max(u, 0.0), 1.0)
    return math.hypot(p[0] - (a[0] + u * abx), p[1] - (a[1] + u * aby))


def _overlap(P, Q) -> bool:
    """Separating-axis test for two convex polygons (vertices in order)."""
    for poly in (P, Q):
        for i in range(len(poly)):
            (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % len(poly)]
            nx, ny = y0 - y1, x1 - x0
            a = [px * nx + py * ny for px, py in P]
            b = [qx * nx + qy * ny for qx, qy in Q]
            if max(a) < min(b) or max(b) < min(a):
                return False
    return True


def sole_gap(pose_a: np.ndarray, pose_b: np.ndarray, length: float, width: float) -> float:
    """Closest distance between two sole rectangles [m]; 0 when they overlap."""
    P, Q = _rectangle(pose_a, length, width), _rectangle(pose_b, length, width)
    if _overlap(P, Q):
        return 0.0
    d = math.inf
    for X, Y in ((P, Q), (Q, P)):
        for p in X:
            for i in range(len(Y)):
                d = min(d, _segment_point_distance(p, Y[i], Y[(i + 1) % len(Y)]))
    return d


def swing_fraction(theta: np.ndarray) -> np.ndarray:
    """Share of the swing travelled at cycloid phase theta in [0, 2 pi] (eq 27's F_x / Amp)."""
    theta = np.asarray(theta, dtype=float)
    return (theta - np.sin(theta)) / (2.0 * np.pi)


@dataclass(frozen=True)
class FootstepPlan:
    """Per step n: the support foot, and where the swing foot comes from and lands (world poses)."""

    period: float                 # [s] one step
    commands: np.ndarray          # (n, 3) (vx [m/s], vy [m/s], wz [rad/s])
    support_side: np.ndarray      # (n,) +1 left foot supports, -1 right
    support: np.ndarray           # (n, 3) support foot pose
    swing_start: np.ndarray       # (n, 3)
    swing_target: np.ndarray      # (n, 3)
    start_left: np.ndarray        # (3,) feet before the first step
    start_right: np.ndarray       # (3,)

    @property
    def n_steps(self) -> int:
        return len(self.commands)


def plan_footsteps(commands: np.ndarray, period: float, half_width: float, first_support: int = -1,
                   limits: StepLimits = StepLimits(), *, swing_samples: int = 9) -> FootstepPlan:
    """Footsteps for per-step commands (n, 3), the feet starting side by side at (0, +-W, 0).

    ``first_support`` = -1: the right foot supports the first step (the left foot moves first),
    as the TLIPFM parameter of the same name. Raises :class:`PlanError` for the first step
    that breaks a limit.
    """
    cmd = np.asarray(commands, dtype=float)
    if cmd.ndim != 2 or cmd.shape[1] != 3 or len(cmd) < 1:
        raise PlanError(f"commands must have shape (n_steps, 3) with n_steps >= 1, got {cmd.shape}")
    if not np.all(np.isfinite(cmd)):
        raise PlanError("commands must be finite")
    if first_support not in (-1, 1):
        raise PlanError(f"first_support must be -1 or +1, got {first_support!r}")
    W, T = float(half_width), float(period)
    feet = {+1: np.array([0.0, W, 0.0]), -1: np.array([0.0, -W, 0.0])}
    start_l, start_r = feet[1].copy(), feet[-1].copy()
    n = len(cmd)
    sides = np.empty(n, dtype=int)
    sup = np.empty((n, 3))
    s0 = np.empty((n, 3))
    s1 = np.empty((n, 3))
    sigma = first_support
    fr = swing_fraction(np.linspace(0.0, 2.0 * np.pi, swing_samples))
    for k in range(n):
        vx, vy, wz = cmd[k]
        s = -sigma                                        # the swing side
        F = feet[sigma]
        mid = compose(F, np.array([0.0, s * W, 0.0]))
        dy = 2.0 * vy * T if s * vy > 0 else 0.0
        dth = 2.0 * wz * T if s * wz > 0 else 0.0
        target = compose(compose(compose(mid, np.array([vx * T, dy, 0.0])), np.array([0.0, 0.0, dth])),
                         np.array([0.0, s * W, 0.0]))
        foot = "left" if s == 1 else "right"
        where = f"step {k} ({foot} foot, command {vx:g},{vy:g},{wz:g})"
        rel = relative(F, target)
        if rel[0] > limits.max_forward + 1e-12:
            raise PlanError(f"{where}: lands {rel[0]:.3f} m ahead of the support foot, "
                            f"beyond max_forward = {limits.max_forward:.3f} m")
        if -rel[0] > limits.max_backward + 1e-12:
            raise PlanError(f"{where}: lands {-rel[0]:.3f} m behind the support foot, "
                            f"beyond max_backward = {limits.max_backward:.3f} m")
        widen = s * rel[1] - 2.0 * W
        if widen > limits.max_outward + 1e-12:
            raise PlanError(f"{where}: widens the stance by {widen:.3f} m, "
                            f"beyond max_outward = {limits.max_outward:.3f} m")
        if abs(rel[2]) > limits.max_turn + 1e-12:
            raise PlanError(f"{where}: turns the foot {abs(rel[2]):.3f} rad against the support "
                            f"foot, beyond max_turn = {limits.max_turn:.3f} rad")
        start = feet[s]
        for f in fr:
            pose = start + f * (target - start)
            gap = sole_gap(F, pose, limits.sole_length, limits.sole_width)
            if gap < limits.min_gap - 1e-12:
                raise PlanError(f"{where}: the soles come {gap * 1000:.2f} mm apart during the swing, "
                                f"closer than min_gap = {limits.min_gap * 1000:.2f} mm")
        sides[k], sup[k], s0[k], s1[k] = sigma, F, start, target
        feet[s] = target
        sigma = s
    return FootstepPlan(period=T, commands=cmd, support_side=sides, support=sup, swing_start=s0,
                        swing_target=s1, start_left=start_l, start_right=start_r)
