"""A step of the engine's plan and its adjustment (ours, on the TLIPFM paper's natural ZMP): the
rules the engine takes from a TLIPFM set (:class:`_Gait`: the planner's footstep, the reach box,
the step's ZMP knots, the DCM the next steps need) and :func:`adjust_step`, the box QP that
chooses the next footstep, the swing's timing and the ZMP's place on the sole."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..footstep_planner import StepLimits, compose
from ..lipm import dcm_backward, dcm_forward_weights, solve_box_qp
from ..params import ParamError
from ..tlipfm import TlipfmParams, pendulum_constants
from .params import EngineParams

__all__ = ["Step", "adjust_step"]


@dataclass
class Step:
    """One step of the engine's plan (times local to the step, poses (x, y, yaw) in its world)."""

    side: int                    # +1 the left foot supports, -1 the right
    support: np.ndarray          # (3,) support foot pose
    swing_from: np.ndarray       # (3,) where the swing foot lifts off
    target: np.ndarray           # (3,) where it lands
    p0: np.ndarray               # (2,) the ZMP at the step's start (the previous boundary)
    t1: float                    # [s] lift-off
    t2: float                    # [s] touch-down
    T: float                     # [s] the step's end
    command: np.ndarray          # (3,) the command it was planned for
    knots_t: np.ndarray = None   # ZMP profile of the step
    knots_p: np.ndarray = None
    shift: np.ndarray = None     # (2,) the flywheel's ZMP shift
    # the swing, re-targetable: from (tau_a, pose_a, theta_a) to (t2, target)
    tau_a: float = 0.0
    pose_a: np.ndarray = None
    theta_a: float = 0.0
    landed: bool = False
    offset: np.ndarray = None    # (2,) the ZMP's move on the support sole (its frame)


class _Gait:
    """What the engine takes from a TLIPFM set, and the step rules that use it."""

    def __init__(self, p: TlipfmParams, limits: StepLimits, stance_widen: float = 0.0,
                 stance_speed: float = 0.1) -> None:
        if not isinstance(p, TlipfmParams):
            raise ParamError(f"the walk engine plans TLIPFM steps; a {p.FAMILY!r} set has no engine "
                             f"(gaits.family({p.FAMILY!r}).engine)")
        self.p = p
        const = pendulum_constants(p)
        self.Tc = const.T
        self.zmp_shift = const.zmp_shift
        self.limits = limits
        total = p.d1 + p.d2
        self.rho = p.d2 / total if abs(total) > 1e-12 else 0.5
        self.stance_widen, self.stance_speed = float(stance_widen), float(stance_speed)
        # d required_dcm / d p0: a step's first ZMP point enters only the backward pass's first
        # segment (0 to t1; the later steps start from this one's boundary, not from p0), whose
        # forward pass is xi(t1) = a xi(0) + w_0 p0 + w_1 p1, so xi(0) moves by -w_0 / a with p0 (ours)
        a, w, _ = dcm_forward_weights(0.0, p.t1, (0.0, p.t1), self.Tc)
        self.start_weight = float(-w[0] / a)

    def half_width(self, command: np.ndarray) -> float:
        """Half the feet's distance the steps of ``command`` land at [m]: the gait's ``half_width``,
        plus ``stance_widen`` at a zero command, falling linearly to nothing at ``stance_speed`` of
        the larger of |vx|, |vy| and a turn's speed of one foot about the other, |wz| 2 half_width
        (ours)."""
        W = self.p.half_width
        if self.stance_widen <= 0.0:
            return W
        speed = max(abs(float(command[0])), abs(float(command[1])), abs(float(command[2])) * 2.0 * W)
        return W + self.stance_widen * max(0.0, 1.0 - speed / self.stance_speed)

    def nominal_target(self, support: np.ndarray, side: int, command: np.ndarray) -> np.ndarray:
        """The planner's footstep (``footstep_planner.plan_footsteps``' rule) for a held command, the
        feet ``half_width(command)`` from the mid-line."""
        T, W = self.p.period, self.half_width(command)
        s = -side
        vx, vy, wz = command
        mid = compose(support, np.array([0.0, s * W, 0.0]))
        dy = 2.0 * vy * T if s * vy > 0 else 0.0
        dth = 2.0 * wz * T if s * wz > 0 else 0.0
        return compose(compose(compose(mid, np.array([vx * T, dy, 0.0])), np.array([0.0, 0.0, dth])),
                       np.array([0.0, s * W, 0.0]))

    def box(self, side: int, turn: float) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the swing target (x, y) in the support foot's frame: the reach, and an inward
        bound that keeps the soles ``min_gap`` apart (widened by a turned foot's corner)."""
        lim, W = self.limits, self.p.half_width
        s = -side
        inner = lim.sole_width + lim.min_gap + abs(math.sin(turn)) * lim.sole_length / 2
        outer = max(2 * W + lim.max_outward, inner)
        ys = sorted((s * inner, s * outer))
        return np.array([-lim.max_backward, ys[0]]), np.array([lim.max_forward, ys[1]])

    def knots(self, support: np.ndarray, p0: np.ndarray, target: np.ndarray, t1: float, t2: float,
              T: float, offset: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The natural ZMP of a step (``tlipfm.command_zmp_segments``): p0 -> a behind -> a ahead of
        the support foot along its heading -> the boundary toward the next one; and the shift.
        ``offset`` (2,) [m], in the support foot's frame, moves the two points on the support foot
        (the ankle's share of a step adjustment, ours)."""
        c, s = math.cos(support[2]), math.sin(support[2])
        h, lat = np.array([c, s]), np.array([-s, c])
        F = support[:2]
        if offset is not None:
            F = F + offset[0] * h + offset[1] * lat
        nxt = target[:2] - support[:2]
        boundary = support[:2] + self.rho * float(nxt @ h) * h + 0.5 * float(nxt @ lat) * lat
        pts = np.array([p0, F - self.p.a * h, F + self.p.a * h, boundary])
        return np.array([0.0, t1, t2, T]), pts, self.zmp_shift * h

    def zmp_box(self, margin: float) -> tuple[np.ndarray, np.ndarray]:
        """How far the ZMP's points may move on the support sole (its frame), ``margin`` [m] inside."""
        L, Wd = self.limits.sole_length, self.limits.sole_width
        hx = max(L / 2 - abs(self.p.a) - margin, 0.0)
        hy = max(Wd / 2 - margin, 0.0)
        return np.array([-hx, -hy]), np.array([hx, hy])

    def required_dcm(self, support: np.ndarray, side: int, p0: np.ndarray, command: np.ndarray,
                     n: int) -> np.ndarray:
        """The DCM a step starting on ``support`` needs for ``n`` steps of the held command that end
        with the ZMP at their last boundary (a zero command's boundary lies between the feet: rest)."""
        p = self.p
        steps = []
        F, sd, start = support, side, p0
        for _ in range(n):
            B = self.nominal_target(F, sd, command)
            kt, kp, sh = self.knots(F, start, B, p.t1, p.t2, p.period)
            steps.append((kt, kp, sh))
            F, sd, start = B, -sd, kp[-1]
        xi = steps[-1][1][-1].copy()
        for kt, kp, sh in reversed(steps):
            xi = dcm_backward(xi, kt, kp, sh, self.Tc)
        return xi


def adjust_step(gait: _Gait, step: Step, tau: float, xi: np.ndarray, command: np.ndarray, n_preview: int,
                swing_pose: np.ndarray | None, params: EngineParams, dt: float,
                fixed_target: bool = False) -> tuple[np.ndarray, float, np.ndarray, dict]:
    """The next footstep (x, y; its heading kept), the single-support scale lambda and the ZMP
    offset on the support sole for a step at local time ``tau`` whose DCM is ``xi``.

    Variables z = (du, dp): the footstep's move from the planner's and the ZMP's move on the sole,
    both in the support foot's frame. The DCM mismatch at the step's end, r = xi_end - xi_req, is
    affine in z (a closed-form LIPM pass at z = 0, and the pass's linear weights for the columns); the
    engine minimises |r|^2 + ``step_weight`` |du|^2 + ``zmp_weight`` |dp|^2 over the reach box and the
    sole (``lipm.solve_box_qp``) for each of five lambdas, drops those whose swing would exceed
    ``foot_speed``, and keeps the lambda of least cost + ``timing_weight`` (1 - lambda)^2.
    ``fixed_target``: the foot has landed; only the ZMP offset is free.
    Returns (target (3,), lambda, offset (2,), info); ``info["binds"]`` names the limits the chosen
    solution sits on (ours, for reports): ``reach`` (the footstep at its reach box or sole gap),
    ``sole`` (the ZMP at the sole's edge less ``zmp_margin``), ``timing`` (a shorter swing than
    planned), ``speed`` (a swing dropped because it would exceed ``foot_speed``; a timing whose
    (1 - lambda)^2 term alone costs more than the best found is not solved, so it is never dropped:
    the speed did not bind there)."""
    p = gait.p
    nominal = step.target.copy() if fixed_target else gait.nominal_target(step.support, step.side, command)
    c, s = math.cos(step.support[2]), math.sin(step.support[2])
    Rot = np.array([[c, -s], [s, c]])
    u_nom = Rot.T @ (nominal[:2] - step.support[:2])
    lo_u, hi_u = gait.box(step.side, nominal[2] - step.support[2])
    if not fixed_target:
        u_nom = np.clip(u_nom, lo_u, hi_u)
    lo_p, hi_p = gait.zmp_box(params.zmp_margin)
    ssp = p.t2 - p.t1
    tail = p.period - p.t2
    n_var = 2 if fixed_target else 4

    # the mismatch r(z) = r0 + M z: r0 from one closed-form pass per timing; M's columns from the
    # pass's weights (lipm.dcm_forward_weights: the ZMP's two sole points move with dp, the boundary
    # with du through the knots' rho and 1/2) less the next steps' required DCM, which depends on the
    # footstep alone (affine: one backward pass and _Gait.start_weight, once, not per timing)
    def required(u: np.ndarray, boundary: np.ndarray) -> np.ndarray:
        B_xy = step.support[:2] + Rot @ u
        return gait.required_dcm(np.array([B_xy[0], B_xy[1], nominal[2]]), -step.side, boundary, command, n_preview)

    B0 = np.array([*(step.support[:2] + Rot @ u_nom), nominal[2]])
    D = Rot * np.array([gait.rho, 0.5])             # d boundary / du
    _, kp0, sh = gait.knots(step.support, step.p0, B0, step.t1, p.t2, p.period)   # the points at z = 0
    if n_preview == 0:                              # a stop: at rest between the feet when this step ends
        req0, J_req = kp0[-1], D
    else:
        req0 = required(u_nom, kp0[-1])
        # moving the footstep by Rot d moves every later point by the same, so the required DCM
        # too, except through the step's boundary (the next step's first ZMP point), which moves
        # by D d; the LIPM being isotropic, that point's weight is one number (_Gait.start_weight)
        J_req = Rot + gait.start_weight * (D - Rot)

    weights = np.array([params.zmp_weight] * 2 + [params.step_weight] * 2)[:n_var]
    lo = np.concatenate([lo_p, lo_u - u_nom])[:n_var]
    hi = np.concatenate([hi_p, hi_u - u_nom])[:n_var]
    # the nominal timing first: when it leaves no mismatch (undisturbed walking) no shorter swing
    # can cost less, and the other timings are not tried
    m = params.min_ssp_scale
    lams = [(step.t2 - p.t1) / ssp] if fixed_target else [1.0] + [m + (1.0 - m) * k / 4 for k in range(4)]
    best = None
    dropped = False
    # the loop in plain floats (numpy's per-call cost dominated its 2-vectors; ours): M by its columns
    xi0, xi1 = float(xi[0]), float(xi[1])
    kp = kp0.tolist()
    sh0, sh1 = float(sh[0]), float(sh[1])
    rq0, rq1 = float(req0[0]), float(req0[1])
    (d00, d01), (d10, d11) = D.tolist()
    (j00, j01), (j10, j11) = np.asarray(J_req, dtype=float).tolist()
    sx, sy = float(step.support[0]), float(step.support[1])
    un = u_nom.tolist()
    wl, lo_l, hi_l = weights.tolist(), lo.tolist(), hi.tolist()
    for lam in lams:
        if best is not None and best[4] < 1e-4 and lam < 1.0:
            break
        if best is not None and params.timing_weight * (1.0 - lam) ** 2 >= best[0]:
            continue                             # its timing alone costs more than the best: it cannot win
        t2 = p.t1 + lam * ssp
        if not fixed_target and t2 < tau + 2 * dt - 1e-12:
            continue                             # the swing cannot land sooner than that
        T = t2 + tail if not fixed_target else step.T
        a, w, ws = dcm_forward_weights(tau, T, (0.0, step.t1, t2, T), gait.Tc)   # _Gait.knots' times
        w = w.tolist()
        r0 = (a * xi0 + (w[0] * kp[0][0] + w[1] * kp[1][0] + w[2] * kp[2][0] + w[3] * kp[3][0]) + ws * sh0 - rq0,
              a * xi1 + (w[0] * kp[0][1] + w[1] * kp[1][1] + w[2] * kp[2][1] + w[3] * kp[3][1]) + ws * sh1 - rq1)
        mw = w[1] + w[2]
        cols = [(mw * c, mw * s), (-mw * s, mw * c)]
        if not fixed_target:
            cols += [(w[3] * d00 - j00, w[3] * d10 - j10), (w[3] * d01 - j01, w[3] * d11 - j11)]
        H = [[2.0 * (ci[0] * cj[0] + ci[1] * cj[1] + (wl[i] if i == j else 0.0)) for j, cj in enumerate(cols)]
             for i, ci in enumerate(cols)]
        g = [2.0 * (ci[0] * r0[0] + ci[1] * r0[1]) for ci in cols]
        z = solve_box_qp(H, g, lo_l, hi_l).tolist()
        r = (r0[0] + sum(col[0] * zj for col, zj in zip(cols, z)), r0[1] + sum(col[1] * zj for col, zj in zip(cols, z)))
        u0, u1 = (un[0], un[1]) if fixed_target else (un[0] + z[2], un[1] + z[3])
        B_xy = (sx + (c * u0 - s * u1), sy + (s * u0 + c * u1))
        if swing_pose is not None and tau >= step.t1 and not fixed_target:
            remaining = t2 - tau
            if remaining <= 0 or math.hypot(B_xy[0] - float(swing_pose[0]),
                                            B_xy[1] - float(swing_pose[1])) / remaining > params.foot_speed:
                dropped = True
                continue
        cost = (r[0] * r[0] + r[1] * r[1]) + sum(wi * zi * zi for wi, zi in zip(wl, z)) \
            + params.timing_weight * (1.0 - lam) ** 2
        if best is None or cost < best[0]:
            best = (cost, np.array(B_xy), lam, np.array(z), math.sqrt(r[0] * r[0] + r[1] * r[1]))
    if best is None:                              # no lambda meets the servo speed: keep the step as it is
        return step.target.copy(), (step.t2 - p.t1) / ssp, step.offset.copy(), \
            {"residual": float("nan"), "kept": True, "binds": ("speed",)}
    _, B_xy, lam, z, res = best
    at = (np.abs(z - lo) < 1e-9) | (np.abs(z - hi) < 1e-9)
    binds = tuple(name for name, hit in (("reach", bool(at[2:].any())), ("sole", bool(at[:2].any())),
                                         ("timing", lam < 1.0 - 1e-9 and not fixed_target),
                                         ("speed", dropped)) if hit)
    return np.array([B_xy[0], B_xy[1], nominal[2]]), float(lam), z[:2].copy(), \
        {"residual": res, "kept": False, "binds": binds}
