"""The CasADi seed: ZMP-tracking optimal control with the TLIPFM timing and ZMP shape as decision variables.

Problem (one footstep plan: ``n_steps`` steps of length S_L, half width S_W,
standing before and after). Decision variables: the gait parameters
theta = (T, t1, t2, a, d) of the natural ZMP (Wong et al. eqs 9-11; d = d_1,
d_2 = S_L - d so the reference stays continuous), and, at every knot, the CoM
state (x, x', y, y') and the ZMP p = (p_x, p_y). Knots are laid per phase
(n1 in the first double support, n2 in single support, n3 in the second
double support), so their spacing follows t1, t2 and T.

* Dynamics: the pendulum of ``gaits.tlipfm`` (LIPM, DLIPM or TLIPFM constants,
  flywheel torque as a ZMP shift), integrated *exactly* between knots for a
  ZMP linear between them (the closed form of eqs 23-24):
  the block ``lipm_interval``.
* ZMP inside the support polygon, with a margin: the sole in single support,
  the box spanning both soles in double support (hard constraints).
* Cost, each term physical:
  - ZMP tracking of the natural reference (``natural_zmp_knots``), so that the
    solution is a TLIPFM gait;
  - CoM acceleration squared (= (x - p)^2 / T_TF^4: the ankle torque needed,
    divided by m g), so the timing has something to trade;
  - the ZMP's distance from the support polygon's centre (a margin term);
  - regularisation of theta to the paper's values (Table 2), scaled by their
    ranges: the tracking and torque terms alone are flat in some timing
    directions (the optimum would sit on a bound, two timings tie).
* Start and end at rest, the CoM over the ZMP.

The solver is built once (``SeedProblem``) and solved many times with other
step lengths, widths and reference values; ``solve`` re-simulates the optimal
CoM with ``gaits.tlipfm.com_closed_form`` and reports the gap, and reports an
infeasible plan with the constraint that binds.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

import gaits
from gaits import TlipfmParams
from gaits import tlipfm as tl

__all__ = ["SWING_CLEARANCE_MARGIN", "SeedProblem", "SeedResult", "SeedInfeasible", "THETA_NAMES", "lipm_interval_function",
           "natural_zmp_function"]

THETA_NAMES = ("period", "t1", "t2", "a", "d")
THETA_SCALE = np.array([0.2, 0.05, 0.1, 0.004, 0.005])      # regularisation ranges [s, s, s, m, m]


class SeedInfeasible(RuntimeError):
    """The plan admits no gait: the message names the constraint that binds most."""


def lipm_interval_function(T: float) -> ca.Function:
    """Named block ``lipm_interval``: (x0, v0, p0, p1, h) -> (x1, v1), exact for a ZMP linear in [0, h].

    x'' = (x - p) / T^2, p(s) = p0 + (p1 - p0) s / h (eq 12 with the flywheel term
    folded into p); the closed form is eqs 23-24 over one segment.
    """
    x0, v0, p0, p1, h = (ca.SX.sym(n) for n in ("x0", "v0", "p0", "p1", "h"))
    ch, sh = ca.cosh(h / T), ca.sinh(h / T)
    k = (p1 - p0) / h
    x1 = x0 * ch + v0 * T * sh + p0 * (1 - ch) + k * (h - T * sh)
    v1 = x0 / T * sh + v0 * ch - p0 / T * sh + k * (1 - ch)
    return ca.Function("lipm_interval", [x0, v0, p0, p1, h], [x1, v1],
                       ["x0", "v0", "p0", "p1", "h"], ["x1", "v1"])


@dataclass(frozen=True)
class _Layout:
    n_steps: int
    n1: int
    n2: int
    n3: int
    n_pre: int
    n_post: int

    @property
    def per_step(self) -> int:
        return self.n1 + self.n2 + self.n3

    @property
    def n_knots(self) -> int:
        return self.n_pre + self.n_steps * self.per_step + self.n_post + 1


def natural_zmp_function(layout: _Layout, first_support: int, t_stand: float) -> ca.Function:
    """Named block ``natural_zmp_knots``: (theta, S_L, S_W) -> knot times, p_x ref, p_y ref, phase.

    The natural ZMP of eqs 10-11 at every knot (d_1 = 0 on the first step and
    d_2 = 0 on the last, as ``gaits.tlipfm``), with ``t_stand`` of standing before
    and after. ``phase`` is +-1 in single support (the support side), 0 otherwise.
    """
    th = ca.SX.sym("theta", 5)
    sl, sw = ca.SX.sym("S_L"), ca.SX.sym("S_W")
    T, t1, t2, a, d = (th[i] for i in range(5))
    times, px, py, phase = [], [], [], []
    t_now = 0.0
    for _ in range(layout.n_pre):
        times.append(t_now)
        px.append(0.0)
        py.append(0.0)
        phase.append(0)
        t_now = t_now + t_stand / layout.n_pre
    for n in range(layout.n_steps):
        pcx = sl * n
        pcy = first_support * sw * (1 if n % 2 == 0 else -1)
        d1 = 0.0 if n == 0 else d
        d2 = 0.0 if n == layout.n_steps - 1 else sl - d
        side = 1 if (first_support * (1 if n % 2 == 0 else -1)) > 0 else -1
        for (dur, m, xa, xb, ya, yb, ph) in (
                (t1, layout.n1, pcx - d1, pcx - a, 0.0, pcy, 0),
                (t2 - t1, layout.n2, pcx - a, pcx + a, pcy, pcy, side),
                (T - t2, layout.n3, pcx + a, pcx + d2, pcy, 0.0, 0)):
            for j in range(m):
                u = j / m
                times.append(t_now)
                px.append(xa + (xb - xa) * u)
                py.append(ya + (yb - ya) * u)
                phase.append(ph)
                t_now = t_now + dur / m
    last_x = sl * (layout.n_steps - 1)
    for _ in range(layout.n_post + 1):
        times.append(t_now)
        px.append(last_x)
        py.append(0.0)
        phase.append(0)
        t_now = t_now + t_stand / layout.n_post
    return ca.Function("natural_zmp_knots", [th, sl, sw],
                       [ca.vertcat(*times), ca.vertcat(*px), ca.vertcat(*py), ca.DM(phase)],
                       ["theta", "S_L", "S_W"], ["t", "px_ref", "py_ref", "phase"])


@dataclass
class SeedResult:
    """The optimal gait parameters, the trajectory behind them and how they were obtained."""

    theta: dict[str, float]
    tlipfm: TlipfmParams
    t: np.ndarray            # (K,) knot times [s]
    com: np.ndarray          # (K, 2) [m]
    zmp: np.ndarray          # (K, 2) [m]
    zmp_ref: np.ndarray      # (K, 2) [m]
    cost: float
    solve_time: float        # [s] the IPOPT call alone
    iterations: int
    resim_gap: float         # [m] max |CoM - closed-form re-simulation of the optimal ZMP|
    min_margin: float        # [m] smallest distance of the ZMP to its support-polygon edge
    meta: dict = field(default_factory=dict)


class SeedProblem:
    """Build the NLP once for a plan layout and model; ``solve`` it for many plans."""

    def __init__(self, base: TlipfmParams = TlipfmParams(), *, n_steps: int = 6, n1: int = 3,
                 n2: int = 6, n3: int = 3, t_stand: float = 0.6, n_stand: int = 6,
                 foot: tuple[float, float] = (0.10, 0.06), margin: float = 0.01,
                 weights: dict | None = None) -> None:
        t0 = time.perf_counter()
        if not 0 <= margin < min(foot) / 2:
            raise ValueError(f"ZMP margin {margin} m leaves no room in a {foot[0]} x {foot[1]} m sole")
        self.base = base
        self.layout = _Layout(n_steps, n1, n2, n3, n_stand, n_stand)
        self.t_stand = t_stand
        self.foot = foot
        self.margin = margin
        # weights: track the natural ZMP closely; trade CoM acceleration (ankle torque) and the
        # ZMP's distance from the sole centre against staying near the paper's timing
        self.w = {"track": 1000.0, "acc": 0.2, "centre": 10.0, "reg": 0.1}
        self.w.update(weights or {})
        const = tl.pendulum_constants(base)
        self.T_TF, self.shift = const.T, const.zmp_shift
        self.interval = lipm_interval_function(self.T_TF)
        self.zmp_ref = natural_zmp_function(self.layout, base.first_support, t_stand)
        self._phase = np.array(self.zmp_ref(np.array([0.64, 0.15, 0.49, 0.004, 0.01]), 0.02, 0.045)[3]).ravel()
        self._build()
        self.build_time = time.perf_counter() - t0

    # --- the NLP ------------------------------------------------------------------
    def _build(self) -> None:
        L = self.layout
        K = L.n_knots
        theta = ca.SX.sym("theta", 5)
        X = ca.SX.sym("X", 4, K)            # x, x', y, y'
        P = ca.SX.sym("P", 2, K)            # ZMP
        par = ca.SX.sym("par", 7)           # S_L, S_W, theta0 (5)
        sl, sw, theta0 = par[0], par[1], par[2:7]
        t, pxr, pyr, _ = self.zmp_ref(theta, sl, sw)
        phase = self._phase
        g, lbg, ubg, names = [], [], [], []

        def add(expr, lo, hi, name):
            g.append(expr)
            lbg.append(lo)
            ubg.append(hi)
            names.append(name)

        half_l, half_w = self.foot[0] / 2 - self.margin, self.foot[1] / 2 - self.margin
        J = 0
        shift = self.shift
        for k in range(K - 1):
            h = t[k + 1] - t[k]
            for ax in (0, 1):
                s = shift if ax == 0 else 0.0
                x1, v1 = self.interval(X[2 * ax, k], X[2 * ax + 1, k], P[ax, k] + s, P[ax, k + 1] + s, h)
                add(X[2 * ax, k + 1] - x1, 0, 0, f"dynamics {'xy'[ax]} at knot {k}")
                add(X[2 * ax + 1, k + 1] - v1, 0, 0, f"dynamics {'xy'[ax]}' at knot {k}")
            acc_x = (X[0, k] - P[0, k] - shift) / self.T_TF ** 2
            acc_y = (X[2, k] - P[1, k]) / self.T_TF ** 2
            J += h * (self.w["track"] * ((P[0, k] - pxr[k]) ** 2 + (P[1, k] - pyr[k]) ** 2)
                      + self.w["acc"] * (acc_x ** 2 + acc_y ** 2))
        # support polygon, knot by knot
        step_of = self._step_of_knot()
        for k in range(K):
            n = step_of[k]
            if phase[k] != 0:
                cx = sl * n
                cy = float(phase[k]) * sw
                add(P[0, k] - cx, -half_l, half_l, f"ZMP outside the support sole (x) in step {n}")
                add(P[1, k] - cy, -half_w, half_w, f"ZMP outside the support sole (y) in step {n}")
                J += self.w["centre"] * ((P[0, k] - cx) ** 2 + (P[1, k] - cy) ** 2) * 0.01
            else:
                # double support: inside the box spanning the soles of steps n-1, n and n+1
                xs = [sl * max(n - 1, 0), sl * n, sl * min(n + 1, L.n_steps - 1)]
                add(P[0, k] - ca.fmin(ca.fmin(xs[0], xs[1]), xs[2]), -half_l, ca.inf,
                    f"ZMP behind both soles (double support, step {n})")
                add(P[0, k] - ca.fmax(ca.fmax(xs[0], xs[1]), xs[2]), -ca.inf, half_l,
                    f"ZMP ahead of both soles (double support, step {n})")
                add(P[1, k] - sw, -ca.inf, half_w, f"ZMP left of both soles (double support, step {n})")
                add(P[1, k] + sw, -half_w, ca.inf, f"ZMP right of both soles (double support, step {n})")
        # timing sanity: phases no shorter than a few ticks
        add(theta[1], 0.05, ca.inf, "t1 >= 0.05 s (first double support)")
        add(theta[2] - theta[1], 0.15, ca.inf, "t2 - t1 >= 0.15 s (single support)")
        add(theta[0] - theta[2], 0.05, ca.inf, "period - t2 >= 0.05 s (second double support)")
        add(theta[4], 0.0, ca.inf, "d >= 0")
        add(sl - theta[4], 0.0, ca.inf, "d <= S_L")
        # rest at both ends
        for ax in (0, 1):
            add(X[2 * ax, 0] - P[ax, 0] - (shift if ax == 0 else 0.0), 0, 0, f"start at rest ({'xy'[ax]})")
            add(X[2 * ax + 1, 0], 0, 0, f"start at rest ({'xy'[ax]}')")
            add(X[2 * ax + 1, K - 1], 0, 0, f"end at rest ({'xy'[ax]}')")
            add(X[2 * ax, K - 1] - P[ax, K - 1] - (shift if ax == 0 else 0.0), 0, 0, f"end at rest ({'xy'[ax]})")
        J += self.w["reg"] * ca.sumsqr((theta - theta0) / THETA_SCALE)
        z = ca.vertcat(theta, ca.vec(X), ca.vec(P))
        self._K = K
        self._names = names
        self._lbg = np.array(lbg, dtype=float)
        self._ubg = np.array(ubg, dtype=float)
        nlp = {"x": z, "p": par, "f": J, "g": ca.vertcat(*g)}
        opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                "ipopt.max_iter": 300, "ipopt.tol": 1e-8}
        self.solver = ca.nlpsol("tlipfm_seed", "ipopt", nlp, opts)
        nz = z.shape[0]
        self._lbx = -np.inf * np.ones(nz)
        self._ubx = np.inf * np.ones(nz)
        self._lbx[:5] = [0.4, 0.02, 0.1, 0.0, 0.0]
        self._ubx[:5] = [1.2, 0.6, 1.15, 0.02, 0.05]
        self.cost_terms = ca.Function("seed_cost", [z, par], [J], ["z", "par"], ["J"])

    def _step_of_knot(self) -> list:
        L = self.layout
        out: list = [0] * L.n_pre
        for n in range(L.n_steps):
            out += [n] * L.per_step
        out += [L.n_steps - 1] * (L.n_post + 1)
        return out

    # --- solving ------------------------------------------------------------------
    def solve(self, step_length: float | None = None, half_width: float | None = None,
              theta0: dict | None = None, bounds: dict | None = None) -> SeedResult:
        """Optimal theta for a plan; raises :class:`SeedInfeasible` naming the binding constraint.

        ``bounds`` narrows theta's box, e.g. ``{"period": (0.5, 0.7)}`` [s, m].
        """
        b = self.base
        lbx, ubx = self._lbx.copy(), self._ubx.copy()
        for name, (lo, hi) in (bounds or {}).items():
            if name not in THETA_NAMES:
                raise ValueError(f"unknown seed parameter {name!r}; expected one of {', '.join(THETA_NAMES)}")
            i = THETA_NAMES.index(name)
            lbx[i], ubx[i] = max(lbx[i], lo), min(ubx[i], hi)
            if lbx[i] > ubx[i]:
                raise SeedInfeasible(f"bounds for {name} are empty: [{lo:g}, {hi:g}] within "
                                     f"[{self._lbx[i]:g}, {self._ubx[i]:g}]")
        sl = b.step_length if step_length is None else step_length
        sw = b.half_width if half_width is None else half_width
        d0 = b.d1 * sl / b.step_length if b.step_length else sl / 2   # the paper's d_1 / S_L ratio
        th0 = {"period": b.period, "t1": b.t1, "t2": b.t2, "a": b.a, "d": d0}
        th0.update(theta0 or {})
        th0_vec = np.array([th0[n] for n in THETA_NAMES])
        par = np.r_[sl, sw, th0_vec]
        # initial guess: the paper's gait itself (its closed-form CoM at the knots)
        t, pxr, pyr, _ = (np.array(v).ravel() for v in self.zmp_ref(th0_vec, sl, sw))
        x_guess = np.zeros((4, self._K))
        x_guess[0], x_guess[2] = pxr, pyr
        p_guess = np.vstack([pxr, pyr])
        z0 = np.r_[th0_vec, x_guess.ravel(order="F"), p_guess.ravel(order="F")]
        t0 = time.perf_counter()
        z0[:5] = np.clip(z0[:5], lbx[:5], ubx[:5])
        sol = self.solver(x0=z0, p=par, lbx=lbx, ubx=ubx, lbg=self._lbg, ubg=self._ubg)
        solve_time = time.perf_counter() - t0
        stats = self.solver.stats()
        z = np.array(sol["x"]).ravel()
        g = np.array(sol["g"]).ravel()
        viol = np.maximum(self._lbg - g, 0) + np.maximum(g - self._ubg, 0)
        if not stats["success"] or viol.max() > 1e-6:
            i = int(np.argmax(viol))
            raise SeedInfeasible(f"no gait for S_L = {sl:g} m, S_W = {sw:g} m "
                                 f"({stats['return_status']}): binding constraint "
                                 f"'{self._names[i]}' violated by {viol[i]:.3g}")
        theta = dict(zip(THETA_NAMES, (float(v) for v in z[:5])))
        K = self._K
        X = z[5:5 + 4 * K].reshape(4, K, order="F")
        P = z[5 + 4 * K:].reshape(2, K, order="F")
        t, pxr, pyr, phase = (np.array(v).ravel() for v in self.zmp_ref(z[:5], sl, sw))
        gap = self._resimulate(t, X, P)
        margin = self._min_margin(P, phase, sl, sw)
        params = b.replace(step_length=sl, half_width=sw, period=theta["period"], t1=theta["t1"],
                           t2=theta["t2"], a=theta["a"], d1=theta["d"], d2=sl - theta["d"])
        return SeedResult(theta, params, t, X[[0, 2]].T, P.T, np.vstack([pxr, pyr]).T,
                          float(sol["f"]), solve_time, int(stats.get("iter_count", -1)), gap, margin,
                          {"build_time": self.build_time, "status": stats["return_status"]})

    def _resimulate(self, t: np.ndarray, X: np.ndarray, P: np.ndarray) -> float:
        """Max |CoM of the NLP - gaits.tlipfm.com_closed_form driven by the optimal ZMP| [m].

        Re-simulated step by step from each step's first knot (the pendulum is unstable:
        over the whole walk the solver's 1e-8 residuals would grow by e^(9 s / T_TF)).
        """
        L = self.layout
        starts = {0} | {L.n_pre + n * L.per_step for n in range(L.n_steps + 1)}
        worst = 0.0
        for ax in (0, 1):
            s = self.shift if ax == 0 else 0.0
            x, v = X[2 * ax, 0], X[2 * ax + 1, 0]
            for k in range(len(t) - 1):
                if k in starts:
                    x, v = X[2 * ax, k], X[2 * ax + 1, k]
                h = t[k + 1] - t[k]
                kk = (P[ax, k + 1] - P[ax, k]) / h
                xs, vs = tl.com_closed_form(np.array([h]), x, v, np.array([0.0]),
                                            np.array([P[ax, k]]), np.array([kk]), self.T_TF, s)
                x, v = float(xs[0]), float(vs[0])
                worst = max(worst, abs(x - X[2 * ax, k + 1]))
        return worst

    def _min_margin(self, P: np.ndarray, phase: np.ndarray, sl: float, sw: float) -> float:
        steps = self._step_of_knot()
        m = np.inf
        for k, ph in enumerate(phase):
            if ph != 0:
                dx = self.foot[0] / 2 - abs(P[0, k] - sl * steps[k])
                dy = self.foot[1] / 2 - abs(P[1, k] - ph * sw)
                m = min(m, dx, dy)
        return float(m)


#: [m] how far above the tallest surface layer the seed lifts the swing foot (ours)
SWING_CLEARANCE_MARGIN = 0.01


def _clear_layer(params: gaits.GaitParams, layer_height: float) -> gaits.GaitParams:
    """``params`` with the swing foot lifted ``SWING_CLEARANCE_MARGIN`` over the layer
    (never lowered; clipped to the family's own bound for its lift)."""
    if layer_height <= 0:
        return params
    name = gaits.family(params.FAMILY).lift_field
    hi = next(f.metadata["hi"] for f in dataclasses.fields(params) if f.name == name)
    lift = min(layer_height + SWING_CLEARANCE_MARGIN, hi)
    return params.replace(**{name: lift}) if lift > getattr(params, name) else params


def seed_for(family: str, base: gaits.GaitParams, problem: SeedProblem | None = None,
             layer_height: float = 0.0) -> gaits.GaitParams:
    """The CasADi seed mapped onto a family's parameters (TLIPFM directly; EROS and cosine by
    correspondence: the family's ``from_seed`` in ``gaits/families.py``).

    ``layer_height`` [m] is the tallest carpet or grass layer the gait must walk on. The
    CoM problem says nothing about the swing foot, but a foot that stays inside the
    blades is held by them (the EROS paper's failure; ``tuner.surfaces``), so the seed
    lifts the foot to the layer height plus ``SWING_CLEARANCE_MARGIN`` when the base
    lifts it less. Measured on grass50 (TLIPFM seed at 24 mm steps): a 20-40 mm lift
    stays up but covers 11-67% of the plan, 50-60 mm covers all of it.
    """
    if layer_height < 0:
        raise ValueError(f"layer_height must be >= 0 m, got {layer_height!r}")
    fam = gaits.family(family)
    if not isinstance(base, fam.params_class):
        raise ValueError(f"seed_for({family!r}): the base holds {base.FAMILY!r} parameters")
    problem = problem or SeedProblem(base if fam.seed_on_own_masses else TlipfmParams())
    step_length, half_width = fam.seed_inputs(base)
    res = problem.solve(step_length, half_width)
    sway = float(np.max(np.abs(res.com[:, 1])))
    return _clear_layer(fam.from_seed(res.tlipfm, sway, base), layer_height)
