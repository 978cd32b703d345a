"""The pedestal calibration keeps the toe-sticking behaviour it is required to keep."""

from tuner.report import calibration as cal
from tuner.sim.surfaces import SURFACES


def test_toe_sticking_condition_accepts_the_built_in_grass_and_rejects_a_stiff_layer():
    soft = cal.evaluate((1, {}, (0.5,), 1.0))[0]                       # the built-in grass50
    assert soft.toe_ok and soft.toe[0] > cal.landing_pitch(SURFACES["carpet4"])[0] + 2.0
    stiff = cal.evaluate((1, {"layer_timeconst": 0.015, "layer_dmin": 0.7, "drag": 200.0}, (0.5,), 1.0))[0]
    assert not stiff.toe_ok
    # each candidate's patterns hold the 10 cells of Table 7 order, and agreement counts both tables
    assert len(soft.without) == len(soft.with_) == 10
    paper = cal._paper_pattern(False, 1) + cal._paper_pattern(True, 1)
    assert soft.agree == sum(a == b for a, b in zip(soft.without + soft.with_, paper))


def test_carpet_needs_no_toe_test():
    c = cal.evaluate((4, {}, (0.5,), 1.0))[0]
    assert c.toe_ok and c.surface == "carpet4"
