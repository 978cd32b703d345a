"""The online walk engine: causal commands, the table it reproduces, step adjustment against a
numerical solution, the estimator's error, and a cost per tick a robot's computer can pay."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import minimize

import gaits
from gaits import CommandStream, EngineParams, WalkEngine
from gaits.control import READINGS, Measurement, TablePlayer
from gaits.engine import Step, _Gait, adjust_step
from gaits.lipm import dcm_forward, dcm_forward_weights, propagate, solve_box_qp, zmp_at
from tuner.params_io import resolve_params
from tuner.robots import load_robot
from tuner.sim.cache import simulator

ROBOT = load_robot("kidsize")
FAST = resolve_params("kidsize-omni-carpet4", None).params
LIMITS = gaits.family("tlipfm").step_limits(FAST, ROBOT)
FIELDS = ("t", "q", "dq", "imu_rpy", "gyro", "accel", "foot_force", "joint_names")


def engine(**kw) -> WalkEngine:
    return WalkEngine(FAST, EngineParams(**kw), ROBOT, 0.01, LIMITS)


class Recorder(TablePlayer):
    """A table that keeps a copy of every measurement it walked on."""

    senses = frozenset(READINGS)

    def __init__(self, traj):
        super().__init__(traj)
        self.seen = []

    def step(self, m, command=None):
        self.seen.append(Measurement(**{f: np.copy(getattr(m, f)) if isinstance(getattr(m, f), np.ndarray)
                                        else getattr(m, f) for f in FIELDS}))
        return super().step(m, command)


@pytest.fixture(scope="module")
def replayed():
    """A constant-command table (0.2 m/s) walked on the rigid floor, and its measurements."""
    n = 24
    cmds = np.tile([0.2, 0.0, 0.0], (n, 1))
    cmds[-1] = 0.0
    traj = gaits.family("tlipfm").walk(FAST, ROBOT, 0.01, cmds)
    rec = Recorder(traj)
    trace = simulator(ROBOT, "rigid").run(rec)
    assert trace.completed
    return traj, rec.seen, FAST.t_start + (n - 1) * FAST.period


# --- the LIPM closed forms and the QP --------------------------------------------------------

def test_closed_forms_match_a_numerical_integration():
    from scipy.integrate import solve_ivp
    Tc, shift = 0.15, np.array([0.002, -0.001])
    kt = np.array([0.0, 0.15, 0.49, 0.64])
    kp = np.array([[0, 0], [0.01, 0.04], [0.03, 0.045], [0.05, 0.0]])
    x0, v0 = np.array([0.001, 0.01]), np.array([0.1, 0.2])

    def f(t, y):
        p = zmp_at(kt, kp, t)
        return [y[2], y[3], (y[0] - p[0] - shift[0]) / Tc ** 2, (y[1] - p[1] - shift[1]) / Tc ** 2]
    for t0, t1 in ((0.05, 0.7), (0.2, 0.3), (0.49, 0.9)):
        sol = solve_ivp(f, (t0, t1), [*x0, *v0], rtol=1e-12, atol=1e-14, max_step=0.001)
        x, v = propagate(x0, v0, t0, t1, kt, kp, shift, Tc)
        assert np.allclose(x, sol.y[:2, -1], atol=1e-9) and np.allclose(v, sol.y[2:, -1], atol=1e-8)
        assert np.allclose(dcm_forward(x0 + Tc * v0, t0, t1, kt, kp, shift, Tc), x + Tc * v, atol=1e-12)


def test_the_dcm_pass_is_the_linear_map_its_weights_say():
    """``dcm_forward_weights`` against ``dcm_forward`` on random profiles: starts before, inside and
    after the knots, zero-length segments, any points and shift."""
    rng = np.random.default_rng(3)
    for _ in range(500):
        m = int(rng.integers(2, 6))
        kt = np.sort(rng.uniform(0.0, 1.0, m))
        if rng.random() < 0.2:
            kt[1] = kt[0]
        kp, s, xi = rng.normal(size=(m, 2)), rng.normal(size=2), rng.normal(size=2)
        Tc = float(rng.uniform(0.05, 0.4))
        t0 = float(rng.uniform(-0.2, 1.1))
        t1 = t0 + float(rng.uniform(0.0, 1.2))
        a, w, ws = dcm_forward_weights(t0, t1, kt, Tc)
        ref = dcm_forward(xi, t0, t1, kt, kp, s, Tc)
        assert np.allclose(a * xi + w @ kp + ws * s, ref, rtol=1e-12, atol=1e-12)


def test_the_box_qp_is_exact():
    rng = np.random.default_rng(1)
    for _ in range(200):
        n = int(rng.integers(2, 6))
        A = rng.normal(size=(n + 2, n))
        H, g = A.T @ A + 0.01 * np.eye(n), rng.normal(size=n) * 3
        lo, hi = -rng.uniform(0.1, 1, n), rng.uniform(0.1, 1, n)
        u = solve_box_qp(H, g, lo, hi)
        ref = minimize(lambda w: 0.5 * w @ H @ w + g @ w, np.zeros(n), jac=lambda w: H @ w + g,
                       bounds=list(zip(lo, hi)), method="L-BFGS-B", options=dict(ftol=1e-15, gtol=1e-12))
        assert 0.5 * u @ H @ u + g @ u <= ref.fun + 1e-10
        assert np.all(u >= lo - 1e-12) and np.all(u <= hi + 1e-12)


# --- step adjustment -------------------------------------------------------------------------

def _step_on_the_left():
    g = _Gait(FAST, LIMITS)
    cmd = np.array([0.2, 0.0, 0.0])
    F = np.array([0.045, FAST.half_width, 0.0])
    prev = np.array([0.0, -FAST.half_width, 0.0])
    p0 = g.knots(prev, np.zeros(2), F, FAST.t1, FAST.t2, FAST.period)[1][-1]
    st = Step(1, F, np.array([0.0, -FAST.half_width, 0.0]), F.copy(), p0, FAST.t1, FAST.t2, FAST.period, cmd)
    st.offset = np.zeros(2)
    return g, st, cmd


def test_slow_steps_land_wider_by_stance_widen():
    """``stance_widen``: at a zero command the planner's footstep lands that much wider on each side,
    half as much at half ``stance_speed``, the gait's own width from ``stance_speed`` on (forward,
    sideways, or a foot turning about the other); 0 (the default) is the planner's rule."""
    W = FAST.half_width
    g = _Gait(FAST, LIMITS, stance_widen=0.02, stance_speed=0.1)
    support = np.array([0.3, W, 0.0])                                 # the left foot supports
    turn = 0.05 / (2 * W)                                            # one foot about the other at 0.05 m/s
    for cmd, w in (((0, 0, 0), W + 0.02), ((0.05, 0, 0), W + 0.01), ((0, -0.05, 0), W + 0.01),
                   ((0.1, 0, 0), W), ((0.3, 0, 0), W), ((0, 0, -turn), W + 0.01), ((0, 0, 2 * turn), W)):
        cmd = np.array(cmd, dtype=float)
        assert g.half_width(cmd) == pytest.approx(w, abs=1e-12)
        if cmd[1] == 0 and cmd[2] == 0:
            B = g.nominal_target(support, 1, cmd)
            assert B[1] == pytest.approx(support[1] - 2 * w, abs=1e-12) and B[0] == pytest.approx(0.3 + cmd[0] * FAST.period)
    plain = _Gait(FAST, LIMITS)
    assert plain.half_width(np.zeros(3)) == W
    assert np.array_equal(plain.nominal_target(support, 1, np.zeros(3)), np.array([0.3, -W, 0.0]))
    with pytest.raises(gaits.ParamError):
        EngineParams(stance_widen=0.05)                               # beyond the stated range


@pytest.mark.parametrize("t1", [0.01, FAST.t1, FAST.t2 - 0.01])
@pytest.mark.parametrize("n", [1, 3])
def test_the_start_points_weight_is_the_required_dcms_own(t1, n):
    """``_Gait.start_weight``, the closed form the step adjustment takes for how the DCM the next
    steps need moves with their first ZMP point, is that DCM's own slope (a difference over the
    point, on both axes, for a turning command too)."""
    g = _Gait(dataclasses.replace(FAST, t1=t1), LIMITS)
    support = np.array([0.1, 0.05, 0.3])
    cmd = np.array([0.15, 0.03, 0.4])
    p0 = np.array([0.08, 0.01])
    base = g.required_dcm(support, -1, p0, cmd, n)
    for d in (np.array([0.01, 0.0]), np.array([0.0, -0.02])):
        moved = g.required_dcm(support, -1, p0 + d, cmd, n)
        assert np.allclose(moved - base, g.start_weight * d, atol=1e-12)
    assert 0.0 < g.start_weight < 0.5              # the point is left as the ZMP moves on to the sole


def test_an_undisturbed_step_is_the_planners():
    g, st, cmd = _step_on_the_left()
    xi = g.required_dcm(st.support, st.side, st.p0, cmd, 4)        # this step and the 3 of the preview
    B, lam, dp, info = adjust_step(g, st, 0.0, xi, cmd, 3, None, EngineParams(), 0.01)
    assert np.allclose(B, g.nominal_target(st.support, st.side, cmd), atol=1e-9)
    assert lam == 1.0 and np.allclose(dp, 0.0, atol=1e-9) and info["residual"] < 1e-8
    assert info["binds"] == ()                                       # no limit touched


def test_the_limits_a_step_sits_on_are_named():
    """A small push leaves every limit free; a large forward one puts the footstep on its reach and
    the ZMP on the sole's edge, and ``binds`` says so (checked against the bounds themselves)."""
    g, st, cmd = _step_on_the_left()
    params = EngineParams(step_weight=0.05, zmp_weight=0.05)
    xi0 = g.required_dcm(st.support, st.side, st.p0, cmd, 4)
    *_, small = adjust_step(g, st, 0.0, xi0 + np.array([0.004, 0.0]), cmd, 3, None, params, 0.01)
    assert "reach" not in small["binds"] and "sole" not in small["binds"]
    B, lam, dp, big = adjust_step(g, st, 0.0, xi0 + np.array([0.3, 0.0]), cmd, 3, None, params, 0.01)
    lo, hi = g.box(st.side, 0.0)
    u = B[:2] - st.support[:2]
    plo, phi = g.zmp_box(params.zmp_margin)
    on_reach = bool(np.any(np.isclose(u, lo, atol=1e-9) | np.isclose(u, hi, atol=1e-9)))
    on_sole = bool(np.any(np.isclose(dp, plo, atol=1e-9) | np.isclose(dp, phi, atol=1e-9)))
    assert on_reach and on_sole
    assert ("reach" in big["binds"]) == on_reach and ("sole" in big["binds"]) == on_sole
    assert ("timing" in big["binds"]) == (lam < 1.0)


def _turned(st, heading: float, wz: float):
    """The same step on a support foot turned by ``heading``, for a command that also turns."""
    cmd = np.array([0.2, 0.0, wz])
    st.support = np.array([st.support[0], st.support[1], heading])
    st.target = st.support.copy()
    st.command = cmd
    return cmd


def _step_cost(g, st, cmd, xi, params, tau, lam, Rot, nominal, u_nom, n_preview=3):
    """The step adjustment's cost of z = (ZMP offset, footstep in the support foot's frame) at the
    timing ``lam``, built from the closed forms themselves (the knots, a forward DCM pass, the
    required DCM of ``n_preview`` steps; none: a stop, at rest on the step's last ZMP point), the
    footstep drawn to ``u_nom`` (the planner's, within the reach): the numerical reference its QP
    is checked against."""
    p = g.p
    t2 = p.t1 + lam * (p.t2 - p.t1)
    T = t2 + p.period - p.t2

    def cost(z):
        Bz = np.r_[st.support[:2] + Rot @ z[2:], nominal[2]]
        kt, kp, sh = g.knots(st.support, st.p0, Bz, st.t1, t2, T, offset=z[:2])
        required = kp[-1] if n_preview == 0 else g.required_dcm(Bz, -st.side, kp[-1], cmd, n_preview)
        r = dcm_forward(xi, tau, T, kt, kp, sh, g.Tc) - required
        du = z[2:] - u_nom
        return float(r @ r + params.step_weight * du @ du + params.zmp_weight * z[:2] @ z[:2]
                     + params.timing_weight * (1.0 - lam) ** 2)
    return cost


def _numerical_min(cost, lo, hi, plo, phi, u_nom) -> float:
    """The least of ``cost`` over the sole's and the reach's bounds, from two starts (L-BFGS-B)."""
    bounds = list(zip(plo, phi)) + list(zip(lo, hi))
    return min(minimize(cost, np.r_[0, 0, x0], bounds=bounds, method="L-BFGS-B",
                        options=dict(ftol=1e-14, gtol=1e-12)).fun for x0 in (u_nom, (lo + hi) / 2))


@pytest.mark.parametrize("push,heading,wz,tau", [((0.06, 0.0), 0.0, 0.0, 0.0), ((0.0, -0.05), 0.0, 0.0, 0.0),
                                                 ((-0.04, 0.02), 0.0, 0.0, 0.0), ((0.12, -0.08), 0.0, 0.0, 0.0),
                                                 ((0.05, 0.03), 0.7, 0.5, 0.0), ((-0.03, 0.06), -1.2, -0.4, 0.05)])
def test_a_pushed_step_moves_toward_the_capture_point_within_the_limits(push, heading, wz, tau):
    """A capture-point error (a push) moves the footstep toward it, keeps the reach box and the sole,
    and the QP's answer for the chosen timing is the numerical optimum of the same cost (on a
    support foot turned any way, for a turning command, at a step's start or inside it)."""
    g, st, cmd = _step_on_the_left()
    cmd = _turned(st, heading, wz)
    params = EngineParams(step_weight=0.05, zmp_weight=0.05)
    nominal = g.nominal_target(st.support, st.side, cmd)
    c, s = np.cos(heading), np.sin(heading)
    Rot = np.array([[c, -s], [s, c]])
    xi0 = g.required_dcm(st.support, st.side, st.p0, cmd, 4)
    xi = dcm_forward(xi0, 0.0, tau, *g.knots(st.support, st.p0, nominal, st.t1, st.t2, st.T), g.Tc) + np.array(push)
    B, lam, dp, info = adjust_step(g, st, tau, xi, cmd, 3, None, params, 0.01)
    moved = B[:2] - nominal[:2]
    assert moved @ np.array(push) > 0                                     # toward the capture point
    lo, hi = g.box(st.side, nominal[2] - heading)
    u = Rot.T @ (B[:2] - st.support[:2])
    assert np.all(u >= lo - 1e-9) and np.all(u <= hi + 1e-9)             # reach and sole gap
    plo, phi = g.zmp_box(params.zmp_margin)
    assert np.all(dp >= plo - 1e-9) and np.all(dp <= phi + 1e-9)         # the ZMP stays on the sole
    u_nom = np.clip(Rot.T @ (nominal[:2] - st.support[:2]), lo, hi)
    cost = _step_cost(g, st, cmd, xi, params, tau, lam, Rot, nominal, u_nom)
    assert cost(np.r_[dp, u]) <= _numerical_min(cost, lo, hi, plo, phi, u_nom) + 1e-7


@pytest.mark.parametrize("push,timing_weight", [((0.12, -0.08), 1e-3), ((0.06, 0.0), 1e-4), ((0.2, 0.05), 1e-2),
                                                 ((0.01, 0.0), 1e-3)])
def test_the_chosen_timing_costs_no_more_than_any_other(push, timing_weight):
    """Over the five timings the adjustment may take (lambda = 1 and four from ``min_ssp_scale`` up),
    its choice costs no more, timing term included, than the numerical optimum of any of them: the
    timings it skips (an undisturbed step, or one whose timing term alone exceeds the best found)
    could not have won."""
    g, st, cmd = _step_on_the_left()
    params = EngineParams(step_weight=0.05, zmp_weight=0.05, timing_weight=timing_weight, min_ssp_scale=0.6)
    nominal = g.nominal_target(st.support, st.side, cmd)
    xi = g.required_dcm(st.support, st.side, st.p0, cmd, 4) + np.array(push)
    B, lam, dp, info = adjust_step(g, st, 0.0, xi, cmd, 3, None, params, 0.01)
    lo, hi = g.box(st.side, 0.0)
    plo, phi = g.zmp_box(params.zmp_margin)
    u_nom = np.clip(nominal[:2] - st.support[:2], lo, hi)
    m = params.min_ssp_scale
    optima = [_numerical_min(_step_cost(g, st, cmd, xi, params, 0.0, lam_, np.eye(2), nominal, u_nom),
                             lo, hi, plo, phi, u_nom)
              for lam_ in [1.0] + [m + (1.0 - m) * k / 4 for k in range(4)]]
    chosen = _step_cost(g, st, cmd, xi, params, 0.0, lam, np.eye(2), nominal, u_nom)
    assert chosen(np.r_[dp, B[:2] - st.support[:2]]) <= min(optima) + 1e-7


def test_a_stopping_step_and_a_landed_foot_are_solved_exactly():
    """The two other forms of the mismatch: a stop (no preview: the DCM at rest on the step's last
    ZMP point) and a landed foot (only the ZMP offset free): the answer is the numerical optimum."""
    g, st, _ = _step_on_the_left()
    cmd = _turned(st, 0.4, 0.3)
    params = EngineParams(step_weight=0.05, zmp_weight=0.05)
    nominal = g.nominal_target(st.support, st.side, cmd)
    xi = g.required_dcm(st.support, st.side, st.p0, cmd, 1) + np.array([0.02, -0.01])
    c, s = np.cos(0.4), np.sin(0.4)
    Rot = np.array([[c, -s], [s, c]])
    lo, hi = g.box(st.side, nominal[2] - 0.4)
    plo, phi = g.zmp_box(params.zmp_margin)
    B, lam, dp, _ = adjust_step(g, st, 0.0, xi, cmd, 0, None, params, 0.01)
    u_nom = np.clip(Rot.T @ (nominal[:2] - st.support[:2]), lo, hi)
    stop_cost = _step_cost(g, st, cmd, xi, params, 0.0, lam, Rot, nominal, u_nom, n_preview=0)
    assert stop_cost(np.r_[dp, Rot.T @ (B[:2] - st.support[:2])]) <= \
        _numerical_min(stop_cost, lo, hi, plo, phi, u_nom) + 1e-7

    st.target = nominal.copy()                                           # landed where planned
    st.landed = True
    tau = 0.5 * (st.t1 + st.t2)
    B, lam, dp, _ = adjust_step(g, st, tau, xi, cmd, 3, None, params, 0.01, fixed_target=True)
    assert np.allclose(B, nominal) and lam == 1.0

    def landed_cost(o):
        kt, kp, sh = g.knots(st.support, st.p0, nominal, st.t1, st.t2, st.T, offset=o)
        r = dcm_forward(xi, tau, st.T, kt, kp, sh, g.Tc) - g.required_dcm(nominal, -st.side, kp[-1], cmd, 3)
        return float(r @ r + params.zmp_weight * o @ o)
    ref = minimize(landed_cost, np.zeros(2), bounds=list(zip(plo, phi)), method="L-BFGS-B",
                   options=dict(ftol=1e-14, gtol=1e-12))
    assert landed_cost(dp) <= ref.fun + 1e-7


# --- the engine as a controller --------------------------------------------------------------

@pytest.mark.parametrize("yaw_feedback", [0.0, 3.0])
def test_a_command_changed_at_tick_k_changes_no_target_before_it(yaw_feedback):
    """Two walks fed the same measurements, their commands equal until tick k: equal targets up to
    tick k - 1 (the engine knows no future command; the gyro's turn feedback neither)."""
    m0 = Measurement(0.0)
    k = 180

    def walk(change: np.ndarray) -> np.ndarray:
        e = engine(yaw_feedback=yaw_feedback)
        e.start_pose()
        e.reset(m0)
        out = []
        for i in range(260):
            c = np.array([0.2, 0.0, 0.0]) if i < k else change
            out.append(e.step(Measurement(i * 0.01), c).copy())
        return np.array(out)
    a, b = walk(np.array([0.2, 0.0, 0.0])), walk(np.array([0.0, 0.08, 0.6]))
    assert np.array_equal(a[:k], b[:k])
    assert not np.allclose(a[k:], b[k:])


def test_the_engine_on_a_replayed_walk_reproduces_the_planned_walk(replayed):
    """Fed the measurements of a constant-command table walked in simulation, and that command, the
    engine's targets are the table's within 2e-3 rad from its second second to three steps before
    the stop (feedback on: the walk holds its plan, so nothing is re-planned). What differs is what
    the table knows and the engine cannot: its CoM starts drifting during the standing second (the
    engine shifts its weight instead), and it sees the stop coming; with a longer preview the engine
    comes closer (8 steps here; the default 3 leaves 6e-3 rad)."""
    traj, seen, stop_t = replayed
    e = WalkEngine(FAST, EngineParams(preview_steps=8, level_feet=0.0, accel_vx=20.0, touchdown_force=1.0,
                                      t_stand=FAST.t_start), ROBOT, 0.01, LIMITS)
    e.start_pose()
    e.reset(seen[0])
    out = np.array([e.step(m, np.array([0.2, 0, 0]) if m.t < stop_t else np.zeros(3)).copy() for m in seen])
    ref = traj.q_ref[1:len(out) + 1]
    t = np.arange(len(out)) * 0.01
    sel = (t >= 2.0) & (t < stop_t - 3 * FAST.period)
    legs = slice(8, 20)
    assert np.abs(out[sel][:, legs] - ref[sel][:, legs]).max() < 2e-3
    assert not [ev for ev in e.events if ev[1].startswith("re-plan") and ev[0] < stop_t - 3 * FAST.period]


def test_the_estimator_follows_the_true_com(replayed):
    """The estimator's CoM on the replayed walk, beside the simulator's (relative to the support
    sole, in the torso's heading): within 3 cm everywhere and 2.5 cm on average (measured 2.6 and
    2.0 cm); most of it the
    rigid-body CoM model (measured: a 1.1 cm bias of pelvis + com_in_pelvis against MuJoCo's CoM
    while walking), which the engine's disturbance signal removes as a slow bias."""
    traj, seen, stop_t = replayed
    e = engine()
    e.start_pose()
    e.reset(seen[0])
    for m in seen:
        e.step(m, np.array([0.2, 0, 0]) if m.t < stop_t else np.zeros(3))
    trace = simulator(ROBOT, "rigid").run(Recorder(traj))
    est = np.array([r[7:9] for r in e._log])
    feet = np.array([r[3:7] for r in e._log])
    errs = []
    for k in range(200, len(est) - 100):
        sup = int(e._log[k][0])
        if sup == 0:
            continue
        yaw = trace.yaw[k + 1]
        R = np.array([[math.cos(yaw), math.sin(yaw)], [-math.sin(yaw), math.cos(yaw)]])
        sole = trace.p_sole_l[k + 1, :2] if sup == 1 else trace.p_sole_r[k + 1, :2]
        true = R @ (trace.p_com[k + 1, :2] - sole)
        mine = est[k] - (feet[k, :2] if sup == 1 else feet[k, 2:])
        errs.append(mine - true)
    errs = np.linalg.norm(np.array(errs), axis=1)
    assert errs.max() < 0.03 and errs.mean() < 0.025


def test_the_kinematic_velocity_is_the_rate_of_the_kinematic_com(replayed):
    """The CoM velocity the engine reads from the gyro and the encoders' rates (``kf_velocity``)
    against the difference of the kinematic CoM it reads from the angles, tick to tick, on the
    replayed walk (the same support foot on both ticks; the walk's CoM moving at up to ~0.3 m/s):
    median within 2.5 cm/s, 95th percentile within 6.5 cm/s (measured 1.6 and 4.8 cm/s; the largest
    errors in double support, where the support sole rolls and the still-sole reading is off, the
    position's as much as the velocity's); without ``kf_velocity`` none is read."""
    traj, seen, stop_t = replayed
    e = engine(kf_velocity=0.05)
    e.start_pose()
    e.reset(seen[0])
    read = e._kinematic_com
    rows = []

    def recorded(m):
        x, v = read(m)
        rows.append((e.steps_taken, e.mode, x.copy(), None if v is None else v.copy()))
        return x, v
    e._kinematic_com = recorded
    for m in seen:
        e.step(m, np.array([0.2, 0, 0]) if m.t < stop_t else np.zeros(3))
    errs, speeds = [], []
    for (n0, mode0, x0, v0), (n1, mode1, x1, v1) in zip(rows, rows[1:]):
        if mode0 == mode1 == "walk" and n0 == n1 and v0 is not None and v1 is not None:
            errs.append(np.linalg.norm((x1 - x0) / 0.01 - (v0 + v1) / 2))
            speeds.append(np.linalg.norm(v0))
    assert len(errs) > 300
    assert np.median(errs) < 0.025 and np.percentile(errs, 95) < 0.065 and max(speeds) > 0.25
    assert engine()._kinematic_com(seen[300])[1] is None


def _carpet4_walk(**over) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The engine set walking 0.3 m/s for 6 s on carpet4 in closed loop: (t, forward velocity read
    or nan) per tick, the simulator's times and forward CoM velocity, the CoM's forward travel [m]."""
    drive = gaits.Drive.of(resolve_params("kidsize-engine-carpet4", None))
    drive = dataclasses.replace(drive, engine=dataclasses.replace(drive.engine, **over))
    stream = CommandStream([0.0, 6.0], [[0.3, 0, 0], [0, 0, 0]], tail=1.0)
    sim = simulator(ROBOT, "carpet4")
    ctl = dataclasses.replace(drive, stream=stream).controller(ROBOT, sim.control_period)
    e = ctl.inner if hasattr(ctl, "inner") else ctl
    e = getattr(e, "engine", e)
    read = e._kinematic_com
    rows = []

    def recorded(m):
        x, v = read(m)
        rows.append((m.t, np.nan if v is None else v[0]))
        return x, v
    e._kinematic_com = recorded
    trace = sim.run(ctl, commands=stream, duration=stream.duration)
    assert not trace.fell
    return np.array(rows), trace.t, np.gradient(trace.p_com[:, 0], trace.t), \
        float(trace.p_com[-1, 0] - trace.p_com[0, 0])


def test_the_measured_velocity_is_not_read_while_a_foot_lands():
    """A step's first ``lag`` the new stance leg's encoders still turn with the landing swing: read
    there (as first built), the velocity ran backward while the CoM moved on (a closed-loop 0.3 m/s
    carpet4 walk: -0.14 against +0.20 m/s in the step's first 20 ms), the estimate took a quarter
    off the walk's speed and the re-plans slowed the walk to 0.22 m/s. Over that walk's steady
    steps (2-6 s) the mean forward velocity read is within 10 % of the simulator's CoM's, and the
    walk travels within 10 % of the same walk without the velocity read (measured: 0.307 against
    0.307 m/s; 1.53 against 1.53 m; read in every tick, both fail: 0.15 against 0.22 m/s)."""
    rows, t, v_true, travel = _carpet4_walk(kf_velocity=0.05)
    *_, travel_without = _carpet4_walk(kf_velocity=0.0)
    sel = (rows[:, 0] >= 2.0) & (rows[:, 0] < 6.0) & ~np.isnan(rows[:, 1])
    k = np.searchsorted(t, rows[sel, 0] - 1e-9)
    assert abs(np.mean(rows[sel, 1]) / np.mean(v_true[k]) - 1) < 0.1
    assert abs(travel / travel_without - 1) < 0.1


def test_a_measured_velocity_shows_a_push_at_once():
    """A push (the CoM's velocity jumping by 0.3 m/s) in the estimator fed a noiseless LIPM state:
    with the velocity measured (``velocity_noise`` 0.05 m/s) the estimate holds 70 % of the jump by
    the sixth tick after it; from the position alone (the default) less than a quarter, and less
    than half ten ticks after it (measured: 0.216 against 0.058 m/s; 0.129 m/s)."""
    from gaits.engine import CoMEstimator
    Tc, dt = 0.15, 0.01
    found = {}
    for noise in (0.0, 0.05):
        f = CoMEstimator(Tc, dt, 1.0, 0.008, noise)
        f.reset(np.zeros(2))
        x, v = np.zeros(2), np.zeros(2)
        got = []
        for k in range(60):
            if k == 30:
                v = v + np.array([0.3, 0.0])
            p = np.array([0.0, 0.0])
            x, v = propagate(x, v, 0.0, dt, np.array([0.0, 1.0]), np.array([p, p]), np.zeros(2), Tc)
            f.update(p, x, v)
            got.append((f.velocity - v)[0] + 0.3 if k >= 30 else 0.0)
        found[noise] = got
    assert found[0.05][35] > 0.7 * 0.3 and found[0.0][35] < 0.25 * 0.3
    assert found[0.0][40] < 0.5 * 0.3


def test_the_engine_walks_a_stream_and_states_its_envelope():
    e = engine()
    env = e.envelope()
    assert env["forward"] == pytest.approx(LIMITS.max_forward / FAST.period)
    assert env["turn_left"] == pytest.approx(LIMITS.max_turn / (2 * FAST.period))
    stream = CommandStream([0.0, 3.0, 5.0], [[0.25, 0, 0], [0, 0, 0.8], [0, 0, 0]], tail=2.0)
    trace = simulator(ROBOT, "carpet4").run(e, commands=stream, duration=stream.duration)
    assert trace.completed and e.steps_taken > 15
    assert e.mode == "stand"                                    # it stopped on the zero command
    assert trace.p_torso[-1, 0] > 0.5 and trace.yaw[-1] - trace.yaw[0] > 0.8


def test_engine_cost_per_tick_on_a_robots_budget():
    """What the engine costs a tick, measured here with its counters (not wall time: the machine
    may be loaded): the step adjustment runs once a step, and the rest is closed forms."""
    e = engine()
    stream = CommandStream([0.0, 3.0], [[0.3, 0, 0], [0, 0, 0]], tail=2.0)
    simulator(ROBOT, "carpet4").run(e, commands=stream, duration=stream.duration)
    assert e.steps_taken < len(e._log) / 10                    # adjustments are a tenth of the ticks or fewer


def test_live_walk_steers_from_the_keyboard_and_ends_when_the_window_closes():
    """``view``'s live loop with a stand-in viewer: keys change the command the engine reads, closing
    the window ends the walk (the viewer itself needs a display, which CI has not)."""
    from tuner.report.live import KeyboardCommand, live_walk

    class Viewer:
        def __init__(self, keyboard, close_at):
            self.keyboard, self.close_at, self.ticks = keyboard, close_at, 0

        def is_running(self):
            return self.ticks < self.close_at

        def sync(self):
            self.ticks += 1
            if self.ticks == 150:
                for _ in range(3):
                    self.keyboard.key(265)          # up arrow: 0.15 m/s forward
            if self.ticks == 450:
                self.keyboard.key(32)               # space: stop
    keyboard = KeyboardCommand()
    viewer = Viewer(keyboard, close_at=600)
    trace = live_walk(simulator(ROBOT, "carpet4"), engine(), viewer, keyboard, realtime=False)
    assert trace.reason == "stopped" and len(trace.t) == 602          # 600 ticks shown, the 601st finds it closed
    assert trace.p_torso[440, 0] - trace.p_torso[150, 0] > 0.2
    assert keyboard.at(0.0).tolist() == [0.0, 0.0, 0.0]


def test_the_gyro_holds_the_heading_within_yaw_hold_and_the_walk_still_stops():
    """Walking sideways with no turn asked while the gyro reads a steady drift of 0.1 rad/s: with
    yaw_hold the engine plans a turn against the drift, at most yaw_hold; without it (the
    default) no turn; asked to stop, it comes to stand within 3 s."""
    def walk(hold: float, ticks: int = 500, stop_after: int | None = None) -> WalkEngine:
        e = engine(yaw_feedback=3.0, yaw_hold=hold)
        e.start_pose()
        e.reset(Measurement(0.0))
        for i in range(ticks):
            stopped = stop_after is not None and i >= stop_after
            c = np.zeros(3) if stopped else np.array([0.0, 0.05, 0.0])
            drift = 0.0 if stopped else 0.1
            e.step(Measurement(i * 0.01, gyro=np.array([0.0, 0.0, drift])), c)
        return e
    held = walk(0.06)
    assert held.command[2] == pytest.approx(-0.06, abs=1e-12)        # at the bound, against the drift
    assert walk(0.5).command[2] < -0.06                              # a wider bound: more
    assert walk(0.0).command[2] == 0.0
    assert walk(0.06, ticks=800, stop_after=500).mode == "stand"


def test_the_stride_calibration_plans_the_scaled_command_and_widens_the_envelope():
    """stride_backward 1.2, stride_sideways 0.8, stride_turn 1.1: asked (-0.1, 0.05, 0.2) the
    engine plans exactly the steps an uncalibrated engine plans asked (-0.12, 0.04, 0.22); forward
    as asked; the envelope grows where the calibration plans shorter steps and shrinks where longer."""
    def walk(e: WalkEngine, c, ticks: int = 300) -> WalkEngine:
        e.start_pose()
        e.reset(Measurement(0.0))
        for i in range(ticks):
            e.step(Measurement(i * 0.01), np.array(c, dtype=float))
        return e
    cal = walk(engine(stride_backward=1.2, stride_sideways=0.8, stride_forward=0.7, stride_turn=1.1),
               (-0.1, 0.05, 0.2))
    plain = walk(engine(), (-0.12, 0.04, 0.22))
    assert np.allclose(cal.command, [-0.12, 0.04, 0.22], atol=1e-12)
    assert cal.steps_taken == plain.steps_taken > 5
    assert np.allclose(cal.cur.target, plain.cur.target, atol=1e-12)
    assert np.allclose(cal.feet[1], plain.feet[1], atol=1e-12) and np.allclose(cal.feet[-1], plain.feet[-1], atol=1e-12)
    assert np.allclose(walk(engine(stride_forward=0.7, stride_backward=1.2), (0.1, 0.0, 0.0), 200).command,
                       [0.07, 0.0, 0.0], atol=1e-12)
    assert np.allclose(walk(engine(), (-0.1, 0.05, 0.0), 200).command, [-0.1, 0.05, 0.0], atol=1e-12)
    e0, e1 = engine().envelope(), engine(stride_sideways=0.8, stride_backward=1.25, stride_turn=1.1).envelope()
    assert e1["turn_left"] == pytest.approx(e0["turn_left"] / 1.1)
    assert e1["left"] == pytest.approx(e0["left"] / 0.8) and e1["right"] == pytest.approx(e0["right"] / 0.8)
    assert e1["backward"] == pytest.approx(e0["backward"] / 1.25) and e1["forward"] == pytest.approx(e0["forward"])


def test_the_combined_limit_scales_a_command_at_the_envelopes_corner_along_its_direction():
    """combined_limit 1: a command asking each direction's whole envelope at once is scaled to the
    ellipsoid (its shares' norm 1) along its own direction; a command along one direction, or one
    whose shares' norm is within the limit, is as the box clips it; the default (2) is the box."""
    box, ell = engine(), engine(combined_limit=1.0)
    env = box.envelope()
    corner = np.array([env["forward"], env["left"], env["turn_left"]])
    np.testing.assert_allclose(box.shaper.clip(2 * corner), corner, atol=1e-12)
    got = ell.shaper.clip(2 * corner)
    np.testing.assert_allclose(got, corner / np.sqrt(3.0), atol=1e-12)
    back = np.array([-env["backward"], 0.0, env["turn_left"]])
    np.testing.assert_allclose(ell.shaper.clip(back), back / np.sqrt(2.0), atol=1e-12)
    np.testing.assert_allclose(ell.shaper.clip(np.array([5.0, 0.0, 0.0])), [env["forward"], 0.0, 0.0], atol=1e-12)
    inside = 0.5 * corner                     # shares' norm 0.87
    np.testing.assert_allclose(ell.shaper.clip(inside), inside, atol=1e-12)
    mid = engine(combined_limit=1.5).shaper.clip(corner)
    assert np.sqrt(np.sum((mid / corner) ** 2)) == pytest.approx(1.5)


def test_the_gyro_makes_up_a_turning_shortfall_within_bounds():
    """Asked 0.6 rad/s while the gyro reads 80 % of it, the engine plans a faster turn once the asked
    turn is reached and three steps have passed (at most 30 % more); it turns as asked when the gyro
    agrees (within 0.03 rad/s: the filter's last lag); without feedback (the default) the planned
    turn is the asked one; at a zero command the correction decays and the engine stops."""
    def walk(gain: float, seen: float, ticks: int = 400, then_stop: bool = False) -> WalkEngine:
        e = engine(yaw_feedback=gain)
        e.start_pose()
        e.reset(Measurement(0.0))
        for i in range(ticks):
            c = np.array([0.0, 0.0, 0.6])
            if then_stop and i >= ticks - 100:
                c = np.zeros(3)
            e.step(Measurement(i * 0.01, gyro=np.array([0.0, 0.0, seen * float(e.command[2] - e.shaper.wz_extra)])), c)
        return e
    short = walk(3.0, 0.8)
    assert 0.6 < short.command[2] <= 0.6 * 1.3 + 1e-9
    assert walk(3.0, 1.0).command[2] == pytest.approx(0.6, abs=0.03)
    assert walk(0.0, 0.8).command[2] == pytest.approx(0.6, abs=1e-12)
    stopped = walk(3.0, 0.8, ticks=600, then_stop=True)
    assert abs(stopped.shaper.wz_extra) < 0.5 * abs(short.shaper.wz_extra)
    assert stopped.mode == "stand"                 # the decayed correction ends: asked to stop, it stops


def test_a_re_plan_takes_the_pushs_velocity_once():
    """A re-plan moves the plan's velocity by k_vel of the disturbance and leaves the rest as the
    disturbance at once, though the disturbance compares with the plan ``lag`` ago: a second re-plan
    at the next tick adds k_vel of what is left, not k_vel of the whole push again."""
    e = engine(k_vel=0.6, lag=0.03, replan_error=10.0)
    e.start_pose()
    e.reset(Measurement(0.0))
    for i in range(200):                                   # blind ticks: the plan walks on
        e.step(Measurement(i * 0.01), np.array([0.1, 0.0, 0.0]))
    assert e.mode == "walk"
    n = 3
    com_lag, vel_lag = e._history[-1 - n]
    push = np.array([0.3, -0.1])
    e.estimator.x = np.array([com_lag, vel_lag + push])
    e._bias = np.zeros(4)
    v0 = e.vel.copy()
    assert np.allclose(e._disturbance()[1], push)
    e._take_blended()
    assert np.allclose(e.vel - v0, 0.6 * push)
    assert np.allclose(e._disturbance()[1], 0.4 * push)
    e._take_blended()
    assert np.allclose(e.vel - v0, (0.6 + 0.6 * 0.4) * push)


# --- readings a robot's bus garbles ----------------------------------------------------------

class Garbled:
    """The engine behind a robot whose bus garbles frames: ``names`` read NaN for ``n`` ticks
    from ``t0`` (everything else of the controller protocol is the engine's)."""

    def __init__(self, inner, names, t0, n):
        self.inner, self.names, self.t0, self.n = inner, names, t0, n
        self.senses, self.dt, self.duration = inner.senses, inner.dt, inner.duration
        self.walk_start = inner.walk_start

    def start_pose(self):
        return self.inner.start_pose()

    def reset(self, m):
        self.inner.reset(m)

    def step(self, m, command=None):
        if self.t0 - 1e-9 <= m.t < self.t0 + (self.n - 0.5) * self.dt:
            m = dataclasses.replace(m, **{k: np.full(np.shape(getattr(m, k)), np.nan) for k in self.names})
        return self.inner.step(m, command)

    def plan(self, n):
        return self.inner.plan(n)


def test_readings_that_are_not_finite_are_not_taken_and_the_walk_goes_on():
    """For 50 ms of a 0.25 m/s carpet4 walk every reading is NaN: the engine takes none of them
    (its estimator predicts from the model meanwhile), every target stays finite, the walk goes on
    to its stop, and the engine counts each reading's dropped ticks and logs each run once. Taken,
    the first NaN tilt stayed in the tilt filter: every target NaN from the next tick on, then a
    ZeroDivisionError (measured before ``finite_readings``)."""
    e = engine()
    names = ("q", "dq", "imu_rpy", "gyro", "accel", "foot_force")
    stream = CommandStream([0.0, 3.0], [[0.25, 0, 0], [0, 0, 0]], tail=2.0)
    trace = simulator(ROBOT, "carpet4").run(Garbled(e, names, 2.5, 5), commands=stream, duration=stream.duration)
    assert trace.completed and e.mode == "stand"
    assert np.all(np.isfinite(trace.q_ref))
    assert trace.p_torso[-1, 0] > 0.4
    assert e.dropped == {**{k: 5 for k in names}, "command": 0}
    logged = [ev for ev in e.events if "not finite" in ev[1]]
    assert len(logged) == len(names) and all(ev[0] == pytest.approx(2.5) for ev in logged)
    assert e.plan(10).meta["dropped"] == e.dropped


def test_a_command_that_is_not_finite_holds_the_last_one():
    """A NaN in the behaviour's command is not taken: the engine walks on the last command, as if
    the NaN had not come, and counts it; a command of the wrong shape is a ValueError."""
    good, bad = engine(), engine()
    for e in (good, bad):
        e.start_pose()
        e.reset(Measurement(0.0))
    for i in range(300):
        c = np.array([0.2, 0.0, 0.3])
        q_good = good.step(Measurement(i * 0.01), c).copy()
        q_bad = bad.step(Measurement(i * 0.01), np.array([np.nan, 0.0, 0.3]) if 150 <= i < 160 else c).copy()
        assert np.array_equal(q_good, q_bad), i
    assert bad.dropped["command"] == 10 and good.dropped["command"] == 0
    with pytest.raises(ValueError, match=r"shape \(3,\); got shape \(2,\)"):
        bad.step(Measurement(3.0), np.array([0.2, 0.0]))


def test_finite_readings_leaves_out_what_is_not_finite_and_refuses_a_wrong_shape():
    from gaits.control import finite_readings
    n = len(gaits.JOINT_NAMES)
    m = Measurement(0.5, q=np.zeros(n), dq=np.zeros(n), imu_rpy=np.array([0.0, np.inf, 0.0]), gyro=np.zeros(3),
                    accel=np.array([0.0, 0.0, 9.81]), foot_force=np.r_[np.full(7, 6.0), np.nan])
    kept, dropped = finite_readings(m)
    assert dropped == ("imu_rpy", "foot_force")
    assert kept.imu_rpy is None and kept.foot_force is None and kept.q is m.q and kept.t == 0.5
    clean = dataclasses.replace(m, imu_rpy=np.zeros(3), foot_force=np.full(8, 6.0))
    assert finite_readings(clean) == (clean, ())
    with pytest.raises(ValueError, match=r"Measurement.foot_force has shape \(6,\), expected \(8,\)"):
        finite_readings(dataclasses.replace(m, foot_force=np.zeros(6)))
    with pytest.raises(ValueError, match=r"Measurement.q has shape \(12,\), expected \(20,\)"):
        finite_readings(dataclasses.replace(m, q=np.zeros(12)))
    with pytest.raises(ValueError, match="Measurement.t"):
        finite_readings(dataclasses.replace(m, t=float("nan")))


def test_the_stabiliser_keeps_its_last_correction_when_the_imu_drops_out():
    from gaits.control import HoldPose, Stabilised
    from gaits.imu_stabiliser import StabiliserParams
    pose = np.zeros(len(gaits.JOINT_NAMES))
    s = Stabilised(HoldPose(pose, 0.01), StabiliserParams(enabled=True, k_ankle_pitch=0.5))
    s.reset(Measurement(0.0))
    tilted = s.step(Measurement(0.01, imu_rpy=np.array([0.0, 0.1, 0.0]), gyro=np.zeros(3))).copy()
    assert np.any(tilted != 0.0)
    for m in (Measurement(0.02, imu_rpy=np.array([np.nan, 0.1, 0.0]), gyro=np.zeros(3)), Measurement(0.03)):
        assert np.array_equal(s.step(m), tilted)


def test_servo_share_caps_every_targets_move_at_its_servos_speed():
    """EngineParams.servo_share: no target moves faster than that share of its servo's speed (the
    robot's, per joint); 0 leaves the targets as planned (bit for bit); a robot file's speeds serve
    the same (the robot side)."""
    from gaits.engine.walk import joint_speeds
    stream = CommandStream([0.0, 2.0], [[0.25, 0, 0], [0, 0, 0]], tail=1.0)
    speeds = joint_speeds(ROBOT)
    # MX-64 legs, MX-28 head: each motor's unloaded speed at 15 V
    assert speeds[gaits.JOINT_NAMES.index("l_knee")] == pytest.approx(8.612, abs=1e-3) and speeds[0] == pytest.approx(
        ROBOT.servo_of("head_yaw").speed)

    def walk(**kw):
        e = engine(**kw)
        tr = simulator(ROBOT, "rigid").run(e, commands=stream, duration=stream.duration)
        return e, tr.q_ref
    plain, q_plain = walk()
    capped, q_capped = walk(servo_share=0.5)
    cols = [gaits.JOINT_NAMES.index(j) for j in simulator(ROBOT, "rigid").joint_names]
    rate = np.abs(np.diff(q_capped, axis=0)) / 0.01
    assert np.all(rate <= 0.5 * speeds[cols] + 1e-9) and capped.capped > 0 and plain.capped == 0
    assert np.max(np.abs(np.diff(q_plain, axis=0)) / 0.01 / speeds[cols]) > 0.5      # the cap did something
    assert np.array_equal(q_plain, walk(servo_share=0.0)[1])

    class File:                                           # a robot file's joints: their speeds, ours
        leg, foot_size = ROBOT.leg, ROBOT.foot_size
        joints = {n: type("J", (), {"speed": 3.0})() for n in gaits.JOINT_NAMES}
    assert np.all(joint_speeds(File) == 3.0)

    class Legs(File):                                     # a robot without head or arms: their speed unknown
        joints = {n: type("J", (), {"speed": 3.0})() for n in gaits.JOINT_NAMES if n[2:] in gaits.leg_kinematics.LEG_JOINTS}
    assert np.isinf(joint_speeds(Legs)[0]) and np.all(joint_speeds(Legs)[gaits.JOINT_NAMES.index("l_knee")] == 3.0)
    e = WalkEngine(FAST, EngineParams(servo_share=0.5), Legs, 0.01, LIMITS)
    q0 = e.start_pose().q
    e.reset(Measurement(0.0))
    last, worst = q0, 0.0
    for k in range(300):                                  # the legs are capped though the head has no speed
        q = e.step(Measurement(k * 0.01), np.array([0.25, 0.0, 0.0]))
        worst = max(worst, float(np.max(np.abs(q - last))))
        last = q
    assert e.capped > 0 and worst <= 0.5 * 3.0 * 0.01 + 1e-12
