"""A leg as its robot file builds it, and a numerical IK for it (ours, not the papers').

The papers' IKs (``leg_kinematics``) are closed forms for ideal legs: the hip's three axes meet at
one point, the knee and the ankle lie straight below it at the zero pose, the ankle's two axes
meet. Many team robots are built otherwise (a hip yaw axis beside the hip centre, legs bent at the
zero pose, a tilted ankle axis). For those, :class:`LegChain` holds the leg's six joint axes as
the robot file has them at the zero pose, each a unit axis ``u_i`` through a point ``a_i`` in the
pelvis frame (our joints' signs: positive knee flexion, toes down for positive ankle pitch), and
the sole's frame ``M`` at the zero pose; the forward kinematics is the product of exponentials

    T_pelvis_sole(q) = exp([S_1] q_1) ... exp([S_6] q_6) M,   S_i = (u_i, -u_i x a_i)

(Lynch & Park, Modern Robotics, eq 4.14), its factors in the order the file builds the leg from the
pelvis (``order``: a hip that turns roll first, then yaw, as some robots' do, composes so; the
joints keep our names and our order everywhere else), and :meth:`LegChain.solve` the inverse: damped Newton
steps (Levenberg-Marquardt, the geometric Jacobian in the pelvis frame, the rotation error as the
log map's axis-angle) from a warm start, the last tick's solution. Pure numpy, scalar and small:
it runs on the robot. The sole point is the closed form's: ``ankle_height`` below the ankle centre
(the closest point between the ankle's two axes), so a caller's offsets mean the same for both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["LegChain", "LegChains", "IKNotConverged"]

_TOL = 1e-10          # [m + rad] error at which the Newton steps stop
_FLOOR = 1e-8         # [m + rad] below this a step that does not improve is the rounding floor: stop
_ACCEPT = 1e-6        # [m, rad] an answer further than this from the target is no solution


class IKNotConverged(ValueError):
    """The target is out of the leg's reach (or the Newton steps did not reach it): ``best`` holds
    the joints of the closest pose found, ``error`` its distance [m + rad]."""

    def __init__(self, message: str, best: np.ndarray, error: float) -> None:
        super().__init__(message)
        self.best = best
        self.error = error


def _log_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation vector (axis times angle) of ``R`` (3,)."""
    c = (R[0, 0] + R[1, 1] + R[2, 2] - 1.0) / 2.0
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s = 0.5 * math.sqrt(float(v @ v))
    angle = math.atan2(s, max(min(c, 1.0), -1.0))
    if s < 1e-9:
        if c > 0:                               # near identity: the first-order term
            return 0.5 * v
        # near pi: the axis from the symmetric part
        B = (R + np.eye(3)) / 2.0
        axis = B[:, int(np.argmax(np.diag(B)))]
        return math.pi * axis / np.linalg.norm(axis)
    return v * (angle / (2.0 * s))


@dataclass(frozen=True)
class LegChain:
    """One leg's joints (hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll) as the robot
    file has them at the zero pose, in the pelvis frame, our joints' signs (module docstring).

    ``axes`` and ``points`` (6 x 3): each joint's unit axis and a point on it [m]; ``sole`` (3,)
    [m] and ``sole_rotation`` (3 x 3, rows) the sole frame at the zero pose (its point
    ``ankle_height`` below the ankle centre, its z the sole's normal)."""

    axes: tuple
    points: tuple
    sole: tuple
    sole_rotation: tuple
    sole_offset: tuple = (0.0, 0.0, 0.0)   # [m] the sole's centre from ``sole``, in the sole's axes (this
    #                                        leg's own: a robot's two feet need not mirror each other)
    order: tuple = (0, 1, 2, 3, 4, 5)       # the joints (indices in our order) from the pelvis to the foot:
    #                                        a leg built hip roll, hip yaw, hip pitch, ... is (1, 0, 2, 3, 4, 5)

    def __post_init__(self) -> None:
        u = np.asarray(self.axes, dtype=float)
        a = np.asarray(self.points, dtype=float)
        if u.shape != (6, 3) or a.shape != (6, 3) or np.shape(self.sole) != (3,) or np.shape(self.sole_rotation) != (3, 3):
            raise ValueError("a leg chain is 6 axes and 6 points (6 x 3), a sole point (3,) and a sole rotation (3 x 3)")
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(a))):
            raise ValueError("a leg chain's axes and points must be finite")
        norms = np.linalg.norm(u, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-6):
            raise ValueError(f"a leg chain's axes must be unit vectors (norms {np.round(norms, 6).tolist()})")
        object.__setattr__(self, "axes", tuple(tuple(float(x) for x in r / n) for r, n in zip(u, norms)))
        object.__setattr__(self, "points", tuple(tuple(float(x) for x in r) for r in a))
        object.__setattr__(self, "sole", tuple(float(x) for x in self.sole))
        if np.shape(self.sole_offset) != (3,) or not np.all(np.isfinite(self.sole_offset)):
            raise ValueError("a leg chain's sole offset is 3 finite numbers [m]")
        object.__setattr__(self, "sole_offset", tuple(float(x) for x in self.sole_offset))
        object.__setattr__(self, "sole_rotation", tuple(tuple(float(x) for x in r) for r in np.asarray(self.sole_rotation)))
        order = tuple(int(i) for i in self.order)
        if sorted(order) != list(range(6)):
            raise ValueError(f"a leg chain's order is the six joints 0-5 each once, got {list(order)}")
        object.__setattr__(self, "order", order)
        # the axes, points and joints' indices as the chain composes them, pelvis to foot
        object.__setattr__(self, "_seq", tuple((self.axes[i], self.points[i], i) for i in order))
        # the sole's point and rotation at the zero pose as plain floats (the rotation row by row)
        object.__setattr__(self, "_sole_floats", (tuple(self.sole), tuple(x for row in self.sole_rotation for x in row)))

    # --- the chain ---------------------------------------------------------------------------
    def fk(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles (6,) -> (the sole point (3,), the sole's rotation (3, 3)) in the pelvis frame."""
        p, R, _, _ = self._chain(q)
        return p, R

    def fk_many(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`fk` over leading dimensions: (..., 6) -> ((..., 3), (..., 3, 3))."""
        q = np.asarray(q, dtype=float)
        flat = q.reshape(-1, 6)
        ps = np.empty((len(flat), 3))
        Rs = np.empty((len(flat), 3, 3))
        for i, qi in enumerate(flat):
            ps[i], Rs[i] = self.fk(qi)
        return ps.reshape(q.shape[:-1] + (3,)), Rs.reshape(q.shape[:-1] + (3, 3))

    def _chain(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The sole's pose and each joint's axis and point in the pelvis frame at ``q`` (the joints
        compose in ``order``; ``q`` and the axes and points returned are in our order)."""
        p, R, axes, pts = self.chain_floats(q)
        return np.array(p), np.array(R).reshape(3, 3), np.array(axes), np.array(pts)

    def chain_floats(self, q) -> tuple[tuple, tuple, list, list]:
        """:meth:`_chain` in plain floats (the engine's estimator and servo model read it too): the sole point (3-tuple), its rotation (9-tuple, row by
        row), the axes and points (lists of 3-tuples). numpy's per-call cost dominates 3 x 3 products;
        this is the IK's inner loop."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
        px = py = pz = 0.0
        axes, pts = [None] * 6, [None] * 6
        for (ux, uy, uz), (ax, ay, az), i in self._seq:
            axes[i] = (r00 * ux + r01 * uy + r02 * uz, r10 * ux + r11 * uy + r12 * uz,
                       r20 * ux + r21 * uy + r22 * uz)
            pts[i] = (r00 * ax + r01 * ay + r02 * az + px, r10 * ax + r11 * ay + r12 * az + py,
                      r20 * ax + r21 * ay + r22 * az + pz)
            qi = float(q[i])
            sn, cs = math.sin(qi), math.cos(qi)
            v = 1.0 - cs
            # Rodrigues: Ri = I + sin K + (1 - cos) K^2, K = [u]x
            a00, a01, a02 = cs + ux * ux * v, ux * uy * v - uz * sn, ux * uz * v + uy * sn
            a10, a11, a12 = uy * ux * v + uz * sn, cs + uy * uy * v, uy * uz * v - ux * sn
            a20, a21, a22 = uz * ux * v - uy * sn, uz * uy * v + ux * sn, cs + uz * uz * v
            # the screw's translation (I - Ri) a, turned into the pelvis frame
            tx = ax - (a00 * ax + a01 * ay + a02 * az)
            ty = ay - (a10 * ax + a11 * ay + a12 * az)
            tz = az - (a20 * ax + a21 * ay + a22 * az)
            px, py, pz = (px + r00 * tx + r01 * ty + r02 * tz, py + r10 * tx + r11 * ty + r12 * tz,
                          pz + r20 * tx + r21 * ty + r22 * tz)
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
                r00 * a00 + r01 * a10 + r02 * a20, r00 * a01 + r01 * a11 + r02 * a21, r00 * a02 + r01 * a12 + r02 * a22,
                r10 * a00 + r11 * a10 + r12 * a20, r10 * a01 + r11 * a11 + r12 * a21, r10 * a02 + r11 * a12 + r12 * a22,
                r20 * a00 + r21 * a10 + r22 * a20, r20 * a01 + r21 * a11 + r22 * a21, r20 * a02 + r21 * a12 + r22 * a22)
        (mx, my, mz), M = self._sole_floats
        p = (r00 * mx + r01 * my + r02 * mz + px, r10 * mx + r11 * my + r12 * mz + py,
             r20 * mx + r21 * my + r22 * mz + pz)
        m0, m1, m2, m3, m4, m5, m6, m7, m8 = M
        R = (r00 * m0 + r01 * m3 + r02 * m6, r00 * m1 + r01 * m4 + r02 * m7, r00 * m2 + r01 * m5 + r02 * m8,
             r10 * m0 + r11 * m3 + r12 * m6, r10 * m1 + r11 * m4 + r12 * m7, r10 * m2 + r11 * m5 + r12 * m8,
             r20 * m0 + r21 * m3 + r22 * m6, r20 * m1 + r21 * m4 + r22 * m7, r20 * m2 + r21 * m5 + r22 * m8)
        return p, R, axes, pts

    def _newton_terms(self, q, pt: tuple, Rt: tuple) -> tuple[np.ndarray, np.ndarray]:
        """The error (6,) of the sole's pose at ``q`` from the target (``pt`` 3-tuple, ``Rt`` 9-tuple:
        position, then the rotation vector of Rt R^T) and the sole's Jacobian (6 x 6), in floats."""
        (px, py, pz), R, axes, pts = self.chain_floats(q)
        # E = Rt R^T, row i of Rt against row j of R
        t0, t1, t2, t3, t4, t5, t6, t7, t8 = Rt
        s0, s1, s2, s3, s4, s5, s6, s7, s8 = R
        E = (t0 * s0 + t1 * s1 + t2 * s2, t0 * s3 + t1 * s4 + t2 * s5, t0 * s6 + t1 * s7 + t2 * s8,
             t3 * s0 + t4 * s1 + t5 * s2, t3 * s3 + t4 * s4 + t5 * s5, t3 * s6 + t4 * s7 + t5 * s8,
             t6 * s0 + t7 * s1 + t8 * s2, t6 * s3 + t7 * s4 + t8 * s5, t6 * s6 + t7 * s7 + t8 * s8)
        vx, vy, vz = E[7] - E[5], E[2] - E[6], E[3] - E[1]
        c = (E[0] + E[4] + E[8] - 1.0) / 2.0
        s = 0.5 * math.sqrt(vx * vx + vy * vy + vz * vz)
        if s < 1e-9 and c > 0:                      # near identity: the first-order term
            wx, wy, wz = 0.5 * vx, 0.5 * vy, 0.5 * vz
        elif s < 1e-9:                              # near pi: the general form
            wx, wy, wz = (float(x) for x in _log_rotation(np.array(E).reshape(3, 3)))
        else:
            k = math.atan2(s, max(min(c, 1.0), -1.0)) / (2.0 * s)
            wx, wy, wz = vx * k, vy * k, vz * k
        rows = ([], [], [], [], [], [])
        for (ux, uy, uz), (ax, ay, az) in zip(axes, pts):
            dx, dy, dz = px - ax, py - ay, pz - az      # the sole point from the axis
            rows[0].append(uy * dz - uz * dy)
            rows[1].append(uz * dx - ux * dz)
            rows[2].append(ux * dy - uy * dx)
            rows[3].append(ux)
            rows[4].append(uy)
            rows[5].append(uz)
        return np.array((pt[0] - px, pt[1] - py, pt[2] - pz, wx, wy, wz)), np.array(rows)

    # --- the inverse ---------------------------------------------------------------------------
    def solve(self, p_target: np.ndarray, R_target: np.ndarray, q0: np.ndarray | None = None,
              iterations: int = 40, tol: float = _TOL, step_tol: float = 0.0) -> np.ndarray:
        """Joint angles (6,) that put the sole point at ``p_target`` (3,) with the rotation
        ``R_target`` (3, 3), in the pelvis frame, from ``q0`` (default: the zero pose; a walk passes its
        last tick's answer, so a result never depends on another walk's). Damped Newton steps (module
        docstring); raises
        :class:`IKNotConverged` with the closest pose found when it does not reach the target
        within 1e-6 (m + rad). ``tol`` [m + rad]: the error at which the steps stop (a walk's tick
        may stop sooner than the default, far below a servo's resolution); ``step_tol`` [rad]: an
        undamped step shorter than this is taken as the answer without evaluating it (Newton's error
        after a step is of the order of the step squared; 0: every answer is evaluated)."""
        p_t = np.asarray(p_target, dtype=float)
        R_t = np.asarray(R_target, dtype=float)
        q = np.zeros(6) if q0 is None else np.array(q0, dtype=float)
        best_q, best_err = q.copy(), math.inf
        lam = 1e-9
        pt = tuple(float(x) for x in p_t)
        Rt = tuple(float(x) for x in R_t.reshape(9))
        for _ in range(iterations):
            e, J = self._newton_terms(q, pt, Rt)
            err = float(math.sqrt(e @ e))
            if err < best_err:
                best_q, best_err = q.copy(), err
                lam = max(lam * 0.1, 1e-12)
                if err < tol:
                    break
            else:                                   # no better: at the rounding floor, or damp more
                if best_err < _FLOOR:
                    break
                q = best_q.copy()
                lam = max(lam * 100.0, 1e-6)
                e, J = self._newton_terms(q, pt, Rt)
            dq = None
            if lam < 1e-8:                          # (almost) undamped: Newton's step itself, J dq = e
                try:
                    dq = np.linalg.solve(J, e)
                except np.linalg.LinAlgError:       # a singular pose: the damped step below
                    dq = None
            if dq is None:
                JJ = J @ J.T
                JJ.flat[::7] += lam
                dq = J.T @ np.linalg.solve(JJ, e)
            q = q + dq
            if step_tol and lam < 1e-6 and err == best_err and float(dq @ dq) < step_tol * step_tol:
                return (q + math.pi) % (2 * math.pi) - math.pi
        q = best_q
        if best_err > _ACCEPT:
            raise IKNotConverged(f"sole target {np.round(p_t, 4).tolist()} m is out of the leg's reach (closest pose "
                                 f"{best_err * 1000:.1f} mm + mrad away)", best_q, best_err)
        return (q + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class LegChains:
    """Both legs' chains (:class:`LegChain`) and why the robot needs them: the closed form's
    assumptions it breaks, in words (``robot check`` prints it)."""

    left: LegChain
    right: LegChain
    reason: str = ""

    def side(self, side: int) -> LegChain:
        return self.left if side == 1 else self.right


def ideal_chain(leg, side: int) -> LegChain:
    """The chain of an ideal leg (``leg_kinematics.LegGeometry``'s, the closed form's): the hip's
    axes z, x, y through the hip centre, the knee and the ankle's y, x below it, the sole flat (for
    tests, and to compare the two IKs)."""
    hip = np.asarray(leg.hip_in_pelvis(side), dtype=float)
    down = np.array([0.0, 0.0, -1.0])
    knee = hip + leg.thigh * down
    ankle = knee + leg.shank * down
    x, y, z = np.eye(3)
    return LegChain(axes=(z, x, y, y, y, x), points=(hip, hip, hip, knee, ankle, ankle),
                    sole=ankle + leg.ankle_height * down, sole_rotation=np.eye(3))


def chains_to_mapping(chains: LegChains) -> dict:
    """Both chains as plain lists for a robot file (``robot_file``): per side the axes and points
    (6 x 3) and the sole point (3,); the reason beside them."""
    def one(c: LegChain) -> dict:
        return {"axes": [list(a) for a in c.axes], "points": [list(p) for p in c.points], "sole": list(c.sole),
                "sole_rotation": [list(r) for r in c.sole_rotation], "sole_offset": list(c.sole_offset),
                "order": list(c.order)}
    return {"reason": chains.reason, "left": one(chains.left), "right": one(chains.right)}


def chains_from_mapping(doc, source: str) -> LegChains:
    """:func:`chains_to_mapping`'s inverse, each field checked (a ``ParamError`` naming it)."""
    from .params import ParamError
    if not isinstance(doc, dict) or set(doc) - {"reason", "left", "right"} or not {"left", "right"} <= set(doc):
        raise ParamError(f"{source}: leg_chains: expected a mapping with left, right (and reason)")
    sides = {}
    for side in ("left", "right"):
        d = doc[side]
        if not isinstance(d, dict) or not {"axes", "points", "sole", "sole_rotation"} <= set(d) \
                or set(d) - {"axes", "points", "sole", "sole_rotation", "sole_offset", "order"}:
            raise ParamError(f"{source}: leg_chains.{side}: expected axes, points, sole, sole_rotation (and "
                             f"sole_offset, order)")
        try:
            arrays = {k: np.asarray(d[k], dtype=float) for k in d}
        except (TypeError, ValueError):
            raise ParamError(f"{source}: leg_chains.{side}: every entry must be a number [m]") from None
        arrays.setdefault("sole_offset", np.zeros(3))
        arrays.setdefault("order", np.arange(6.0))
        for k, shape in (("axes", (6, 3)), ("points", (6, 3)), ("sole", (3,)), ("sole_rotation", (3, 3)),
                         ("sole_offset", (3,)), ("order", (6,))):
            if arrays[k].shape != shape or not np.all(np.isfinite(arrays[k])):
                raise ParamError(f"{source}: leg_chains.{side}.{k}: expected {' x '.join(map(str, shape))} finite "
                                 f"numbers, got shape {arrays[k].shape}")
        try:
            if np.any(arrays["order"] != np.round(arrays["order"])):
                raise ValueError(f"order {arrays['order'].tolist()}: expected whole numbers 0-5")
            sides[side] = LegChain(**{k: arrays[k] for k in ("axes", "points", "sole", "sole_rotation", "sole_offset",
                                                             "order")})
        except ValueError as exc:
            raise ParamError(f"{source}: leg_chains.{side}: {exc}") from None
    reason = doc.get("reason", "")
    if not isinstance(reason, str):
        raise ParamError(f"{source}: leg_chains.reason = {reason!r}: expected text")
    return LegChains(sides["left"], sides["right"], reason)
