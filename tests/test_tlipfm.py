"""TLIPFM generator (Wong et al. 2020): closed form vs integration, special cases, ZMP reference."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from gaits import ParamError, load_baseline
from gaits import tlipfm
from gaits.trajectory import GRAVITY

TABLE2 = load_baseline("tkux-table2").params


@pytest.mark.parametrize("model,accel", [("tlipfm", 0.0), pytest.param("tlipfm", 3.0, marks=pytest.mark.slow),
                                         pytest.param("dlipm", 0.0, marks=pytest.mark.slow),
                                         pytest.param("lipm", 0.0, marks=pytest.mark.slow)])   # ~4 s each
def test_closed_form_matches_integration_over_14_steps(model, accel):
    """Eqs 23-26 against solve_ivp of eqs 12-13, each step from the same initial state (DOP853 at
    rtol 1e-12 agrees to ~1e-10 m; the step size left to it: a 5 ms cap cost 2.5x the evaluations for
    the same verdict)."""
    p = TABLE2.replace(model=model, flywheel_accel=accel)
    assert p.n_steps == 14
    c = tlipfm.pendulum_constants(p)
    s = np.linspace(0.0, p.period, 129)
    worst = 0.0
    for n in range(p.n_steps):
        t_abs = p.t_start + n * p.period + s
        com = tlipfm.com_trajectory(p, t_abs)
        for axis, shift in ((0, c.zmp_shift), (1, 0.0)):

            def rhs(tt, y, axis=axis, shift=shift):
                zmp = tlipfm.natural_zmp(p, np.array([tt]))[0, axis]
                return [y[1], (y[0] - zmp) / c.T ** 2 - shift / c.T ** 2]   # eq 12 / 13 (eq 4)

            sol = solve_ivp(rhs, (t_abs[0], t_abs[-1]),
                            [com.step_x0[n, axis], com.step_v0[n, axis]],
                            t_eval=t_abs, rtol=1e-12, atol=1e-14, method="DOP853", first_step=1e-4)
            assert sol.success
            worst = max(worst, float(np.max(np.abs(sol.y[0] - com.pos[:, axis]))))
    assert worst < 1e-6, worst


def test_steps_join_continuously():
    p = TABLE2
    com = tlipfm.com_trajectory(p, np.array([0.0]))
    breaks, (Lx, Kx), (Ly, Ky), _ = tlipfm.zmp_segments(p)
    c = com.constants
    for n in range(p.n_steps - 1):
        for axis, (L, K), shift in ((0, (Lx, Kx), c.zmp_shift), (1, (Ly, Ky), 0.0)):
            x, v = tlipfm.com_closed_form(np.array([p.period]), com.step_x0[n, axis],
                                          com.step_v0[n, axis], breaks, L[n], K[n], c.T, shift)
            assert abs(x[0] - com.step_x0[n + 1, axis]) < 1e-12
            assert abs(v[0] - com.step_v0[n + 1, axis]) < 1e-9


def test_tlipfm_reduces_to_lipm():
    p = TABLE2.replace(mass_thigh=0.0, mass_calf=0.0, l_u=0.0, flywheel_accel=0.0)
    c = tlipfm.pendulum_constants(p, "tlipfm")
    assert c.T == pytest.approx(math.sqrt(p.z_c / GRAVITY), rel=1e-15)
    assert c.zmp_shift == 0.0
    t = np.linspace(0, p.t_start + p.n_steps * p.period + p.t_end, 2001)
    a = tlipfm.com_trajectory(p, t, "tlipfm")
    b = tlipfm.com_trajectory(p, t, "lipm")
    assert np.max(np.abs(a.pos - b.pos)) < 1e-12


def test_pendulum_constants_hand_checked_for_table2():
    # LIPM: sqrt(0.217 / 9.81)
    assert tlipfm.pendulum_constants(TABLE2, "lipm").T == pytest.approx(0.148729, abs=1e-6)
    # DLIPM: (3.05 + 0.95/4) 0.217 / ((3.05 + 0.95/2) 9.81) = 0.713388 / 34.58025
    assert tlipfm.pendulum_constants(TABLE2, "dlipm").T == pytest.approx(0.143631, abs=1e-6)
    # TLIPFM: C^2 = 0.66185 + 0.2745 + 0.0244125 + 0.010171875 = 0.970934375;
    #         M_eff = 3.05 + 0.15 + 0.1875 = 3.3875
    c = tlipfm.pendulum_constants(TABLE2, "tlipfm")
    assert c.c_tau2 == pytest.approx(0.970934375, abs=1e-12)
    assert c.T == pytest.approx(math.sqrt(0.970934375 / (3.3875 * 9.81)), rel=1e-12)
    assert c.T == pytest.approx(0.170930, abs=1e-6)


def test_flywheel_torque_is_a_constant_zmp_shift():
    p = TABLE2.replace(flywheel_accel=10.0)
    c = tlipfm.pendulum_constants(p)
    assert c.tau == pytest.approx(0.26)
    assert c.zmp_shift == pytest.approx(c.T ** 2 * 0.26 / c.c_tau2)


def test_table2_derived_periods():
    assert TABLE2.t_ssp == pytest.approx(0.34)   # Table 2: T_SSP
    assert TABLE2.t_dsp == pytest.approx(0.30)   # Table 2: T_DSP


def test_natural_zmp_is_continuous():
    p = TABLE2
    dt = 1e-5
    t = np.arange(0.0, p.t_start + p.n_steps * p.period + p.t_end, dt)
    z = tlipfm.natural_zmp(p, t)
    _, (Lx, Kx), (Ly, Ky), _ = tlipfm.zmp_segments(p)
    max_slope = max(np.max(np.abs(Kx)), np.max(np.abs(Ky)))
    jumps = np.max(np.abs(np.diff(z, axis=0)))
    assert jumps <= max_slope * dt * 1.001 + 1e-12


def test_natural_zmp_inside_support_foot_in_single_support():
    p = TABLE2
    pc = tlipfm.step_locations(p)
    for n in range(p.n_steps):
        s = np.linspace(p.t1, p.t2, 50)
        z = tlipfm.natural_zmp(p, p.t_start + n * p.period + s)
        # sagittal: from p^c - a to p^c + a (eq 10); lateral: on p^c (eq 11)
        assert np.all(np.abs(z[:, 0] - pc[n, 0]) <= p.a + 1e-12)
        assert np.all(np.abs(z[:, 1] - pc[n, 1]) <= 1e-12)
        # hence inside a 10 cm x 6 cm sole centred on the support foot
        assert np.all(np.abs(z[:, 0] - pc[n, 0]) < 0.05)


def test_step_locations_eqs_6_to_8():
    pc = tlipfm.step_locations(TABLE2)
    assert np.allclose(pc[:4, 0], [0.0, 0.02, 0.04, 0.06])
    # S_first = -1: the right foot (y < 0) supports the first step, the left foot moves first
    assert np.allclose(pc[:4, 1], [-0.045, 0.045, -0.045, 0.045])


def test_cycloid_swing_eq27():
    f = tlipfm.cycloid_swing(np.array([0.15, 0.32, 0.49]), 0.15, 0.49, 0.04, 0.0, 0.03)
    assert np.allclose(f[:, 0], [0.0, 0.02, 0.04])   # (theta - sin theta) Amp_x, Amp_x = 0.04 / 2 pi
    assert np.allclose(f[:, 2], [0.0, 0.03, 0.0])    # (1 - cos theta) H_z / 2


def test_generated_feet_and_com():
    traj = tlipfm.generate(TABLE2, dt=0.01)
    assert traj.zmp_source == "model"
    # 14 steps of 2 cm: the last foot lands beside the 14th support, at 13 S_L
    assert traj.p_world_foot_l[-1, 0] == pytest.approx(0.26)
    assert traj.p_world_foot_r[-1, 0] == pytest.approx(0.26)
    assert traj.p_world_com[-1, 0] == pytest.approx(0.26, abs=2e-3)
    assert np.max(traj.p_world_foot_l[:, 2]) == pytest.approx(0.03, abs=1e-4)
    assert set(np.unique(traj.support)) == {-1, 0, 1}


@pytest.mark.parametrize("changes,match", [
    ({"t1": 0.5, "t2": 0.49}, r"need 0 < t1 < t2 < period, got t1 = 0.5 s"),
    ({"t2": 0.7}, r"t2 = 0.7 s, period = 0.64 s"),
    ({"d1": 0.015}, r"d1 \+ d2 = step_length"),
    ({"z_c": 0.05}, r"tlipfm.z_c = 0.05 m is out of range \[0.08, 0.5\] m"),
    ({"model": "zmp"}, r"tlipfm.model = 'zmp' is not allowed: expected one of 'lipm'"),
    ({"n_steps": 3.5}, r"tlipfm.n_steps must be an integer"),
])
def test_inconsistent_parameters_are_rejected(changes, match):
    with pytest.raises(ParamError, match=match):
        TABLE2.replace(**changes)


def test_dt_out_of_range():
    with pytest.raises(ParamError, match="dt = 0.5 s"):
        tlipfm.generate(TABLE2, dt=0.5)


def test_the_engines_closed_form_is_the_papers():
    """The LIPM's closed form is evaluated twice: the paper's eqs 23-26 over a step's samples
    (``tlipfm.com_closed_form``, the tables) and the engine's segment by segment (``lipm.propagate``,
    ``lipm.dcm_backward``, on the robot every tick). Kept as two evaluations on purpose (either one
    rewritten on the other changes its results in the last bits: the tables' figures, or the engine's
    bit-for-bit reference walks), they must agree on the same ZMP profile."""
    import numpy as np

    from gaits import lipm
    from gaits.tlipfm import _dcm_backward, com_closed_form
    T, tail = 0.17, 0.64
    breaks = np.array([0.0, 0.15, 0.49])
    L, K = np.array([0.01, -0.02, 0.3]), np.array([0.0, 0.09, -0.5])      # ZMP L + K s on each segment
    ends = np.append(breaks[1:], tail)
    knot_t = np.concatenate([[b, e] for b, e in zip(breaks, ends)])
    knot_p = np.array([[Li + Ki * s, 0.0] for b, e, Li, Ki in zip(breaks, ends, L, K) for s in (b, e)])
    for s in (0.05, 0.2, 0.49, 0.6):
        x, v = com_closed_form(np.array([s]), 0.02, 0.1, breaks, L, K, T, 0.004)
        pos, vel = lipm.propagate(np.array([0.02, 0.0]), np.array([0.1, 0.0]), 0.0, s, knot_t, knot_p,
                                  np.array([0.004, 0.0]), T)
        assert abs(pos[0] - x[0]) < 1e-12 and abs(vel[0] - v[0]) < 1e-12, s
    xi_start = _dcm_backward(0.31, breaks, L, K, tail, T, 0.004)
    assert abs(lipm.dcm_backward(np.array([0.31, 0.0]), knot_t, knot_p, np.array([0.004, 0.0]), T)[0] - xi_start) < 1e-12
