"""The linear inverted pendulum with a piecewise-linear ZMP, in closed form, for online planning (ours).

The TLIPFM paper's CoM (eqs 15-26) is the LIPM x'' = (x - p(t) - s) / T_c^2 per horizontal axis,
with T_c its natural period (``tlipfm.pendulum_constants``: LIPM, DLIPM or TLIPFM), p the ZMP and
s the flywheel's constant ZMP shift. Within a ZMP segment p(t) = p_i + k_i (t - t_i),
u = x - p - s obeys u'' = u / T_c^2, so

    x(t) = p(t) + s + (x_i - p_i - s) cosh(d / T_c) + T_c (v_i - k_i) sinh(d / T_c)
    v(t) = k_i + (x_i - p_i - s) sinh(d / T_c) / T_c + (v_i - k_i) cosh(d / T_c),    d = t - t_i,

and the divergent component of motion xi = x + T_c x' (the capture point, DCM) obeys
xi(t) = p(t) + s + T_c k_i + (xi_i - p_i - s - T_c k_i) e^{d / T_c}. :func:`propagate` and
:func:`dcm_forward` carry a state across any number of segments exactly; :func:`dcm_backward`
runs the DCM back from a step's end (exact for linear segments, the table generator's bounded
solution). Everything is 2-D (both horizontal axes at once: the LIPM is isotropic, so turning
walks are the same per world axis). These are the same closed forms as ``gaits/tlipfm.py``
(eqs 23-26), written for a state that starts anywhere inside a step, as an online planner needs.

A ZMP profile is ``knots``: times (m,) increasing and points (m, 2), linear between knots and
held after the last.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["propagate", "dcm_forward", "dcm_forward_weights", "dcm_backward", "zmp_at", "solve_box_qp"]

_KKT_TOL = 1e-10


def _segment(knot_t: np.ndarray, knot_p: np.ndarray, t: float) -> int:
    """Index of the segment [t_i, t_{i+1}) holding t (the last one past the end)."""
    i = int(np.searchsorted(knot_t, t, side="right")) - 1
    return min(max(i, 0), len(knot_t) - 2)


def zmp_at(knot_t: np.ndarray, knot_p: np.ndarray, t: float) -> np.ndarray:
    """The ZMP (2,) at time t of a piecewise-linear profile (held beyond its ends)."""
    if t <= knot_t[0]:
        return knot_p[0].copy()
    if t >= knot_t[-1]:
        return knot_p[-1].copy()
    i = _segment(knot_t, knot_p, t)
    f = (t - knot_t[i]) / (knot_t[i + 1] - knot_t[i])
    return knot_p[i] + f * (knot_p[i + 1] - knot_p[i])


def _slope(knot_t: np.ndarray, knot_p: np.ndarray, i: int) -> np.ndarray:
    dt = knot_t[i + 1] - knot_t[i]
    return (knot_p[i + 1] - knot_p[i]) / dt if dt > 0 else np.zeros(2)


def _pieces(kt: list, t0: float, t1: float):
    """(start, end, i) of every piece of [t0, t1] (floats): i the knot segment it lies in, or -1
    past the last knot (the ZMP held there). Before the first knot the first segment extends."""
    m = len(kt)
    t = t0
    i = 0
    while i < m - 2 and kt[i + 1] <= t:
        i += 1
    while t < t1 - 1e-12:
        if t >= kt[-1]:
            yield t, t1, -1
            return
        while i < m - 2 and kt[i + 1] <= t:
            i += 1
        end = min(t1, kt[i + 1])
        yield t, end, i
        t = end
        if end >= kt[i + 1] and i < m - 2:
            i += 1


def _segments(knot_t: np.ndarray, knot_p: np.ndarray, t0: float, t1: float):
    """(start, end, p at start (x, y), slope (x, y)) of every piece of [t0, t1] (floats)."""
    kt = knot_t.tolist() if hasattr(knot_t, "tolist") else list(knot_t)
    kp = knot_p.tolist() if hasattr(knot_p, "tolist") else [list(v) for v in knot_p]
    for t, end, i in _pieces(kt, t0, t1):
        if i < 0:
            yield t, end, kp[-1][0], kp[-1][1], 0.0, 0.0
            continue
        dt = kt[i + 1] - kt[i]
        kx = (kp[i + 1][0] - kp[i][0]) / dt if dt > 0 else 0.0
        ky = (kp[i + 1][1] - kp[i][1]) / dt if dt > 0 else 0.0
        yield t, end, kp[i][0] + kx * (t - kt[i]), kp[i][1] + ky * (t - kt[i]), kx, ky


def propagate(x: np.ndarray, v: np.ndarray, t0: float, t1: float, knot_t: np.ndarray, knot_p: np.ndarray,
              shift: np.ndarray, Tc: float) -> tuple[np.ndarray, np.ndarray]:
    """The CoM state (x, v) (2,) at t1 from the state at t0 <= t1 (closed form, segment by segment).
    Beyond the profile's last knot the ZMP is held."""
    xx, xy = float(x[0]), float(x[1])
    vx, vy = float(v[0]), float(v[1])
    sx, sy = float(shift[0]), float(shift[1])
    for a, b, px, py, kx, ky in _segments(knot_t, knot_p, t0, t1):
        d = b - a
        ch, sh = math.cosh(d / Tc), math.sinh(d / Tc)
        ux, uy = xx - px - sx, xy - py - sy
        xx, vx = px + kx * d + sx + ux * ch + Tc * (vx - kx) * sh, kx + ux * sh / Tc + (vx - kx) * ch
        xy, vy = py + ky * d + sy + uy * ch + Tc * (vy - ky) * sh, ky + uy * sh / Tc + (vy - ky) * ch
    return np.array([xx, xy]), np.array([vx, vy])


def dcm_forward(xi: np.ndarray, t0: float, t1: float, knot_t: np.ndarray, knot_p: np.ndarray,
                shift: np.ndarray, Tc: float) -> np.ndarray:
    """The DCM (2,) at t1 from the DCM at t0 <= t1."""
    ex, ey = float(xi[0]), float(xi[1])
    sx, sy = float(shift[0]), float(shift[1])
    for a, b, px, py, kx, ky in _segments(knot_t, knot_p, t0, t1):
        d = b - a
        e = math.exp(d / Tc)
        ex = px + kx * d + sx + Tc * kx + (ex - px - sx - Tc * kx) * e
        ey = py + ky * d + sy + Tc * ky + (ey - py - sy - Tc * ky) * e
    return np.array([ex, ey])


def dcm_forward_weights(t0: float, t1: float, knot_t: np.ndarray, Tc: float) -> tuple[float, np.ndarray, float]:
    """(a, w (m,), w_s): :func:`dcm_forward` as the linear map it is,
    xi(t1) = a xi(t0) + sum_i w_i p_i + w_s s, for the profile's knot times and any points p_i
    and shift s (the same weights on both axes: the LIPM is isotropic). Per piece of length d
    starting where the ZMP is p_a with slope k, xi <- e xi + (1 - e)(p_a + s + T_c k) + k d,
    e = e^{d / T_c}; p_a and k are linear in the piece's two knots. The step adjustment uses it
    for the columns of its affine DCM mismatch (ours)."""
    kt = knot_t.tolist() if hasattr(knot_t, "tolist") else list(knot_t)
    a, ws = 1.0, 0.0
    w = [0.0] * len(kt)
    for t, end, i in _pieces(kt, t0, t1):
        d = end - t
        e = math.exp(d / Tc)
        a, ws = a * e, ws * e + (1.0 - e)
        w = [wi * e for wi in w]
        dt = kt[i + 1] - kt[i] if i >= 0 else 0.0
        if dt > 0:
            f = (t - kt[i]) / dt
            c_k = ((1.0 - e) * Tc + d) / dt
            w[i] += (1.0 - e) * (1.0 - f) - c_k
            w[i + 1] += (1.0 - e) * f + c_k
        else:                                    # a held point: past the end, or a zero-length segment
            w[i] += 1.0 - e
    return a, np.array(w), ws


def dcm_backward(xi_end: np.ndarray, knot_t: np.ndarray, knot_p: np.ndarray, shift: np.ndarray,
                 Tc: float) -> np.ndarray:
    """The DCM (2,) at the profile's first knot that reaches ``xi_end`` at its last knot."""
    ex, ey = float(xi_end[0]), float(xi_end[1])
    sx, sy = float(shift[0]), float(shift[1])
    kt = knot_t.tolist() if hasattr(knot_t, "tolist") else list(knot_t)
    kp = knot_p.tolist() if hasattr(knot_p, "tolist") else [list(v) for v in knot_p]
    for i in range(len(kt) - 2, -1, -1):
        d = kt[i + 1] - kt[i]
        if d <= 0:
            continue
        kx, ky = (kp[i + 1][0] - kp[i][0]) / d, (kp[i + 1][1] - kp[i][1]) / d
        e = math.exp(-d / Tc)
        # xi(t1) = p1 + s + Tc k + (xi(t0) - p0 - s - Tc k) e^{d/Tc}
        ex = kp[i][0] + sx + Tc * kx + (ex - kp[i + 1][0] - sx - Tc * kx) * e
        ey = kp[i][1] + sy + Tc * ky + (ey - kp[i + 1][1] - sy - Tc * ky) * e
    return np.array([ex, ey])


def _solve_small(A: list, b: list) -> list:
    """x with A x = b for a small dense A (lists of floats): Gaussian elimination with partial
    pivoting (LAPACK's dgesv does the same). Raises ``np.linalg.LinAlgError`` on an exactly
    singular A, as ``np.linalg.solve`` does."""
    n = len(b)
    M = [list(row) + [bi] for row, bi in zip(A, b)]
    for k in range(n):
        piv = max(range(k, n), key=lambda i: abs(M[i][k]))
        if M[piv][k] == 0.0:
            raise np.linalg.LinAlgError("Singular matrix")
        if piv != k:
            M[k], M[piv] = M[piv], M[k]
        rk, d = M[k], M[k][k]
        for i in range(k + 1, n):
            ri = M[i]
            f = ri[k] / d
            if f:
                for j in range(k + 1, n + 1):
                    ri[j] -= f * rk[j]
    x = [0.0] * n
    for i in range(n - 1, -1, -1):
        ri = M[i]
        acc = ri[n]
        for j in range(i + 1, n):
            acc -= ri[j] * x[j]
        x[i] = acc / ri[i]
    return x


def solve_box_qp(H: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray, iterations: int = 50) -> np.ndarray:
    """argmin 1/2 u^T H u + g^T u over the box lo <= u <= hi, H positive definite (any small n).

    The primal active-set method (Nocedal and Wright, Numerical Optimization, 16.3) with the
    bounds as constraints: from a feasible point, step to the minimiser on the variables not held
    at a bound, stopping at the first bound met (which joins the held set); at a minimiser of the
    held set, release the bound whose multiplier is most negative, or stop when none is
    (the KKT conditions hold). Exact, and finite for a convex QP; the tests check it against
    scipy's bounded minimiser and against every active set tried in turn. In plain floats (the
    engine solves up to five at a step's start, n = 4: numpy's per-call cost dominated them).
    """
    H, g, lo, hi = (x if isinstance(x, list) else np.asarray(x, dtype=float).tolist() for x in (H, g, lo, hi))
    n = len(g)
    rng = range(n)

    def gradient(u: list) -> list:
        return [sum(H[i][j] * u[j] for j in rng) + g[i] for i in rng]

    u = _solve_small(H, [-x for x in g])        # the unconstrained minimiser: the answer when feasible
    if all(lo[i] <= u[i] <= hi[i] for i in rng):
        return np.array(u)
    u = [min(max(0.0, lo[i]), hi[i]) for i in rng]
    held = [u[i] <= lo[i] or u[i] >= hi[i] for i in rng]     # the bounds the start point sits on
    at_hi = [held[i] and u[i] >= hi[i] and not u[i] <= lo[i] for i in rng]
    for _ in range(iterations):
        free = [i for i in rng if not held[i]]
        step = [0.0] * n
        if free:
            grad = gradient(u)
            sub = _solve_small([[H[i][j] for j in free] for i in free], [-grad[i] for i in free])
            for k, i in enumerate(free):
                step[i] = sub[k]
        if max(abs(x) for x in step) < 1e-14:
            grad = gradient(u)
            # >= 0 for a bound that should stay; the free variables' not counted
            mult = [(-grad[i] if at_hi[i] else grad[i]) if held[i] else math.inf for i in rng]
            i = min(rng, key=mult.__getitem__)
            if mult[i] >= -_KKT_TOL:
                return np.array(u)
            held[i] = False
            continue
        alpha, block = 1.0, -1
        for i in free:
            if step[i] < 0 and u[i] + step[i] < lo[i]:
                a_i = (lo[i] - u[i]) / step[i]
            elif step[i] > 0 and u[i] + step[i] > hi[i]:
                a_i = (hi[i] - u[i]) / step[i]
            else:
                continue
            if a_i < alpha:
                alpha, block = a_i, i
        u = [min(max(u[i] + alpha * step[i], lo[i]), hi[i]) for i in rng]
        if block >= 0:
            held[block] = True
            at_hi[block] = step[block] > 0
            u[block] = hi[block] if at_hi[block] else lo[block]
    return np.array(u)
