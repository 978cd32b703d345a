"""Natural walking trajectory generator on the three-mass LIPM plus flywheel (TLIPFM).

Wong, Xiao, Aoyama, *Natural Walking Trajectory Generator for Humanoid Robot
Based on Three-Mass LIPFM*, IEEE Access 8 (2020). Equation numbers below are the
paper's. LIPM and DLIPM, the paper's comparisons, are special cases of the same
closed form with other pendulum constants (:func:`pendulum_constants`).

Pipeline: step locations p^c (eqs 6-8) -> natural moving-ZMP reference per step
(eqs 10-11) -> CoM position and velocity in closed form per step (eqs 23-26,
i.e. eqs 15-22 with the piecewise-linear ZMP) -> cycloid swing foot (eq 27) ->
leg IK (``gaits.leg_kinematics``) -> joint table.

Readings of the printed paper:

* eq 10 prints ``(d_2 - a)/(T - t_1)`` in the last segment; the closed form's
  K_3 = (d_2 - a)/(T - t_2) and continuity at t = T need ``T - t_2``. We use it.
* eq 14 prints first derivatives where second derivatives are meant (compare eq 4).
* J is printed as "0.026 kg/cm^2"; as kg cm^2 it would be 2.6e-6 kg m^2, far
  below any 5 kg robot's pitch inertia, so we read 0.026 kg m^2.
* The ZMP of each step runs from p^c - d_1 to p^c + d_2 and the next starts at
  p^c + S_L - d_1, so the reference is continuous only if d_1 + d_2 = S_L
  (true for Table 2); the parameters are rejected otherwise. The paper indexes
  d_{1,n}, d_{2,n} per step: we use d_1 = 0 on the first step and d_2 = 0 on
  the last, so the reference starts and ends between the feet, standing.
* eq 27 prints F_y = Amp_y (= W_y) through the whole swing, which would make the
  foot jump sideways at lift-off; we use W_y (1 - cos(theta))/2, equal to the
  printed value at mid-swing and zero at lift-off and touch-down.
* The paper does not say how x(0), x'(0) of each step are chosen. We take the
  bounded solution: the divergent component xi = x + T_TF x' is integrated
  backwards from standing still at the end (exact for a piecewise-linear ZMP),
  and each step's initial state is (x, (xi - x) / T_TF). The robot starts at
  rest after ``t_start`` of standing, and the step closed form (eq 23) carries
  the state from one step to the next.

DLIPM as the two-mass case (derivation). Put masses m_i on the line from the
support point p to the CoM (x, z_c), mass i at height fraction f_i and with
horizontal position x_i = p + f_i (x - p) (the upper body on its vertical
stick: x_i = x, height z_c + l_u). The moment balance about p with a flywheel
torque tau is  sum_i m_i (h_i x_i'' - g (x_i - p)) = -tau, and with p fixed
x_i'' = f_i x'':

    (sum_i m_i f_i h_i) x'' = g (sum_i m_i f_i) (x - p) - tau.

TLIPFM: (M_u, f=1, h=z_c+l_u), (m_t, 3/4, 3z_c/4), (m_c, 1/4, z_c/4), giving
eq 2: C_tau^2 = M_u z_c + M_u l_u + 9 m_t z_c/16 + m_c z_c/16 and
T_TF^2 = C_tau^2 / ((M_u + 3 m_t/4 + m_c/4) g). DLIPM (Park's double-link
model): the upper body at the CoM (l_u = 0) and the whole support leg
m_l = m_t + m_c at its middle (f = 1/2, h = z_c/2), no flywheel:
C^2 = (M_u + m_l/4) z_c, T^2 = (M_u + m_l/4) z_c / ((M_u + m_l/2) g).
LIPM: one mass at the CoM, T^2 = z_c / g.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .footstep_planner import FootstepPlan, StepLimits, plan_footsteps, swing_fraction
from .leg_kinematics import LegGeometry
from .params import GaitParams, ParamError, param
from .trajectory import GRAVITY, GaitTrajectory, assemble

__all__ = [
    "TlipfmParams",
    "PendulumConstants",
    "pendulum_constants",
    "step_locations",
    "zmp_segments",
    "natural_zmp",
    "com_closed_form",
    "com_trajectory",
    "cycloid_swing",
    "generate",
    "straight_commands",
    "command_zmp_segments",
]


@dataclass(frozen=True)
class TlipfmParams(GaitParams):
    """TLIPFM generator parameters; defaults are the TKU-X values of Table 2 (SI units)."""

    FAMILY = "tlipfm"
    model: str = param("tlipfm", "-", doc="dynamic model of the CoM",
                       choices=("lipm", "dlipm", "tlipfm"))
    step_length: float = param(0.02, "m", -0.08, 0.08, "step forward distance", "S_L")
    half_width: float = param(0.045, "m", 0.02, 0.12, "half the distance between the feet", "S_W")
    first_support: int = param(-1, "-", doc="starting support foot sign: -1 the right foot supports "
                               "first (left foot moves first), +1 the left", paper="S_first",
                               choices=(-1, 1))
    d1: float = param(0.01, "m", -0.05, 0.05, "ZMP behind the support foot at step start", "d_1,n")
    d2: float = param(0.01, "m", -0.05, 0.05, "ZMP ahead of the support foot at step end", "d_2,n")
    a: float = param(0.004, "m", -0.03, 0.03, "half the ZMP travel during single support", "a_n")
    l_u: float = param(0.09, "m", 0.0, 0.3, "CoM to upper-body mass (half the upper body)", "l_u")
    z_c: float = param(0.217, "m", 0.08, 0.5, "constant CoM height", "z_c")
    w_y: float = param(0.0, "m", -0.03, 0.03, "lateral swing-foot offset at mid-swing", "W_y")
    h_z: float = param(0.03, "m", 0.0, 0.10, "swing-foot lift height", "H_z")
    t1: float = param(0.15, "s", 0.01, 2.9, "start of single support within a step", "t_1")
    t2: float = param(0.49, "s", 0.02, 2.95, "end of single support within a step", "t_2")
    period: float = param(0.64, "s", 0.1, 3.0, "period of one step", "T")
    n_steps: int = param(14, "-", 2, 500, "total number of steps", "N")
    inertia: float = param(0.026, "kg m^2", 0.0, 1.0, "flywheel rotational inertia", "J")
    flywheel_accel: float = param(0.0, "rad/s^2", -100.0, 100.0,
                                  "constant flywheel angular acceleration (tau = J phi'')", "phi''")
    mass_upper: float = param(3.05, "kg", 0.05, 100.0, "upper-body mass", "M_u")
    mass_thigh: float = param(0.2, "kg", 0.0, 20.0, "support-leg thigh mass", "m_t")
    mass_calf: float = param(0.75, "kg", 0.0, 20.0, "support-leg calf mass (with sole)", "m_c")
    torso_pitch: float = param(0.0, "rad", -0.3, 0.3, "constant forward lean of the pelvis and "
                               "torso (ours; the paper walks upright)")
    reach_forward: float = param(0.45, "leg", 0.1, 0.8, "walk commands: longest step ahead of the "
                                 "support foot, in thigh + shank lengths (ours)")
    reach_backward: float = param(0.32, "leg", 0.1, 0.6, "walk commands: longest step behind the "
                                  "support foot, in thigh + shank lengths (ours)")
    reach_outward: float = param(0.27, "leg", 0.05, 0.5, "walk commands: widest outward side step, "
                                 "in thigh + shank lengths (ours)")
    max_turn: float = param(0.6, "rad", 0.1, 1.2, "walk commands: largest turn of a foot against "
                            "the support foot per step (ours)")
    t_start: float = param(1.0, "s", 0.0, 10.0, "standing time before the first step (ours)")
    t_end: float = param(1.0, "s", 0.0, 10.0, "standing time after the last step (ours)")

    def check_consistency(self) -> None:
        if not self.t1 < self.t2 < self.period:
            raise ParamError(f"tlipfm: need 0 < t1 < t2 < period, got t1 = {self.t1:g} s, "
                             f"t2 = {self.t2:g} s, period = {self.period:g} s")
        if abs(self.d1 + self.d2 - self.step_length) > 1e-9:
            raise ParamError(f"tlipfm: the ZMP reference is continuous only if d1 + d2 = "
                             f"step_length; got d1 + d2 = {self.d1 + self.d2:g} m, "
                             f"step_length = {self.step_length:g} m")

    @property
    def t_ssp(self) -> float:
        """T_SSP = t2 - t1 [s] (eq 9)."""
        return self.t2 - self.t1

    @property
    def t_dsp(self) -> float:
        """T_DSP = T - T_SSP [s] (eq 9)."""
        return self.period - self.t_ssp


@dataclass(frozen=True)
class PendulumConstants:
    """T_TF [s] and C_tau^2 [kg m] of eq 4, and the flywheel torque tau [N m]."""

    model: str
    T: float
    c_tau2: float
    tau: float

    @property
    def zmp_shift(self) -> float:
        """T_TF^2 tau / C_tau^2 [m]: the flywheel torque acts as a constant ZMP offset (eq 15)."""
        return self.T ** 2 * self.tau / self.c_tau2


def pendulum_constants(p: TlipfmParams, model: str | None = None,
                       g: float = GRAVITY) -> PendulumConstants:
    """Natural period and torque parameter of LIPM, DLIPM or TLIPFM (eq 4 and module docstring)."""
    model = model or p.model
    if model == "lipm":
        mass = p.mass_upper + p.mass_thigh + p.mass_calf
        return PendulumConstants("lipm", math.sqrt(p.z_c / g), mass * p.z_c, 0.0)
    if model == "dlipm":
        m_leg = p.mass_thigh + p.mass_calf
        c2 = (p.mass_upper + m_leg / 4.0) * p.z_c
        return PendulumConstants("dlipm", math.sqrt(c2 / ((p.mass_upper + m_leg / 2.0) * g)), c2, 0.0)
    if model == "tlipfm":
        c2 = (p.mass_upper * p.z_c + p.mass_upper * p.l_u
              + 9.0 * p.mass_thigh * p.z_c / 16.0 + p.mass_calf * p.z_c / 16.0)
        m_eff = p.mass_upper + 3.0 * p.mass_thigh / 4.0 + p.mass_calf / 4.0
        return PendulumConstants("tlipfm", math.sqrt(c2 / (m_eff * g)), c2,
                                 p.inertia * p.flywheel_accel)
    raise ParamError(f"unknown model {model!r}: expected lipm, dlipm or tlipfm")


def step_locations(p: TlipfmParams) -> np.ndarray:
    """Support-foot locations p^c = (p_x^c, p_y^c) of steps n = 0..N-1 (eqs 6-8), shape (N, 2)."""
    n = np.arange(p.n_steps)
    px = p.step_length * n
    py = p.first_support * p.half_width * np.where(n % 2 == 0, 1.0, -1.0)
    return np.column_stack([px, py])


def zmp_segments(p: TlipfmParams) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-step piecewise-linear ZMP: breaks (3,) and (L, K) of shape (N, 3) for x and for y.

    Segment i of step n is p(s) = L[n, i] + K[n, i] s for local time s in
    [breaks[i], breaks[i+1]) (breaks = 0, t1, t2; the step ends at T). These are
    the L_i, K_i of eq 23 (sagittal) and the coefficients behind y_1..y_3 of
    eq 25 (lateral).
    """
    pc = step_locations(p)
    t1, t2, T = p.t1, p.t2, p.period
    n = p.n_steps
    d1 = np.full(n, p.d1)
    d2 = np.full(n, p.d2)
    d1[0] = 0.0          # start between the feet (see module docstring)
    d2[-1] = 0.0         # end between the feet
    a = p.a
    px, py = pc[:, 0], pc[:, 1]
    Lx = np.column_stack([px - d1, px - a - 2 * a * t1 / (t2 - t1), px + a - (d2 - a) * t2 / (T - t2)])
    Kx = np.column_stack([(d1 - a) / t1, np.full(n, 2 * a / (t2 - t1)), (d2 - a) / (T - t2)])
    Ly = np.column_stack([np.zeros(n), py, py * T / (T - t2)])
    Ky = np.column_stack([py / t1, np.zeros(n), -py / (T - t2)])
    return np.array([0.0, t1, t2]), (Lx, Kx), (Ly, Ky), pc


def command_zmp_segments(p: TlipfmParams, plan: FootstepPlan):
    """The natural ZMP (eqs 10-11) along a footstep plan, per world axis (ours).

    Each step keeps the paper's three segments and times (0, t1, t2, T): in double
    support the ZMP moves in a straight line from the previous step's boundary point
    to a behind the support foot's centre, in single support from a behind to a
    ahead of it *along the foot's heading*, then to the next boundary point. The
    boundary point between support feet F_n and F_n+1 is, in F_n's frame,
    (rho dx, dy / 2) of their offset (dx, dy), with rho = d2 / (d1 + d2) (0.5 when
    both are 0): for a straight walk it is the paper's p^c_n + d_2 on the mid-line,
    so a constant command gives eqs 10-11 exactly (tested). The first step starts and
    the last ends between the feet, as in :func:`zmp_segments`.

    Returns breaks (3,), (Lx, Kx), (Ly, Ky) of shape (n_steps, 3), and the support
    headings (n_steps,).
    """
    t1, t2, T = p.t1, p.t2, p.period
    total = p.d1 + p.d2
    rho = p.d2 / total if abs(total) > 1e-12 else 0.5
    F = plan.support
    c, s = np.cos(F[:, 2]), np.sin(F[:, 2])
    heading = np.column_stack([c, s])
    lateral = np.column_stack([-s, c])
    ahead = F[:, :2] + p.a * heading
    behind = F[:, :2] - p.a * heading
    nxt = plan.swing_target[:, :2] - F[:, :2]
    fwd = np.sum(nxt * heading, axis=1)
    side = np.sum(nxt * lateral, axis=1)
    boundary = F[:, :2] + (rho * fwd)[:, None] * heading + (0.5 * side)[:, None] * lateral
    first = (plan.start_left[:2] + plan.start_right[:2]) / 2.0
    start = np.vstack([first, boundary[:-1]])
    K0 = (behind - start) / t1
    K1 = (ahead - behind) / (t2 - t1)
    K2 = (boundary - ahead) / (T - t2)
    L0, L1, L2 = start, behind - K1 * t1, ahead - K2 * t2
    Lx = np.column_stack([L0[:, 0], L1[:, 0], L2[:, 0]])
    Ly = np.column_stack([L0[:, 1], L1[:, 1], L2[:, 1]])
    Kx = np.column_stack([K0[:, 0], K1[:, 0], K2[:, 0]])
    Ky = np.column_stack([K0[:, 1], K1[:, 1], K2[:, 1]])
    return np.array([0.0, t1, t2]), (Lx, Kx), (Ly, Ky), F[:, 2].copy()


def _segment_index(s: np.ndarray, breaks: np.ndarray) -> np.ndarray:
    return np.clip(np.searchsorted(breaks, s, side="right") - 1, 0, len(breaks) - 1)


def natural_zmp(p: TlipfmParams, t: np.ndarray, plan: FootstepPlan | None = None) -> np.ndarray:
    """Natural moving-ZMP reference (eqs 10-11) at absolute times t, shape (len(t), 2).

    Absolute time starts with ``t_start`` of standing; the reference holds its
    first and last values while standing. With a footstep ``plan``, the reference of
    :func:`command_zmp_segments`.
    """
    if plan is None:
        breaks, (Lx, Kx), (Ly, Ky), _ = zmp_segments(p)
    else:
        breaks, (Lx, Kx), (Ly, Ky), _ = command_zmp_segments(p, plan)
    n_steps = len(Lx)
    t = np.asarray(t, dtype=float)
    s_all = t - p.t_start
    n = np.clip(np.floor(s_all / p.period).astype(int), 0, n_steps - 1)
    s = np.clip(s_all - n * p.period, 0.0, p.period)
    s = np.where(s_all < 0, 0.0, s)
    s = np.where(s_all >= n_steps * p.period, p.period, s)
    i = _segment_index(s, breaks)
    return np.column_stack([Lx[n, i] + Kx[n, i] * s, Ly[n, i] + Ky[n, i] * s])


def com_closed_form(s: np.ndarray, x0: float, v0: float, breaks: np.ndarray, L: np.ndarray,
                    K: np.ndarray, T: float, zmp_shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """CoM position and velocity within one step, eqs 23-24 (sagittal) / 25-26 (lateral).

    ``s`` local times in [0, T_step]; (x0, v0) the state at s = 0; the ZMP is
    L[i] + K[i] s on [breaks[i], breaks[i+1]); ``zmp_shift`` = T_TF^2 tau / C_tau^2
    (the flywheel term of eq 23; 0 laterally). Returns (x(s), x'(s)).
    """
    s = np.asarray(s, dtype=float)
    ch, sh = np.cosh(s / T), np.sinh(s / T)
    x = x0 * ch + v0 * T * sh - zmp_shift * (ch - 1.0)
    v = x0 / T * sh + v0 * ch - zmp_shift / T * sh
    L_prev = K_prev = 0.0
    for b, Li, Ki in zip(breaks, L, K):
        dL, dK = Li - L_prev, Ki - K_prev
        sig = s - b
        on = sig >= 0.0
        c_b, s_b = np.cosh(sig / T), np.sinh(sig / T)
        x = x + np.where(on, dL * (1.0 - c_b) + dK * (s - b * c_b - T * s_b), 0.0)
        v = v + np.where(on, -dL / T * s_b + dK * (1.0 - b / T * s_b - c_b), 0.0)
        L_prev, K_prev = Li, Ki
    return x, v


def _dcm_backward(xi_end: float, breaks: np.ndarray, L: np.ndarray, K: np.ndarray,
                  t_step: float, T: float, shift: float) -> float:
    """xi = x + T x' at the start of a step, from xi at its end (exact for linear ZMP segments)."""
    ends = np.append(breaks[1:], t_step)
    xi = xi_end
    for b, e, Li, Ki in zip(breaks[::-1], ends[::-1], L[::-1], K[::-1]):
        p_e = Li + Ki * e + shift
        p_b = Li + Ki * b + shift
        xi = p_b + Ki * T + (xi - p_e - Ki * T) * math.exp(-(e - b) / T)
    return xi


@dataclass(frozen=True)
class ComTrajectory:
    """CoM samples and the per-step initial states the closed form started from."""

    t: np.ndarray          # (N,) absolute time [s]
    pos: np.ndarray        # (N, 2) [m]
    vel: np.ndarray        # (N, 2) [m/s]
    step_x0: np.ndarray    # (n_steps, 2) CoM position at each step start [m]
    step_v0: np.ndarray    # (n_steps, 2) CoM velocity at each step start [m/s]
    constants: PendulumConstants


def _com_axis(t: np.ndarray, t_start: float, period: float, breaks: np.ndarray, L: np.ndarray,
              K: np.ndarray, shift: np.ndarray, T: float) -> tuple[np.ndarray, ...]:
    """One horizontal axis of the CoM for per-step linear ZMP segments (eqs 23-26).

    ``L``, ``K`` (n_steps, 3) as in :func:`zmp_segments`; ``shift`` (n_steps,) the flywheel's
    ZMP offset of each step along this axis. Returns position, velocity (len(t),) and the
    per-step initial position and velocity (n_steps,).
    """
    n_steps = len(L)
    pos = np.empty(len(t))
    vel = np.empty(len(t))
    x0s = np.empty(n_steps)
    v0s = np.empty(n_steps)
    # backward pass of the divergent component, from rest at the end
    p_end = L[-1, 2] + K[-1, 2] * period + shift[-1]
    xi_start = np.empty(n_steps)
    xi = p_end
    for n in range(n_steps - 1, -1, -1):
        xi = _dcm_backward(xi, breaks, L[n], K[n], period, T, shift[n])
        xi_start[n] = xi
    p0 = L[0, 0] + shift[0]
    # standing before the walk: constant ZMP p0; start at rest at x = xi(0)
    xi_0 = p0 + (xi_start[0] - p0) * math.exp(-t_start / T)
    x, v = xi_0, 0.0
    s_all = t - t_start
    mask = s_all < 0
    if np.any(mask):
        xs, vs = com_closed_form(t[mask], x, v, np.array([0.0]), np.array([p0 - shift[0]]),
                                 np.array([0.0]), T, shift[0])
        pos[mask], vel[mask] = xs, vs
    xe, _ = com_closed_form(np.array([t_start]), x, v, np.array([0.0]),
                            np.array([p0 - shift[0]]), np.array([0.0]), T, shift[0])
    x = float(xe[0])
    for n in range(n_steps):
        v = (xi_start[n] - x) / T
        x0s[n], v0s[n] = x, v
        lo, hi = n * period, (n + 1) * period
        mask = (s_all >= lo) & ((s_all < hi) | ((n == n_steps - 1) & (s_all <= hi)))
        if np.any(mask):
            xs, vs = com_closed_form(s_all[mask] - lo, x, v, breaks, L[n], K[n], T, shift[n])
            pos[mask], vel[mask] = xs, vs
        xe, _ = com_closed_form(np.array([period]), x, v, breaks, L[n], K[n], T, shift[n])
        x = float(xe[0])
    # standing after the walk
    v = (p_end - x) / T
    mask = s_all > n_steps * period
    if np.any(mask):
        xs, vs = com_closed_form(s_all[mask] - n_steps * period, x, v, np.array([0.0]),
                                 np.array([p_end - shift[-1]]), np.array([0.0]), T, shift[-1])
        pos[mask], vel[mask] = xs, vs
    return pos, vel, x0s, v0s


def com_trajectory(p: TlipfmParams, t: np.ndarray, model: str | None = None,
                   plan: FootstepPlan | None = None) -> ComTrajectory:
    """CoM (x, y) and velocity at absolute times t for the natural ZMP (eqs 23-26).

    Standing phases before and after the walk are the same closed form with a
    constant ZMP. See the module docstring for the choice of initial states. With a
    footstep ``plan`` (a walk command), the ZMP of :func:`command_zmp_segments` is used:
    the LIPM is isotropic, so the closed form holds per *world* axis for any piecewise-
    linear ZMP, turning or not (tested against a numerical integration).
    """
    const = pendulum_constants(p, model)
    if plan is None:
        breaks, segx, segy, _ = zmp_segments(p)
        shifts = np.column_stack([np.full(p.n_steps, const.zmp_shift), np.zeros(p.n_steps)])
    else:
        breaks, segx, segy, heading = command_zmp_segments(p, plan)
        shifts = const.zmp_shift * np.column_stack([np.cos(heading), np.sin(heading)])
    t = np.asarray(t, dtype=float)
    n_steps = len(segx[0])
    pos = np.empty((len(t), 2))
    vel = np.empty((len(t), 2))
    x0s = np.empty((n_steps, 2))
    v0s = np.empty((n_steps, 2))
    for axis, (L, K) in enumerate((segx, segy)):
        pos[:, axis], vel[:, axis], x0s[:, axis], v0s[:, axis] = _com_axis(
            t, p.t_start, p.period, breaks, L, K, shifts[:, axis], const.T)
    return ComTrajectory(t, pos, vel, x0s, v0s, const)


def cycloid_swing(s: np.ndarray, t1: float, t2: float, dx: float, w_y: float,
                  h_z: float) -> np.ndarray:
    """Swing-foot displacement from lift-off (eq 27), shape (len(s), 3).

    theta = 2 pi (s - t1) / (t2 - t1), clipped to [0, 2 pi];
    F_x = (theta - sin theta) Amp_x with Amp_x = dx / (2 pi);
    F_z = (1 - cos theta) Amp_z with Amp_z = H_z / 2;
    F_y = W_y (1 - cos theta) / 2 (see the module docstring).
    """
    theta = 2.0 * np.pi * np.clip((np.asarray(s, dtype=float) - t1) / (t2 - t1), 0.0, 1.0)
    fx = (theta - np.sin(theta)) * dx / (2.0 * np.pi)
    fy = w_y * (1.0 - np.cos(theta)) / 2.0
    fz = (1.0 - np.cos(theta)) * h_z / 2.0
    return np.column_stack([fx, fy, fz])


def _command_feet(p: TlipfmParams, plan: FootstepPlan, t: np.ndarray):
    """Feet poses along a plan: the cycloid of eq 27 applied to the swing's whole (x, y, yaw)
    displacement, W_y across the support foot's heading. Returns left, right (len(t), 3),
    their yaws (len(t), 2) and the support phase (len(t),)."""
    left = np.tile(np.array([plan.start_left[0], plan.start_left[1], 0.0]), (len(t), 1))
    right = np.tile(np.array([plan.start_right[0], plan.start_right[1], 0.0]), (len(t), 1))
    yaw = np.zeros((len(t), 2))
    support = np.zeros(len(t), dtype=int)
    s_all = t - p.t_start
    for n in range(plan.n_steps):
        sup_side = int(plan.support_side[n])
        sw_side = -sup_side
        lo, hi = n * p.period, (n + 1) * p.period
        mask = (s_all >= lo) & (s_all < hi)
        s = s_all[mask] - lo
        theta = 2.0 * np.pi * np.clip((s - p.t1) / (p.t2 - p.t1), 0.0, 1.0)
        frac = swing_fraction(theta)[:, None]
        a, b, F = plan.swing_start[n], plan.swing_target[n], plan.support[n]
        pose = a + frac * (b - a)
        bulge = p.w_y * sw_side * (1.0 - np.cos(theta)) / 2.0
        pose[:, 0] += -np.sin(F[2]) * bulge
        pose[:, 1] += np.cos(F[2]) * bulge
        z = (1.0 - np.cos(theta)) * p.h_z / 2.0
        sw = np.column_stack([pose[:, :2], z])
        st = np.broadcast_to(np.array([F[0], F[1], 0.0]), sw.shape)
        i_sw, i_st = (0, 1) if sw_side == 1 else (1, 0)
        (left if sw_side == 1 else right)[mask] = sw
        (left if sup_side == 1 else right)[mask] = st
        yaw[mask, i_sw] = pose[:, 2]
        yaw[mask, i_st] = F[2]
        support[mask] = np.where((s > p.t1) & (s <= p.t2), sup_side, 0)
        after = s_all >= hi
        (left if sw_side == 1 else right)[after] = np.array([b[0], b[1], 0.0])
        yaw[after, i_sw] = b[2]
    return left, right, yaw, support


def straight_commands(p: TlipfmParams) -> np.ndarray:
    """The per-step commands of the paper's straight walk (eqs 6-8): S_L / T forward on every step
    but the last, which sets the swing foot down beside the support foot, shape (N, 3)."""
    cmd = np.zeros((p.n_steps, 3))
    cmd[:-1, 0] = p.step_length / p.period
    return cmd


def generate(p: TlipfmParams, leg: LegGeometry = LegGeometry(), dt: float = 0.01,
             model: str | None = None, commands: np.ndarray | None = None,
             limits: StepLimits | None = None) -> GaitTrajectory:
    """The full TLIPFM (or LIPM / DLIPM) walk sampled every ``dt`` seconds.

    One path for every walk: footsteps from ``gaits/footstep_planner.py`` for per-step
    ``commands`` (n, 3) (vx [m/s], vy [m/s], wz [rad/s], see ``gaits/walk_command.py``), the
    natural ZMP along them, the closed-form CoM and the cycloid swing. Without ``commands`` the
    walk is the paper's straight one, the constant command :func:`straight_commands` (its
    footsteps are eqs 6-8 exactly, tested), planned without step limits. With commands,
    ``n_steps`` and ``step_length`` are unused (the commands give both), d1 and d2 only set
    where the ZMP crosses between the feet. The pelvis heading is the mean of the feet's (ours).
    """
    if not (1e-4 <= dt <= 0.1):
        raise ParamError(f"dt = {dt!r} s is out of range [0.0001, 0.1] s")
    straight = commands is None
    if straight:
        commands = straight_commands(p)
        limits = StepLimits(max_forward=0.5, max_backward=0.5, min_gap=0.0)
    plan = plan_footsteps(commands, p.period, p.half_width, p.first_support, limits or StepLimits())
    total = p.t_start + plan.n_steps * p.period + p.t_end
    t = np.arange(int(round(total / dt)) + 1) * dt
    com = com_trajectory(p, t, model, plan)
    zmp = natural_zmp(p, t, plan)
    left, right, yaw_feet, support = _command_feet(p, plan, t)
    p_com = np.column_stack([com.pos, np.full(len(t), p.z_c)])
    pelvis = p_com - np.array([0.0, 0.0, leg.com_above_pelvis])
    meta = {"model": com.constants.model, "T_TF": com.constants.T, "C_tau2": com.constants.c_tau2,
            "tau": com.constants.tau, "cycle_time": 2 * p.period}
    if not straight:
        meta.update({"t_start": p.t_start, "period": p.period,
                     "commands": np.asarray(commands, dtype=float).tolist()})
    return assemble("tlipfm", t, leg, p_world_pelvis=pelvis, p_world_foot_l=left,
                    p_world_foot_r=right, support=support, p_world_zmp_ref=zmp,
                    yaw_world_pelvis=None if straight else yaw_feet.mean(axis=1),
                    yaw_world_feet=None if straight else yaw_feet,
                    pitch_pelvis=p.torso_pitch, meta=meta)
