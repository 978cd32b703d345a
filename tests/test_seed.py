"""The CasADi seed: its blocks against numpy references, the TKU-X solve, infeasibility."""

import math

import casadi as ca
import numpy as np
import pytest

from gaits import load_baseline
from gaits import tlipfm as tl
from tuner.search.seed import SWING_CLEARANCE_MARGIN, SeedInfeasible, SeedProblem, lipm_interval_function, seed_for

TABLE2 = load_baseline("tkux-table2").params


@pytest.fixture(scope="module")
def problem():
    return SeedProblem(TABLE2)


def test_lipm_interval_block_matches_the_closed_form():
    T = 0.17
    f = lipm_interval_function(T)
    assert f.name() == "lipm_interval"
    rng = np.random.default_rng(0)
    for _ in range(50):
        x0, v0, p0, p1 = rng.uniform(-0.05, 0.05, 4)
        h = rng.uniform(0.01, 0.2)
        x1, v1 = (float(v) for v in f(x0, v0, p0, p1, h))
        xr, vr = tl.com_closed_form(np.array([h]), x0, v0, np.array([0.0]), np.array([p0]),
                                    np.array([(p1 - p0) / h]), T)
        assert x1 == pytest.approx(xr[0], abs=1e-14) and v1 == pytest.approx(vr[0], abs=1e-13)


def test_natural_zmp_block_matches_gaits(problem):
    f = problem.zmp_ref
    assert f.name() == "natural_zmp_knots"
    theta = np.array([TABLE2.period, TABLE2.t1, TABLE2.t2, TABLE2.a, TABLE2.d1])
    t, px, py, _ = (np.array(v).ravel() for v in f(theta, TABLE2.step_length, TABLE2.half_width))
    walk = (t >= problem.t_stand - 1e-12) & (t <= problem.t_stand + problem.layout.n_steps * TABLE2.period - 1e-9)
    p = TABLE2.replace(n_steps=problem.layout.n_steps, t_start=problem.t_stand)
    ref = tl.natural_zmp(p, t[walk])
    assert np.max(np.abs(ref[:, 0] - px[walk])) < 1e-12
    assert np.max(np.abs(ref[:, 1] - py[walk])) < 1e-12


def test_seed_solves_for_tkux_within_bounds_with_zmp_inside(problem):
    res = problem.solve()
    th = res.theta
    assert 0.4 <= th["period"] <= 1.2 and 0.05 <= th["t1"] < th["t2"] < th["period"]
    assert 0.0 <= th["a"] <= 0.02 and 0.0 <= th["d"] <= TABLE2.step_length
    assert res.min_margin >= problem.margin - 1e-6          # ZMP inside the sole in single support
    assert res.resim_gap < 1e-9                              # closed-form re-simulation agrees
    assert res.solve_time < 1.0                              # target: < 1 s after the build
    res.tlipfm.check_consistency()                           # a valid TlipfmParams
    assert res.tlipfm.d1 + res.tlipfm.d2 == pytest.approx(TABLE2.step_length)


def test_seed_moves_the_timing_with_the_step(problem):
    short = problem.solve(step_length=0.01).theta
    long = problem.solve(step_length=0.06).theta
    assert long["period"] > short["period"]
    assert long["t2"] - long["t1"] < short["t2"] - short["t1"]   # longer double support for long steps


def test_infeasible_plan_names_the_binding_constraint(problem):
    # a second double support needs period - t2 >= 0.05 s: impossible with these boxes
    with pytest.raises(SeedInfeasible, match=r"binding constraint 'period - t2 >= 0.05 s"):
        problem.solve(bounds={"period": (0.4, 0.45), "t2": (0.5, 0.6)})
    with pytest.raises(SeedInfeasible, match=r"bounds for t1 are empty"):
        problem.solve(bounds={"t1": (0.7, 0.8)})
    with pytest.raises(ValueError, match="leaves no room"):
        SeedProblem(TABLE2, margin=0.04)


def test_seed_maps_onto_the_other_families():
    eros = seed_for("eros", load_baseline("eros-x24-with").params)
    assert eros.step_x == 0.024 and math.radians(0.25) <= eros.t_mn <= math.radians(45)
    cos = seed_for("cosine", load_baseline("cosine-setiono").params)
    assert cos.step == 0.04
    tlp = seed_for("tlipfm", TABLE2)
    assert tlp.FAMILY == "tlipfm"


def test_cost_block_is_a_named_function(problem):
    assert isinstance(problem.cost_terms, ca.Function) and problem.cost_terms.name() == "seed_cost"


def test_seed_lifts_the_swing_foot_over_the_tallest_layer():
    base = TABLE2.replace(h_z=0.02)
    assert seed_for("tlipfm", base).h_z == 0.02                        # rigid floor: the base's lift
    assert seed_for("tlipfm", base, layer_height=0.05).h_z == pytest.approx(0.05 + SWING_CLEARANCE_MARGIN)
    assert seed_for("tlipfm", base.replace(h_z=0.08), layer_height=0.05).h_z == 0.08   # never lowered
    assert seed_for("tlipfm", base, layer_height=0.10).h_z == 0.10     # clipped to the bound of H_z
    eros = seed_for("eros", load_baseline("eros-x24-with").params.replace(foot_lift=0.02), layer_height=0.03)
    assert eros.foot_lift == pytest.approx(0.04)
    with pytest.raises(ValueError, match="layer_height"):
        seed_for("tlipfm", base, layer_height=-0.01)
