"""The EROS double-support phase in physics: both feet carry the robot for the set share of each
step, and the CoM crosses to the new stance foot while they do (rigid floor, built-in robot)."""

import math

import numpy as np
import pytest

import gaits
from gaits import eros, load_baseline
from tuner.robots import load_robot
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES

ROBOT = load_robot("kidsize")


def _walk(params):
    sim = Simulator(ROBOT, SURFACES["rigid"])
    return sim.rollout(gaits.generate(params, ROBOT.leg, sim.control_period))


def _loaded(trace):
    weight = float(np.median(trace.force[:, :].sum(axis=1)))
    left = trace.force[:, :4].sum(axis=1) > 0.1 * weight
    right = trace.force[:, 4:].sum(axis=1) > 0.1 * weight
    return left, right


def _walking_window(params, trace):
    ref = eros.eros_references(params)
    kinds = [tr.kind for tr in eros.via_points(params)]
    first = ref.t[ref.via_ticks[kinds.index("lift")]]
    last = ref.t[ref.via_ticks[len(kinds) - 1 - kinds[::-1].index("land") + 1]]
    return (trace.t >= first) & (trace.t <= last)


@pytest.mark.parametrize("share", [0.3, 0.4])
def test_both_feet_loaded_for_the_share(share):
    p = load_baseline("eros-x16-without").params.replace(double_support=share)
    trace = _walk(p)
    assert not trace.fell, trace.reason
    left, right = _loaded(trace)
    window = _walking_window(p, trace)
    both = np.mean((left & right)[window])
    assert share - 0.1 <= both <= share + 0.1, both


def test_com_moves_to_the_new_stance_foot_during_double_support():
    p = load_baseline("eros-x16-without").params
    trace = _walk(p)
    left, right = _loaded(trace)
    window = _walking_window(p, trace)
    both = left & right & window
    y = trace.p_com[:, 1] - 0.5 * (trace.p_sole_l[:, 1] + trace.p_sole_r[:, 1])
    # each double-support spell: the CoM goes from one foot's side toward the other's
    spells = np.flatnonzero(np.diff(both.astype(int)) == 1) + 1
    ends = np.flatnonzero(np.diff(both.astype(int)) == -1) + 1
    crossings = 0
    for a in spells:
        b = ends[ends > a][0] if np.any(ends > a) else len(y) - 1
        if b - a < 5:
            continue
        crossings += y[a] * y[b] < 0 or abs(y[b] - y[a]) > 0.01
    assert crossings >= 0.8 * (p.n_steps - 1)


def test_literal_cycle_has_no_double_support_and_falls_at_the_full_lift():
    p = load_baseline("eros-x16-without").params.replace(double_support=0.0, t_mn=math.radians(2.5))
    trace = _walk(p)
    assert trace.fell                                     # the finding, kept visible
