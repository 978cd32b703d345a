"""EROS quarter-circle walking trajectory with heel-strike gait and landing deceleration.

Pristovani, Wijayanto, Alasiry, Khalilullah, *Walking Trajectory Optimization
Algorithm for Robot Humanoid on Synthetic Grass* (EROS robot). Equation numbers
are the paper's.

The walk is a chain of transitions between via points PP_i, four per cycle
(Sec. 4.2 A): SSP->DSP of the right leg (its landing), DSP->SSP of the left leg
(its lift-off), SSP->DSP of the left leg, DSP->SSP of the right leg. Within a
transition every coordinate moves from PP_i to PP_i+1 along a quarter circle in
the angle domain: the input T_T runs from 0 to 90 deg in increments of T_mn,
one increment per controller tick (T_T(i) = T_T(i-1) + T_mn), and

* X (eqs 37, 41):              X = (1 - cos T_T) dS_x + PP_x
* Y, Z on lift-offs (38, 42):  (Y, Z) = sin(T_T) dS + PP
* Y, Z on landings (39, 43):   (Y, Z) = (1 - cos T_T) dS + PP

(eq 39 is printed ``1 - sin(T_T + T_mn) + 90``; the reading that makes sense is
``1 - sin(T_T + 90 deg)`` = ``1 - cos T_T``.) A lift-off therefore rises fast
and ends slowly at the apex (a quarter circle in the x-z plane), and a landing
leaves the apex slowly and meets the ground at its highest speed, toe first:
the failure the paper sees on synthetic grass.

Our reading of the paper's inputs X, Y, Z (Sec. 5 gives (8, 45, 100),
(16, 35, 95) and (24, 25, 90) mm): X is the step length (each foot travels 2X
per stride, the body X per step); Y the lateral sway of the hip toward the
support foot; Z the swing-foot lift. Tables 7-8 label the step rows 0-24 "cm";
24 cm steps are impossible for a 52 cm robot whose legs are ~25 cm, while the
text's mm matches the inputs and the 2 cm steps of the similar TKU-X robot, so
we read mm. Z as a hip height would keep the knees bent ~125 deg under load all
the time; as a lift it needs that bend only in the unloaded swing leg and
clears 50 mm grass, so we read the lift. The paper gives no values for the hip
height, T_mn, C_H, C_DC, n or the controller tick: ours are in the parameter
defaults and ``gaits/baselines``.

Heel-strike gait (eqs 44-47). The ankle pitch gets offsets proportional to the
height difference of the two feet, dS_z = Z_swing - Z_support, taken at the
via point that ends the lift-off (push-off, alpha, eqs 44, 46) and at the one
that starts the landing (collision, beta, eqs 45, 47). The paper divides by a
gain C_H; we multiply by ``heel_gain`` [rad/m] (= 1/C_H), so that a zero gain
switches the offsets off. Per leg, over its own cycle: during the other leg's
landing it ramps 0 -> +alpha (toe down, push-off); during its own lift-off
+alpha -> -beta (toe up); it holds -beta through its landing so the heel meets
the ground first; during the other leg's lift-off it returns -beta -> 0 (foot
flat, loaded). Each ramp follows the transition's Y/Z profile.

Landing deceleration (eqs 48-49). The landing's x travel is divided into n
areas of equal length (eq 48, T_n = dS_x / n): area k spans T_T in
[acos(1 - (k-1)/n), acos(1 - k/n)]. Eq 49 as printed,
``T_mn,DC(n) = log(T_mn,DC(n-1) - C_DC) x T_mn``, is not dimensionally
meaningful (the log of an angle); the text says the increment falls in a
logarithmic rather than linear way as the foot nears the ground. We use
``T_mn,DC(k) = T_mn / (1 + C_DC ln(1 + k))`` in area k: C_DC = 0 is the plain
gait, and the landing lengthens monotonically with C_DC and with n.

Double-support phase (ours; ``double_support``, the share of each step with
both feet loaded). Read literally, eqs 37-39 chain the landing of one foot
straight into the lift-off of the other, and the hip sway (eq 39's 1 - cos back
to the midline, then eq 38's sin out to the other side) crosses the midline at
that very instant: both feet are down for single ticks only, and at lift-off the
CoM is still a sway amplitude away from the new stance sole, so the full-lift
walk falls sideways at once. The paper names a double-support phase and a
push-off "at the beginning of transition from DSP to SSP", which needs the rear
foot loaded for a while, but gives no duration. We insert one, centred on the
sway's midline crossing: each step is ``[DSP/2][lift][landing][DSP/2]``, the
feet stay still during the DSP halves, and the sway keeps the paper's shapes but
spans the whole step (sin from the midline to its apex over the first DSP half
and the lift-off, 1 - cos back over the landing and the second DSP half, at a
uniform angle rate), so the CoM is carried across to the new stance foot while
both feet are down. ``double_support = 0`` is the literal cycle, tick for tick.
The default 0.4 is the middle of the 35-45% band that walked at the paper's
full lift in an independent check (the issue tracker, issue 12); the stance
width that goes with it is set per experiment setting (``tuner`` reads it as
2Y + 5 mm, at least 65 mm).

Walk commands (ours; the paper walks straight ahead only). :func:`generate` takes
per-step commands (vx, vy, wz); the footsteps come from ``gaits/footstep_planner.py``
with the step period :func:`step_period`, and each step is the paper's lift-off and
landing pair of transitions toward the planned swing pose: the apex via point is halfway
in x, y and yaw, all horizontal coordinates follow eq 37's X profile, the lift and the
sway keep eqs 38-39, the sway is measured across the body's heading, and the hip-yaw
joints turn the feet. A constant forward command of ``step_x / step_period`` reproduces
the straight walk exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .footstep_planner import FootstepPlan, StepLimits, plan_footsteps
from .leg_kinematics import LegGeometry
from .params import GaitParams, ParamError, param
from .trajectory import GaitTrajectory, assemble, resample

__all__ = [
    "ErosParams",
    "Transition",
    "quarter_circle",
    "angle_steps",
    "decelerated_angle_steps",
    "dsp_ticks",
    "step_ticks",
    "step_period",
    "step_starts",
    "via_points",
    "eros_references",
    "generate",
]

# state vector of a via point: foot x (left, right), foot z (left, right), body x, body sway y
# (in the body's heading frame), then for walk commands foot y (left, right), foot yaw (left,
# right), body y and body yaw (the world pose of the midpoint the sway is measured from)
XL, XR, ZL, ZR, BX, BY, YL, YR, AL, AR, BW, BA = range(12)
#: Coordinates that follow eq 37's X profile: the paper's x, and (ours) every other horizontal
#: coordinate of a commanded step, so a side step or a turn moves like a forward step.
X_COORDS = (XL, XR, BX, YL, YR, AL, AR, BW, BA)
N_STATE = 12


@dataclass(frozen=True)
class ErosParams(GaitParams):
    """EROS walking-trajectory parameters (SI units). Defaults: the paper's 8 mm experiment, no optimisation."""

    FAMILY = "eros"
    step_x: float = param(0.008, "m", -0.06, 0.06, "step length; negative walks backward", "X")
    sway_y: float = param(0.045, "m", 0.0, 0.08, "lateral hip sway toward the support foot", "Y")
    foot_lift: float = param(0.100, "m", 0.0, 0.11, "swing-foot lift height", "Z")
    hip_height: float = param(0.230, "m", 0.12, 0.30, "sole to hip-joint centre while walking (ours)")
    stance_width: float = param(0.090, "m", 0.04, 0.20, "lateral distance between the sole centres (ours)")
    t_mn: float = param(math.radians(2.0), "rad", math.radians(0.25), math.radians(45.0),
                        "quarter-circle angle increment per controller tick", "T_mn")
    tick: float = param(0.01, "s", 0.001, 0.05, "controller tick: one T_mn increment (ours)")
    n_steps: int = param(8, "-", 2, 500, "number of steps (each swing is one step)")
    first_swing: str = param("left", "-", doc="leg that swings first", choices=("left", "right"))
    heel_strike: bool = param(False, "-", doc="heel-strike gait on (eqs 44-47)")
    heel_gain: float = param(2.0, "rad/m", 0.0, 10.0,
                             "ankle-pitch offset per metre of foot height difference", "1/C_H")
    landing_deceleration: bool = param(False, "-", doc="landing deceleration on (eqs 48-49)")
    c_dc: float = param(1.0, "-", 0.0, 10.0, "deceleration gain", "C_DC")
    n_areas: int = param(4, "-", 1, 20, "number of landing areas", "n")
    double_support: float = param(0.4, "-", 0.0, 0.6,
                                  "share of each step with both feet loaded, centred on the sway's "
                                  "midline crossing (ours; 0: the literal cycle)")
    t_start: float = param(0.5, "s", 0.0, 10.0, "standing time before the first step (ours)")
    t_end: float = param(0.5, "s", 0.0, 10.0, "standing time after the last step (ours)")

    def check_consistency(self) -> None:
        if self.sway_y > self.stance_width:
            raise ParamError(f"eros: sway_y = {self.sway_y:g} m carries the hip past the support "
                             f"foot; it must be at most stance_width = {self.stance_width:g} m")


@dataclass(frozen=True)
class Transition:
    """One quarter-circle transition between via points (indices into the tick timeline)."""

    kind: str          # "lift" (DSP->SSP, eqs 38/42), "land" (SSP->DSP, eqs 39/43), or a start/stop kind
    swing: int         # +1 left leg moves, -1 right leg
    start: np.ndarray  # (12,) via point PP_i: xl, xr, zl, zr, body x, sway y, yl, yr, yaw l, yaw r, body y, body yaw
    end: np.ndarray    # (12,) via point PP_i+1
    theta: np.ndarray  # (K,) T_T samples after the start, last = pi/2


#: Y/Z profile family of each transition kind: the paper's lift-off (eq 38) and landing
#: (eq 39) shapes, and a rest-to-rest raised cosine for our start/stop weight shifts.
PROFILE = {"lift": "lift", "post": "lift", "land": "land", "pre": "land",
           "shift": "rest", "return": "rest", "settle": "rest", "dsp": "rest"}


def quarter_circle(theta: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Profiles (X, Y/Z) in [0, 1] of eqs 37-39 for T_T = theta [rad]; exactly 1 at pi/2.

    ``kind`` "lift" gives eq 38's sin, "land" eq 39's 1 - cos, "rest" the raised
    cosine (1 - cos 2 T_T) / 2 of our start/stop shifts (zero speed at both ends).
    """
    theta = np.asarray(theta, dtype=float)
    x = 1.0 - np.cos(theta)
    if kind == "lift":
        yz = np.sin(theta)
    elif kind == "land":
        yz = 1.0 - np.cos(theta)
    elif kind == "rest":
        yz = (1.0 - np.cos(2.0 * theta)) / 2.0
    else:
        raise ValueError(f"profile kind must be lift, land or rest, got {kind!r}")
    end = theta >= np.pi / 2
    return np.where(end, 1.0, x), np.where(end, 1.0, yz)


def angle_steps(t_mn: float) -> np.ndarray:
    """T_T samples T_mn, 2 T_mn, ... of one transition; the last is exactly 90 deg."""
    k = int(math.ceil(round((math.pi / 2) / t_mn, 9)))
    theta = np.arange(1, k + 1) * t_mn
    theta[-1] = np.pi / 2
    return theta


def decelerated_angle_steps(t_mn: float, c_dc: float, n_areas: int) -> np.ndarray:
    """T_T samples of a decelerated landing (eqs 48-49 as read in the module docstring)."""
    bounds = np.arccos(1.0 - np.arange(1, n_areas + 1) / n_areas)   # area ends, equal x travel
    bounds[-1] = np.pi / 2
    out = []
    theta = 0.0
    while theta < np.pi / 2 - 1e-12:
        k = int(np.searchsorted(bounds, theta, side="right")) + 1     # 1-based area of theta
        k = min(k, n_areas)
        theta = min(theta + t_mn / (1.0 + c_dc * math.log(1.0 + k)), np.pi / 2)
        out.append(theta)
    out[-1] = np.pi / 2
    return np.array(out)


#: Stop lean after the last step with a double-support phase, as a share of the sway (ours).
STOP_LEAN = 0.25


def dsp_ticks(p: ErosParams) -> int:
    """Ticks of each half of the double-support phase: DSP / (DSP + lift + plain landing) = share."""
    if p.double_support <= 0.0:
        return 0
    ssp = 2 * len(angle_steps(p.t_mn))
    return max(1, int(round(p.double_support / (1.0 - p.double_support) * ssp / 2.0)))


def step_ticks(p: ErosParams) -> int:
    """Controller ticks of one step: its DSP halves, lift-off and (decelerated) landing."""
    landing = (decelerated_angle_steps(p.t_mn, p.c_dc, p.n_areas)
               if p.landing_deceleration else angle_steps(p.t_mn))
    return 2 * dsp_ticks(p) + len(angle_steps(p.t_mn)) + len(landing)


def step_period(p: ErosParams) -> float:
    """Duration of one step [s]: the T a walk command's step is planned with."""
    return step_ticks(p) * p.tick


def _sway_angles(p: ErosParams) -> np.ndarray:
    plain = angle_steps(p.t_mn)
    half = dsp_ticks(p)
    return plain if half == 0 else np.linspace(0.0, np.pi / 2, half + len(plain) + 1)[1:]


def step_starts(p: ErosParams, n_steps: int) -> np.ndarray:
    """Start time [s] of each of ``n_steps`` steps, and the end of the last, shape (n_steps + 1,).

    The steps follow the start-up shifts ("shift", "pre"); each begins with its first DSP half.
    """
    first = int(round(p.t_start / p.tick)) + 2 * len(_sway_angles(p))
    return (first + np.arange(n_steps + 1) * step_ticks(p)) * p.tick


def via_points(p: ErosParams, plan: FootstepPlan | None = None) -> list[Transition]:
    """The chain of transitions: start-up, the steps, stop, and a final settle.

    The paper's cycle makes the hip sway a smooth sinusoid (1 - cos on landings
    followed by sin on lift-offs), but starting it from rest with a lift-off would
    need an infinite sideways acceleration. The paper does not say how EROS
    starts; we start and stop the sway with transitions that move no foot:
    "shift" (rest to the swing side, raised cosine), "pre" (back to the centre,
    eq 39's shape, arriving at full sway speed), the steps, then "post" (eq 38's
    shape, to the last landed foot's side) and "return" (raised cosine to the
    centre). Those use the plain T_mn stepping, or with a double-support phase
    the sway's own (slower) angle rate, so the sway speed is continuous.

    With ``double_support > 0`` each step is framed by two "dsp" transitions of
    ``dsp_ticks(p)`` ticks that move no foot (their sway is set by
    :func:`eros_references`).

    Without ``plan`` the walk is the paper's: ``n_steps`` steps of ``step_x``
    straight ahead, the last one setting the swing foot beside the support foot.
    With a :class:`~gaits.footstep_planner.FootstepPlan` (a walk command, ours) each
    step's swing foot goes from where it stands to the plan's target pose (x, y,
    yaw): the apex via point is halfway in every horizontal coordinate, all of them
    follow eq 37's X profile, the lift and the sway are the paper's. The body's
    pose (the midpoint of the feet) moves like the paper's body x, and the sway
    is taken across the body's heading.
    """
    half_w = p.stance_width / 2
    state = np.zeros(N_STATE)
    state[YL], state[YR] = half_w, -half_w
    swing = 1 if p.first_swing == "left" else -1
    if plan is not None:
        if plan.n_steps < 1 or int(plan.support_side[0]) != -swing:
            raise ParamError(f"eros: the footstep plan must start with the "
                             f"{'right' if swing == 1 else 'left'} foot supporting "
                             f"(first_swing = {p.first_swing})")
        for side, start in ((1, plan.start_left), (-1, plan.start_right)):
            if not np.allclose(start, [0.0, side * half_w, 0.0], atol=1e-12):
                raise ParamError("eros: the footstep plan must start from the stance width "
                                 f"{p.stance_width:g} m, feet side by side at x = 0")
    n_steps = p.n_steps if plan is None else plan.n_steps
    plain = angle_steps(p.t_mn)
    landing = (decelerated_angle_steps(p.t_mn, p.c_dc, p.n_areas)
               if p.landing_deceleration else plain)
    half = dsp_ticks(p)
    sway = _sway_angles(p)
    chain: list[Transition] = []

    def hold(n: int, swing: int, at: np.ndarray) -> None:
        if n > 0:
            chain.append(Transition("dsp", swing, at, at.copy(), np.linspace(0.0, np.pi / 2, n + 1)[1:]))

    lean = state.copy()
    lean[BY] = swing * p.sway_y                 # toward the first swing foot, at rest
    chain.append(Transition("shift", 0, state, lean, sway))
    chain.append(Transition("pre", 0, lean, state.copy(), sway))
    for j in range(n_steps):
        xs, ys, as_, zs = (XL, YL, AL, ZL) if swing == 1 else (XR, YR, AR, ZR)
        xp, yp, ap = (XR, YR, AR) if swing == 1 else (XL, YL, AL)
        support = state[[xp, yp, ap]]
        if plan is None:
            last = j == n_steps - 1
            target = np.array([state[xp] + (0.0 if last else p.step_x), swing * half_w, 0.0])
        else:
            target = plan.swing_target[j]
            if int(plan.support_side[j]) != -swing:
                raise ParamError(f"eros: step {j} of the footstep plan does not alternate the feet")
        body_next = 0.5 * (target + support)
        apex = state.copy()
        apex[[xs, ys, as_]] = 0.5 * (state[[xs, ys, as_]] + target)
        apex[zs] = p.foot_lift
        apex[[BX, BW, BA]] = 0.5 * (state[[BX, BW, BA]] + body_next)
        apex[BY] = -swing * p.sway_y            # toward the support foot
        hold(half, swing, state)
        chain.append(Transition("lift", swing, state, apex, plain))
        down = apex.copy()
        down[[xs, ys, as_]] = target
        down[zs] = 0.0
        down[[BX, BW, BA]] = body_next
        down[BY] = 0.0
        chain.append(Transition("land", swing, apex, down, landing))
        hold(half, swing, down)
        state = down
        swing = -swing
    lean = state.copy()
    # toward the foot that landed last; with a double support the CoM crosses the midline
    # with both feet down, and a lean of a quarter of the sway, at the same speed, stops it
    # over the stance polygon (ours; a full sway tips the robot over that foot's edge)
    brake = 1.0 if half == 0 else STOP_LEAN
    lean[BY] = -swing * p.sway_y * brake
    post = sway if half == 0 else np.linspace(0.0, np.pi / 2, max(1, round(len(sway) * brake)) + 1)[1:]
    chain.append(Transition("post", 0, state, lean, post))
    chain.append(Transition("return", 0, lean, state.copy(), sway))
    chain.append(Transition("settle", 0, state, state.copy(), plain))
    return chain


def _heel_targets(p: ErosParams, chain: list[Transition]) -> list[tuple[float, float]]:
    """End values of the ankle-pitch offsets (left, right) after each transition (eqs 44-47)."""
    ends = []
    cur = {1: 0.0, -1: 0.0}
    steps = [tr for tr in chain if tr.kind != "dsp"]
    following = {id(a): b for a, b in zip(steps, steps[1:])}
    for tr in chain:
        if tr.kind == "dsp":                           # both feet down: offsets held
            ends.append((cur[1], cur[-1]))
            continue
        nxt = following.get(id(tr))
        for leg in (1, -1):
            if not p.heel_strike or tr.kind not in ("lift", "land"):
                cur[leg] = 0.0                         # start-up, stop and settle: feet flat
                continue
            zs = ZL if tr.swing == 1 else ZR
            zp = ZR if tr.swing == 1 else ZL
            if tr.kind == "lift" and tr.swing == leg:
                # eq 45/47: collision offset from dS'_z at the via point that starts the landing
                ds_collision = tr.end[zs] - tr.end[zp]
                cur[leg] = -p.heel_gain * ds_collision
            elif tr.kind == "land" and tr.swing == leg:
                pass                                   # hold: the heel meets the ground first
            elif tr.kind == "land" and tr.swing != leg:
                if nxt is not None and nxt.kind == "lift" and nxt.swing == leg:
                    # eq 44/46: push-off offset from dS_z at the via point that ends the lift-off
                    z_own, z_other = (ZL, ZR) if leg == 1 else (ZR, ZL)
                    ds_push = nxt.end[z_own] - nxt.end[z_other]
                    cur[leg] = p.heel_gain * ds_push
                else:
                    cur[leg] = 0.0
            elif tr.kind == "lift" and tr.swing != leg:
                cur[leg] = 0.0                         # foot flat again once loaded
        ends.append((cur[1], cur[-1]))
    return ends


@dataclass(frozen=True)
class ErosReferences:
    """World references on the controller's own tick timeline (before resampling)."""

    t: np.ndarray            # (K,) [s]
    state: np.ndarray        # (K, 12) the via-point coordinates (XL ... BA) [m, rad]
    ankle_offset: np.ndarray  # (K, 2) [rad] left, right
    support: np.ndarray      # (K,)
    via_ticks: np.ndarray    # tick index at which each via point is reached (first = 0)
    via_states: np.ndarray   # (len(chain) + 1, 12)
    transition_ticks: np.ndarray  # (len(chain),) ticks spent in each transition


def _spread_sway(state: np.ndarray, chain: list[Transition], via_ticks: np.ndarray, extra: int) -> None:
    """Sway over whole steps (double-support reading, module docstring), in place.

    Knots: the midline before the first step (end of "pre"), the sway apex at
    the end of each lift-off, the midline at the end of the last step. From the
    midline to an apex the sway follows eq 38's sin, from an apex to the midline
    eq 39's 1 - cos, and apex to apex the two joined (a half cosine, which is
    both at a uniform angle rate): the CoM crosses the midline halfway between
    apexes, in the middle of the double support. A decelerated landing (eqs
    48-49) is longer than the plain one by ``extra`` ticks: the sway waits at its
    apex for them, so the CoM leaves the stance foot as long before touchdown as
    without deceleration (ours: the literal cycle slows the sway with the foot,
    which with a double-support phase tips the robot toward the still-airborne
    foot). Rows of transition i are ``via_ticks[i] + 1 .. via_ticks[i + 1]``.
    """
    kinds = [tr.kind for tr in chain]
    lifts = [i for i, k in enumerate(kinds) if k == "lift"]
    start = via_ticks[kinds.index("pre") + 1]
    stop = via_ticks[kinds.index("post")]
    knots = [(start, 0.0)]
    for i in lifts:
        knots += [(via_ticks[i + 1], chain[i].end[BY]), (via_ticks[i + 1] + extra, chain[i].end[BY])]
    knots.append((stop, 0.0))
    for (t0, y0), (t1, y1) in zip(knots, knots[1:]):
        n = t1 - t0
        if n == 0:
            continue
        s = np.arange(1, n + 1) / n
        if y0 == y1:                                    # waiting at the apex
            y = np.full(n, y0)
        elif y0 == 0.0:                                 # midline -> apex: sin
            y = y1 * np.sin(s * np.pi / 2)
        elif y1 == 0.0:                                 # apex -> midline: 1 - cos
            y = y0 * np.cos(s * np.pi / 2)
        else:                                           # apex -> apex through the midline
            y = y0 * np.cos(s * np.pi)
        state[t0 + 1:t1 + 1, BY] = y


def eros_references(p: ErosParams, plan: FootstepPlan | None = None) -> ErosReferences:
    """Run the quarter-circle chain tick by tick (eqs 36-49); ``plan``: see :func:`via_points`."""
    chain = via_points(p, plan)
    heel_ends = _heel_targets(p, chain)
    n_start = int(round(p.t_start / p.tick))
    n_end = int(round(p.t_end / p.tick))
    states = [np.repeat(chain[0].start[None, :], n_start + 1, axis=0)]
    offsets = [np.zeros((n_start + 1, 2))]
    supports = [np.zeros(n_start + 1, dtype=int)]
    via_ticks = [n_start]
    via_states = [chain[0].start]
    spent = []
    off = np.zeros(2)
    tick = n_start
    for tr, heel_end in zip(chain, heel_ends):
        prof_x, prof_yz = quarter_circle(tr.theta, PROFILE[tr.kind])
        delta = tr.end - tr.start                               # eq 36
        seg = np.repeat(tr.start[None, :], len(tr.theta), axis=0)
        for c in range(N_STATE):
            prof = prof_x if c in X_COORDS else prof_yz
            seg[:, c] = tr.start[c] + prof * delta[c]
        seg[-1] = tr.end                                        # the via point, exactly
        new_off = np.asarray(heel_end)
        seg_off = off[None, :] + prof_yz[:, None] * (new_off - off)[None, :]
        seg_off[-1] = new_off
        off = new_off
        states.append(seg)
        offsets.append(seg_off)
        supports.append(np.full(len(tr.theta), -tr.swing if tr.kind in ("lift", "land") else 0,
                                dtype=int))
        tick += len(tr.theta)
        via_ticks.append(tick)
        via_states.append(tr.end)
        spent.append(len(tr.theta))
    states.append(np.repeat(chain[-1].end[None, :], n_end, axis=0))
    offsets.append(np.zeros((n_end, 2)))
    supports.append(np.zeros(n_end, dtype=int))
    state = np.concatenate(states)
    via_states = np.array(via_states)
    if dsp_ticks(p):
        kinds = [tr.kind for tr in chain]
        extra = len(chain[kinds.index("land")].theta) - len(chain[kinds.index("lift")].theta)
        _spread_sway(state, chain, np.array(via_ticks), extra)
        via_states[:, BY] = state[via_ticks, BY]     # DSP bounds lie inside a sway quarter
    t = np.arange(len(state)) * p.tick
    return ErosReferences(t, state, np.concatenate(offsets), np.concatenate(supports),
                          np.array(via_ticks), via_states, np.array(spent))


def generate(p: ErosParams, leg: LegGeometry = LegGeometry(), dt: float | None = None,
             commands: np.ndarray | None = None, limits: StepLimits | None = None) -> GaitTrajectory:
    """The EROS walk as a joint table sampled every ``dt`` (default: the controller tick).

    With ``commands`` (n, 3) (vx [m/s], vy [m/s], wz [rad/s] per step, ours; see
    ``gaits/walk_command.py``) the steps are those of ``gaits/footstep_planner.py`` for
    the step period :func:`step_period` (its checks against ``limits`` reject a step
    the feet cannot take), walked with the paper's via-point transitions
    (:func:`via_points`); ``n_steps`` and ``step_x`` are then unused. The pelvis
    heading is the body's (the mean of the feet's), the hip-yaw joints turn the feet.
    """
    dt = p.tick if dt is None else dt
    if not (1e-4 <= dt <= 0.1):
        raise ParamError(f"dt = {dt!r} s is out of range [0.0001, 0.1] s")
    plan = None
    if commands is not None:
        plan = plan_footsteps(commands, step_period(p), p.stance_width / 2,
                              -1 if p.first_swing == "left" else 1, limits or StepLimits())
    ref = eros_references(p, plan)
    if abs(dt - p.tick) < 1e-12:
        t, state, off, support = ref.t, ref.state, ref.ankle_offset, ref.support
    else:
        t = np.arange(int(math.floor(ref.t[-1] / dt + 1e-9)) + 1) * dt
        state = resample(ref.t, ref.state, t)
        off = resample(ref.t, ref.ankle_offset, t)
        idx = np.clip(np.searchsorted(ref.t, t, side="right") - 1, 0, len(ref.t) - 1)
        support = ref.support[idx]
    left = state[:, [XL, YL, ZL]]
    right = state[:, [XR, YR, ZR]]
    # the sway is across the body's heading (zero on the paper's straight walk)
    yaw = state[:, BA]
    pelvis = np.column_stack([state[:, BX] - np.sin(yaw) * state[:, BY],
                              state[:, BW] + np.cos(yaw) * state[:, BY],
                              np.full(len(t), p.hip_height + leg.hip_offset_z)])
    support = np.where((state[:, ZL] > 0) | (state[:, ZR] > 0), support, 0)
    meta = {"transition_ticks": ref.transition_ticks.tolist(),
            "cycle_time": (4 * (math.pi / 2) / p.t_mn + 4 * dsp_ticks(p)) * p.tick}
    if plan is None:
        return assemble("eros", t, leg, p_world_pelvis=pelvis, p_world_foot_l=left,
                        p_world_foot_r=right, support=support, ankle_pitch_offset=off, meta=meta)
    meta["commands"] = np.asarray(commands, dtype=float).tolist()
    return assemble("eros", t, leg, p_world_pelvis=pelvis, p_world_foot_l=left,
                    p_world_foot_r=right, support=support, ankle_pitch_offset=off,
                    yaw_world_pelvis=yaw, yaw_world_feet=state[:, [AL, AR]], meta=meta)
