"""The engine's per-tick arithmetic in plain floats against the forms it replaced.

The forward kinematics, the estimator's Kalman step, the legs' closed-form IK and the engine's
pelvis and sole targets run every tick in plain floats (numpy's per-call cost dominates 3 x 3
products); each is checked here against the numpy form it replaced (the rotations multiplied out,
``np.linalg.inv``), on random inputs, within a few ulps: numpy's 3 x 3 products fuse multiplies
and adds, so the two differ in the last bits (tests/test_engine_reference.py holds the engine's
targets to 1e-12 rad over recorded walks). The step adjustment's box QP, in floats too, is checked
against every active set tried in turn.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from gaits.engine import CoMEstimator
from gaits.engine.estimator import _rx, _ry, _rz, sole_floats, sole_in_pelvis, sole_rate
from gaits.leg_chain import LegChains, ideal_chain
from gaits.leg_kinematics import LegGeometry, leg_fk, leg_ik_pose
from gaits.lipm import solve_box_qp

LEG = LegGeometry()
RNG = np.random.default_rng(20261207)


def _numpy_sole(q, leg, side):
    """The numpy form the plain floats replaced (the chain of ``leg_kinematics.leg_fk``)."""
    q1, q2, q3, q4, q5, q6 = q
    R = _rz(q1) @ _rx(q2) @ _ry(q3)
    p = leg.hip_in_pelvis(side) + R @ np.array([0.0, 0.0, -leg.thigh])
    R = R @ _ry(q4)
    p = p + R @ np.array([0.0, 0.0, -leg.shank])
    R = R @ _ry(q5) @ _rx(q6)
    return p + R @ np.array([0.0, 0.0, -leg.ankle_height]), R


@pytest.mark.parametrize("side", [1, -1])
def test_the_forward_kinematics_in_floats_is_the_numpy_chain(side):
    for q in RNG.uniform(-1.5, 1.5, (300, 6)):
        p, R = sole_in_pelvis(q, LEG, side)
        p_ref, R_ref = _numpy_sole(q, LEG, side)
        assert np.allclose(p, p_ref, rtol=0.0, atol=1e-15) and np.allclose(R, R_ref, rtol=0.0, atol=1e-15)
        p_fk, R_fk = leg_fk(q, LEG, side)
        assert np.allclose(p, p_fk, rtol=0.0, atol=1e-14) and np.allclose(R, R_fk, rtol=0.0, atol=1e-14)
        pf, Rf = sole_floats(q, LEG, side)
        assert type(pf[0]) is float and len(pf) == 3 and len(Rf) == 9


def test_a_chain_robots_forward_kinematics_is_its_chains():
    chained = LegGeometry(chains=LegChains(ideal_chain(LEG, 1), ideal_chain(LEG, -1), "tests"))
    for side in (1, -1):
        for q in RNG.uniform(-1.0, 1.0, (50, 6)):
            p, R = sole_in_pelvis(q, chained, side)
            p_ref, R_ref = chained.chains.side(side).fk(q)
            assert np.array_equal(p, p_ref) and np.array_equal(R, R_ref)
            assert np.allclose(p, _numpy_sole(q, LEG, side)[0], rtol=0.0, atol=1e-12)


def test_the_sole_rate_is_the_difference_along_the_rates():
    for q, dq in zip(RNG.uniform(-1.0, 1.0, (100, 6)), RNG.uniform(-3.0, 3.0, (100, 6))):
        p = sole_in_pelvis(q, LEG, 1)[0]
        want = (_numpy_sole(q + 1e-3 * dq, LEG, 1)[0] - p) / 1e-3
        assert np.allclose(sole_rate(q, dq, LEG, 1, p), want, rtol=0.0, atol=1e-11)


@pytest.mark.parametrize("velocity_noise", [0.0, 0.05])
def test_the_kalman_step_in_floats_is_the_numpy_filter(velocity_noise):
    f = CoMEstimator(0.15, 0.01, 1.0, 0.008, velocity_noise)
    f.reset(np.array([0.01, -0.02]))
    x, P = f.x.copy(), f.P.copy()
    for k in range(200):
        zmp, com, vel = RNG.normal(0, 0.05, 2), RNG.normal(0, 0.05, 2), RNG.normal(0, 0.2, 2)
        measured = None if k % 17 == 5 else com          # a dropped tick now and then: the prediction only
        f.update(zmp, measured, vel)
        # the numpy form it replaced
        x = f.A @ x + np.outer(f.B, zmp)
        P = f.A @ P @ f.A.T + f.Q
        if measured is not None and velocity_noise == 0.0:
            K = P[:, 0] / (P[0, 0] + f.R)
            x = x + np.outer(K, measured - x[0])
            P = P - np.outer(K, P[0])
        elif measured is not None:
            K = P @ np.linalg.inv(P + np.diag([f.R, f.R_v]))
            x = x + K @ (np.vstack([measured, vel]) - x)
            P = P - K @ P
        assert np.allclose(f.x, x, rtol=1e-12, atol=1e-15) and np.allclose(f.P, P, rtol=1e-12, atol=1e-18), k
    assert not np.allclose(f.x, 0.0)                      # it moved: the comparison was not of zeros


@pytest.mark.parametrize("side", [1, -1])
def test_the_closed_form_ik_in_floats_inverts_the_chain(side):
    solved = 0
    for q in RNG.uniform([-0.5, -0.3, -1.0, 0.2, -0.8, -0.3], [0.5, 0.3, 0.5, 1.8, 0.8, 0.3], (300, 6)):
        p, R = _numpy_sole(q, LEG, side)
        got = leg_ik_pose(p, R, LEG, side)
        assert np.allclose(got, q, rtol=0.0, atol=1e-9), (q, got)
        solved += 1
    assert solved == 300


def _qp_by_enumeration(H, g, lo, hi):
    """The box QP's exact minimiser by trying every variable free, at its lower or at its upper
    bound (3^n cases): each case's free variables solve their part of H u = -g; the feasible case
    of least objective is the answer (a reference independent of the active-set method)."""
    n = len(g)
    best, best_f = None, np.inf
    for case in itertools.product((0, 1, 2), repeat=n):
        u = np.where(np.array(case) == 1, lo, hi).astype(float)
        free = [i for i in range(n) if case[i] == 0]
        if free:
            fixed = [i for i in range(n) if case[i] != 0]
            rhs = -g[free] - H[np.ix_(free, fixed)] @ u[fixed]
            u[free] = np.linalg.solve(H[np.ix_(free, free)], rhs)
        if np.all(u >= lo - 1e-12) and np.all(u <= hi + 1e-12):
            f = 0.5 * u @ H @ u + g @ u
            if f < best_f:
                best, best_f = u, f
    return best


def test_the_box_qp_in_floats_is_exact():
    rng = np.random.default_rng(7)
    bound = 0
    for _ in range(300):
        n = int(rng.integers(1, 5))
        A = rng.normal(size=(n + 2, n))
        H, g = A.T @ A + 0.01 * np.eye(n), rng.normal(size=n) * 3
        lo, hi = -rng.uniform(0.0, 1, n), rng.uniform(0.0, 1, n)
        u, ref = solve_box_qp(H, g, lo, hi), _qp_by_enumeration(H, g, lo, hi)
        assert np.allclose(u, ref, rtol=0.0, atol=1e-10), (u, ref)
        bound += bool(np.any(np.isclose(u, lo) | np.isclose(u, hi)))
    assert bound > 100                                   # most draws held a bound: the active set ran
    with pytest.raises(np.linalg.LinAlgError):
        solve_box_qp(np.zeros((2, 2)), np.ones(2), -np.ones(2), np.ones(2))
