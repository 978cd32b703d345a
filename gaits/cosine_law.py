"""Cosine-law (triangle) walking diagram of a 5-DoF-per-leg biped.

Setiono et al., bipedal robot walking diagram, Mechatronics, Electrical Power,
and Vehicular Technology 03 (2012) 103-110. Equation numbers are the paper's;
the OCR leaves eqs 1-34 partly unreadable, and Tables 1-3 are the clearest
statement of what the paper computes. What we reconstructed from them:

Motions (Sec. II). A motion lasts t_f (4 s in the paper) and has two halves.
In each, one leg is "tilted" (its foot stays behind the hip by the step
distance S(t)) and the other is "vertical" (its foot under the hip).
First half: the tilted leg supports while the hip moves forward by S and the
vertical leg comes down (full, ending) or makes a small lift (starting).
Second half: the vertical leg supports, the hip stays, and the tilted leg
swings forward under it, lifted (starting, full) or with a half-height bump
(ending). The starting motion begins and the ending motion ends standing; a
full motion swaps the legs' roles and repeats.

Profiles (eqs 24-34), linear in time:
* hip height (eqs 26-27): Hh(t) falls by h over the first half and rises back;
* step distance (eqs 28-29): S(t) rises from 0 to S and falls back;
* swing height h(t) (eqs 30-34): starting motion, vertical leg: up to h/2 at
  t_f/4 and down at t_f/2; tilted leg in starting and full motions: 0 -> h over
  the second half (eq 32); vertical leg in full and ending motions: h -> 0 over
  the first half (eq 33); tilted leg in the ending motion: up to h/2 at 3t_f/4
  and down (eq 34).
* angle between the reference lines (eq 5): theta_T = atan(S(t) / Hh(t)).
  With S = 40 mm and Hh = 230 -> 180 mm this gives the tables' 2.6, 5.6, 8.9,
  12.5 deg.
* reference lines (eqs 6-15): tilted leg (Hh(t) - h(t)) / cos(theta_T),
  vertical leg Hh(t) - h(t).

Leg angles (eqs 1-4, 16-23): the triangle of thigh l1, shank l2 and the
reference line; A is its angle at the hip (opposite l2), C at the ankle
(opposite l1). Tables 1-3 are reproduced (max 0.11 deg, rms 0.04 deg) by
hip = A - theta_T (tilted leg, 0 for the vertical one), knee = hip + C
(eq 22), ankle = -(knee - hip) (eq 20), mirrored in sign for the second leg
(eqs 16, 21, 23), *if* the triangle side is the reference line minus 118 mm and
l1 = 59.98 mm, l2 = 77.67 mm (:data:`SETIONO_TABLE_FIT`, fitted to all 162 table
angles, 3 tables x 9 rows x 6 angle columns; see ``tests/test_cosine_law.py``).
The paper's robot has a 380 mm leg, so these are not its link lengths: the
tables are not consistent with a plain triangle of the real leg, and the fit is
the reading that reproduces them. What the fit identifies: l2 / l1 = 1.295, the
118 mm offset and (measured, against a claim that only the ratio matters) the
common scale too: links x0.9 or x1.2 with the offset re-fitted leave 1.8 / 2.6
deg rms. What it contradicts: a triangle of these links spans hip heights of
only 120 mm from folded to straight, where the paper's robot goes from 380 mm
(straight) to 220 mm (squat); and with the tables' own angles its tilted leg
puts the foot 4.7 mm from under the hip where S is 40 mm. So the tables'
angles are a consistent triangle computation, but not of a leg that takes the
paper's steps; the robot joint table below uses the real leg's geometry.
Table 3 lists the ending motion's second half without the eq 34 bump; our
generator follows the text (eq 34) and the test reports that difference.

In the paper's tilted leg the knee column carries -theta_T and the ankle none,
so the joint angles do not keep the foot flat with the foot exactly S behind.
The robot joint table therefore uses the same triangle consistently
(:func:`triangle_leg_angles`: hip pitch theta_T - A, knee A + C, ankle
-(theta_T + C)) on the feet's Cartesian positions, which is the EROS leg IK
with zero roll and yaw (tested equal). The rolls stay at zero, as in the paper
("the roll movement is assumed to be static"), and so does the hip yaw the
5-DoF leg does not have.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .footstep_planner import PlanError, StepLimits
from .leg_kinematics import LegGeometry
from .params import GaitParams, ParamError, param
from .trajectory import GaitTrajectory, assemble

__all__ = [
    "CosineLawParams",
    "SETIONO_TABLE_FIT",
    "MotionSample",
    "motion_profiles",
    "paper_leg_angles",
    "triangle_leg_angles",
    "walk_schedule",
    "command_steps",
    "step_period",
    "step_starts",
    "generate",
]

#: (l1, l2, offset) [m] that make the paper's triangle reproduce its Tables 1-3.
SETIONO_TABLE_FIT = (0.059978, 0.077668, 0.118077)


@dataclass(frozen=True)
class CosineLawParams(GaitParams):
    """Cosine-law walker parameters (SI). Defaults: the paper's Figs 6-10 and Tables 1-3."""

    FAMILY = "cosine"
    hip_height: float = param(0.230, "m", 0.12, 0.30, "hip height standing (sole to hip joint)", "Hh")
    swing_height: float = param(0.050, "m", 0.0, 0.10, "height of the swinging leg; the hip also "
                                "dips by it", "h")
    step: float = param(0.040, "m", -0.08, 0.08, "step distance between the feet at mid-motion", "S")
    motion_time: float = param(4.0, "s", 0.2, 20.0, "duration of one motion", "t_f")
    n_full: int = param(2, "-", 0, 500, "number of full motions between starting and ending")
    first_swing: str = param("right", "-", doc="leg that lifts first (the paper's red leg)",
                             choices=("left", "right"))
    stance_width: float = param(0.074, "m", 0.04, 0.20, "lateral distance between the sole centres")
    t_start: float = param(0.5, "s", 0.0, 10.0, "standing time before the walk (ours)")
    t_end: float = param(0.5, "s", 0.0, 10.0, "standing time after the walk (ours)")


@dataclass(frozen=True)
class MotionSample:
    """Profiles of one motion at local times t (all arrays of len(t), SI units)."""

    t: np.ndarray
    hip_height: np.ndarray      # Hh(t)
    step: np.ndarray            # S(t)
    theta_t: np.ndarray         # theta_T [rad]
    lift_tilted: np.ndarray     # h(t) of the tilted leg
    lift_vertical: np.ndarray   # h(t) of the vertical leg
    ref_tilted: np.ndarray      # reference line of the tilted leg
    ref_vertical: np.ndarray    # reference line of the vertical leg


def motion_profiles(kind: str, t: np.ndarray, p: CosineLawParams, step: float | None = None) -> MotionSample:
    """Hip height, step, swing heights and reference lines of one motion (eqs 5-15, 24-34).

    ``step`` [m] replaces ``p.step`` for this motion (a walk command's step, ours)."""
    if kind not in ("starting", "full", "ending"):
        raise ValueError(f"kind must be starting, full or ending, got {kind!r}")
    t = np.asarray(t, dtype=float)
    tf, h, Hh = p.motion_time, p.swing_height, p.hip_height
    S = p.step if step is None else float(step)
    half = tf / 2
    first = t <= half
    hip = np.where(first, Hh - h * t / half, (Hh - h) + h * (t - half) / half)   # eqs 26-27
    step = np.where(first, S * t / half, S - S * (t - half) / half)               # eqs 28-29
    rising = np.where(first, 0.0, h * (t - half) / half)                          # eq 32
    falling = np.where(first, h * (1.0 - t / half), 0.0)                          # eq 33
    if kind == "starting":
        q = tf / 4
        bump = np.where(t <= q, h * t / (2 * q), np.maximum(h / 2 - h * (t - q) / (2 * q), 0.0))
        vertical = np.where(first, bump, 0.0)                                     # eqs 30-31
        tilted = rising
    elif kind == "full":
        vertical, tilted = falling, rising
    else:
        q3 = 3 * tf / 4
        bump = np.where(t <= q3, h * (t - half) / (2 * (q3 - half)),
                        h / 2 - h * (t - q3) / (2 * (tf - q3)))
        vertical, tilted = falling, np.where(first, 0.0, np.maximum(bump, 0.0))   # eq 34
    theta = np.arctan2(step, hip)                                                 # eq 5
    return MotionSample(t, hip, step, theta, tilted, vertical,
                        (hip - tilted) / np.cos(theta), hip - vertical)


def paper_leg_angles(ref_line: np.ndarray, tilt: np.ndarray, l1: float, l2: float,
                     offset: float = 0.0) -> np.ndarray:
    """The paper's (hip, knee, ankle) angles of the first ("black") leg, eqs 16-22, shape (..., 3).

    Triangle side ``ref_line - offset``; hip = A - tilt, knee = hip + C (eq 22),
    ankle = -(knee - hip) (eq 20). The second leg's are the negatives
    (eqs 16, 21, 23). Raises ValueError if the triangle cannot close.
    """
    s = np.asarray(ref_line, dtype=float) - offset
    cos_a = (l1 ** 2 + s ** 2 - l2 ** 2) / (2 * l1 * s)
    cos_c = (l2 ** 2 + s ** 2 - l1 ** 2) / (2 * l2 * s)
    if np.any(np.abs(cos_a) > 1) or np.any(np.abs(cos_c) > 1) or np.any(s <= 0):
        raise ValueError(f"triangle of sides {l1:g}, {l2:g} m and reference line minus offset "
                         f"{np.min(s):g}..{np.max(s):g} m does not close")
    A, C = np.arccos(cos_a), np.arccos(cos_c)
    hip = A - np.asarray(tilt, dtype=float)
    knee = hip + C
    ankle = -(knee - hip)
    return np.stack([hip, knee, ankle], axis=-1)


def triangle_leg_angles(reach: np.ndarray, tilt: np.ndarray, l1: float, l2: float) -> np.ndarray:
    """Robot-convention sagittal angles (hip pitch, knee, ankle pitch) by the cosine law.

    ``reach`` is the hip-ankle distance and ``tilt`` the angle of the hip-ankle
    line behind the vertical (the ankle behind the hip for tilt > 0). Law of
    cosines (eqs 1-4): A at the hip, C at the ankle; hip pitch = tilt - A,
    knee = A + C, ankle pitch = -(tilt + C): the sole stays level.
    """
    r = np.asarray(reach, dtype=float)
    if np.any(r > l1 + l2) or np.any(r < abs(l1 - l2)):
        raise ValueError(f"hip-ankle distance {np.min(r):g}..{np.max(r):g} m outside "
                         f"[{abs(l1 - l2):g}, {l1 + l2:g}] m")
    A = np.arccos(np.clip((l1 ** 2 + r ** 2 - l2 ** 2) / (2 * l1 * r), -1, 1))
    C = np.arccos(np.clip((l2 ** 2 + r ** 2 - l1 ** 2) / (2 * l2 * r), -1, 1))
    tilt = np.asarray(tilt, dtype=float)
    return np.stack([tilt - A, A + C, -(tilt + C)], axis=-1)


def walk_schedule(p: CosineLawParams) -> list[tuple[str, int]]:
    """Motions in order with the side (+1 left, -1 right) of each one's vertical leg."""
    vertical = -1 if p.first_swing == "right" else 1
    out = [("starting", vertical)]
    for _ in range(p.n_full):
        vertical = -vertical
        out.append(("full", vertical))
    out.append(("ending", -vertical))
    return out


def step_period(p: CosineLawParams) -> float:
    """Duration of one step [s]: a motion, in which the hip advances by one step S."""
    return p.motion_time


def step_starts(p: CosineLawParams, n_steps: int) -> np.ndarray:
    """Start time [s] of each of ``n_steps`` motions, and the end of the last, shape (n_steps + 1,)."""
    return p.t_start + np.arange(n_steps + 1) * p.motion_time


def command_steps(p: CosineLawParams, commands: np.ndarray, limits: StepLimits) -> np.ndarray:
    """Signed step S [m] of each motion for per-step commands (n, 3) (ours): S = vx t_f.

    The paper's walker only goes straight: its 5-DoF leg has no hip yaw and its roll is
    static, so a sideways or turning command is rejected, as is a step beyond ``limits``
    (the front foot S ahead of the rear one at mid-motion) or a walk of fewer than two
    motions (a starting and an ending one). PlanError names the step.
    """
    cmd = np.asarray(commands, dtype=float)
    if cmd.ndim != 2 or cmd.shape[1] != 3 or len(cmd) < 2:
        raise PlanError(f"cosine: commands must have shape (n_steps, 3) with n_steps >= 2 "
                        f"(a starting and an ending motion), got {cmd.shape}")
    if not np.all(np.isfinite(cmd)):
        raise PlanError("commands must be finite")
    steps = cmd[:, 0] * p.motion_time
    for k, (vx, vy, wz) in enumerate(cmd):
        where = f"step {k} (command {vx:g},{vy:g},{wz:g})"
        if vy != 0.0 or wz != 0.0:
            raise PlanError(f"{where}: the cosine-law walker walks forward and backward only "
                            "(its 5-DoF leg has no hip yaw and the paper keeps the roll static)")
        if steps[k] > limits.max_forward + 1e-12:
            raise PlanError(f"{where}: puts the front foot {steps[k]:.3f} m ahead of the rear one, "
                            f"beyond max_forward = {limits.max_forward:.3f} m")
        if -steps[k] > limits.max_backward + 1e-12:
            raise PlanError(f"{where}: puts the rear foot {-steps[k]:.3f} m behind the front one, "
                            f"beyond max_backward = {limits.max_backward:.3f} m")
    return steps


def generate(p: CosineLawParams, leg: LegGeometry = LegGeometry(), dt: float = 0.01,
             commands: np.ndarray | None = None, limits: StepLimits | None = None) -> GaitTrajectory:
    """The whole walk (starting, n_full full motions, ending) as a joint table every ``dt``.

    With ``commands`` (n, 3) (ours) the walk has n motions, the first a starting and the
    last an ending one, and motion k steps S_k = vx_k t_f (:func:`command_steps`);
    ``n_full`` and ``step`` are then unused.
    """
    if not (1e-4 <= dt <= 0.1):
        raise ParamError(f"dt = {dt!r} s is out of range [0.0001, 0.1] s")
    schedule = walk_schedule(p)
    steps = np.full(len(schedule), p.step)
    if commands is not None:
        steps = command_steps(p, commands, limits or StepLimits())
        schedule = walk_schedule(p.replace(n_full=len(steps) - 2))
    total = p.t_start + len(schedule) * p.motion_time + p.t_end
    t = np.arange(int(round(total / dt)) + 1) * dt
    n = len(t)
    hip_x = np.zeros(n)
    hip_z = np.full(n, p.hip_height)
    foot = {1: np.zeros((n, 3)), -1: np.zeros((n, 3))}
    support = np.zeros(n, dtype=int)
    x_hip = 0.0
    s_all = t - p.t_start
    for k, (kind, vertical) in enumerate(schedule):
        tilted = -vertical
        S = float(steps[k])
        lo = k * p.motion_time
        mask = (s_all >= lo) & (s_all < lo + p.motion_time)
        ms = motion_profiles(kind, s_all[mask] - lo, p, S)
        first = ms.t <= p.motion_time / 2
        # first half: the hip (and the vertical foot under it) moves by S(t) from the
        # tilted foot; second half: the hip holds and the tilted foot catches up.
        hx = np.where(first, x_hip + ms.step, x_hip + S)
        hip_x[mask] = hx
        hip_z[mask] = ms.hip_height
        foot[vertical][mask, 0] = hx
        foot[vertical][mask, 2] = ms.lift_vertical
        foot[tilted][mask, 0] = hx - ms.step
        foot[tilted][mask, 2] = ms.lift_tilted
        support[mask] = np.where(first, tilted, vertical)
        x_hip += S
        after = s_all >= lo + p.motion_time
        hip_x[after] = x_hip
        hip_z[after] = p.hip_height
        for side in (1, -1):
            foot[side][after, 0] = x_hip
            foot[side][after, 2] = 0.0
    half = p.stance_width / 2
    foot[1][:, 1] = half
    foot[-1][:, 1] = -half
    support = np.where((foot[1][:, 2] > 0) | (foot[-1][:, 2] > 0), support, 0)
    pelvis = np.column_stack([hip_x, np.zeros(n), hip_z + leg.hip_offset_z])
    meta = {"schedule": [k for k, _ in schedule], "cycle_time": 2 * p.motion_time}
    if commands is not None:
        meta["commands"] = np.asarray(commands, dtype=float).tolist()
    return assemble("cosine", t, leg, p_world_pelvis=pelvis, p_world_foot_l=foot[1],
                    p_world_foot_r=foot[-1], support=support, meta=meta)
