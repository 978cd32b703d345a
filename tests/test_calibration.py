"""The pedestal calibration keeps the toe-sticking behaviour it is required to keep, and grids the
blade layer on the grass pedestals as it says."""

import pytest

from conftest import ROOT
from tuner.report import calibration as cal
from tuner.sim.ground import kind_of
from tuner.sim.surfaces import SURFACES, load_surface


def test_toe_sticking_condition_accepts_the_built_in_grass_and_rejects_a_stiff_layer():
    soft = cal.evaluate((1, {}, (0.5,), 1.0, "contact"))[0]                       # the built-in grass50
    assert soft.toe_ok and soft.toe[0] > cal.landing_pitch(SURFACES["carpet4"])[0] + 2.0
    stiff_layer = {"layer_timeconst": 0.015, "layer_dmin": 0.7, "drag": 200.0}
    stiff = cal.evaluate((1, stiff_layer, (0.5,), 1.0, "contact"))[0]
    assert not stiff.toe_ok
    # each candidate's patterns hold the 10 cells of Table 7 order, and agreement counts both tables
    assert len(soft.without) == len(soft.with_) == 10
    paper = cal._paper_pattern(False, 1) + cal._paper_pattern(True, 1)
    assert soft.agree == sum(a == b for a, b in zip(soft.without + soft.with_, paper))


def test_carpet_needs_no_toe_test():
    c = cal.evaluate((4, {}, (0.5,), 1.0, "contact"))[0]
    assert c.toe_ok and c.surface == "carpet4"


def test_the_blade_base_is_the_example_files():
    """BLADE_BASE is examples/surfaces/grass50-blades.yaml's layer, with the jam files' release."""
    plain = load_surface(str(ROOT / "examples/surfaces/grass50-blades.yaml"))
    jam = load_surface(str(ROOT / "examples/surfaces/grass50-blades-jam.yaml"))
    for name, value in cal.BLADE_BASE.items():
        assert getattr(jam if name == "blade_jam_pressure" else plain, name) == value, name
    # a grid point on pedestal 1 with no creep and no jam is that file's layer, named for the pedestal
    s = cal.pedestal_surface(1, {"blade_tip_damping": 0.0, "blade_jam_speed": 0.0, "blade_jam_slide": 0.0}, "blades")
    assert s.replace(name=plain.name, description=plain.description, blade_jam_pressure=0.0) == plain
    assert s.name == "grass50-blades"


def test_blade_tasks_grid_the_grass_pedestals_and_keep_the_carpet():
    tasks = cal.calibration_tasks(gains=(0.5,), layer="blades")
    n_grid = 3 * 3 * 2
    assert [sum(t[0] == ped for t in tasks) for ped in (1, 2, 3, 4)] == [n_grid, n_grid, n_grid, 1]
    assert all(t[4] == "blades" for t in tasks)
    carpet = [t for t in tasks if t[0] == 4][0]
    assert carpet[1] == {} and cal.pedestal_surface(4, {}, "blades") == SURFACES["carpet4"]
    g30 = cal.pedestal_surface(2, {"blade_jam_speed": 0.6, "blade_tip_damping": 1.1e5}, "blades")
    assert kind_of(g30).name == "blades" and g30.jams and g30.layer_height == SURFACES["grass30"].layer_height
    assert (g30.blade_jam_speed, g30.blade_tip_damping, g30.blade_modulus) == (0.6, 1.1e5, cal.BLADE_BASE["blade_modulus"])
    # the tips keep the 50 mm file's share of the blades: 9 mm of 30, 3 mm of 10
    assert g30.blade_tip_depth == pytest.approx(0.009)
    assert cal.pedestal_surface(3, {}, "blades").blade_tip_depth == pytest.approx(0.003)
    # the contact layer's tasks are as before: every grid point on every pedestal
    assert len(cal.calibration_tasks()) == 4 * 5 * 6 * 2
    with pytest.raises(ValueError, match="layer 'turf'"):
        cal.calibration_tasks(layer="turf")


def test_a_tie_goes_to_the_blade_layer_with_the_fewest_mechanisms():
    def cand(**values):
        return cal.Candidate(1, "grass50-blades", values, 0.25, "", "", 12)
    key = cal._simplest_key("blades")
    pool = [cand(blade_tip_damping=1.1e5, blade_jam_speed=0.0, blade_jam_slide=0.0),
            cand(blade_tip_damping=0.0, blade_jam_speed=0.6, blade_jam_slide=0.0),
            cand(blade_tip_damping=0.0, blade_jam_speed=0.65, blade_jam_slide=0.0),
            cand(blade_tip_damping=0.0, blade_jam_speed=0.65, blade_jam_slide=0.16)]
    assert min(pool, key=key) is pool[2]                   # no creep; a jam that fewer landings meet
    assert min(pool[:2], key=key) is pool[1]               # creep counts before a jam
    better = cal.Candidate(1, "grass50-blades", pool[0].values, 0.25, "", "", 13)
    assert min(pool + [better], key=key) is better         # agreement first


@pytest.mark.parametrize("surface", [SURFACES["grass30"], cal.pedestal_surface(1, {"blade_jam_slide": 0.16}, "blades")],
                         ids=["contact", "blades"])
def test_a_written_surface_file_reads_back_equal(tmp_path, surface):
    text = cal.surface_yaml(surface, "made by a test\nsecond line")
    assert text.startswith("# made by a test\n# second line\n")
    path = tmp_path / f"{surface.name}.yaml"
    path.write_text(text, encoding="utf-8")
    assert load_surface(str(path)) == surface


def test_a_one_point_blade_calibration_chooses_what_its_evaluations_say():
    """End to end on one grid point (the jam file's layer) and one heel gain: each grass pedestal's
    candidate is that point, chosen unless pedestal 1 fails the toe-sticking test; the carpet is
    its built-in layer."""
    gain, best, every = cal.calibrate(grid={"blade_jam_speed": (0.6,)}, gains=(0.25,), workers=1, layer="blades")
    assert gain == 0.25 and len(every) == 4
    by_ped = {c.pedestal: c for c in every}
    assert by_ped[4].surface == "carpet4" and by_ped[2].surface == "grass30-blades"
    assert by_ped[1].toe_ok == (1 in best)
    for ped in (2, 3, 4):
        assert best[ped] == by_ped[ped]
    # the jam is a fast landing's: the toe-sticking test's slow landing does not meet it
    assert by_ped[1].toe[0] < cal.landing_pitch(SURFACES["carpet4"])[0] + 2.0


@pytest.mark.parametrize("pedestal, name", [(1, "grass50"), (2, "grass30"), (3, "grass10")])
def test_the_shipped_calibrated_files_are_grid_points_of_their_pedestal(pedestal, name):
    """examples/surfaces/calibrated holds what `calibrate --layer blades --out` wrote: each file is
    pedestal_surface() of one point of BLADE_GRID (the README's figures were measured on them)."""
    s = load_surface(str(ROOT / f"examples/surfaces/calibrated/{name}-blades.yaml"))
    values = {k: getattr(s, k) for k in cal.BLADE_GRID}
    assert all(values[k] in grid for k, grid in cal.BLADE_GRID.items()), values
    assert s == cal.pedestal_surface(pedestal, values, "blades")
