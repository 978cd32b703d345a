"""The sports-turf test methods simulated (tuner/sim/turf_tests.py): each figure computed from the
falling mass's accelerometer as the method defines it, checked against hand calculations on
springs of known rate, and `gait-tuner surfaces --test` through the CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tuner.sim.surfaces import SURFACES
from tuner.sim.turf_tests import (BANDS, WEBOTS_GRASS, RotationTest, SpringGround, drop_test,
                                  rigid_peak_force, rotation_test, sole_sink, webots_ground)

from conftest import run_cli


def test_the_concrete_reference_is_the_published_one():
    """20 kg from 55 mm onto 2000 N/mm on a rigid floor: m g + sqrt((m g)^2 + 2 m g h k) = 6769 N,
    the methods' 6760 N within 0.2 %; the rig on a stiff spring (20 MN/m, ten times the test's)
    gives the hand calculation's 6463 N within 0.5 %."""
    assert rigid_peak_force() == pytest.approx(6760.0, rel=2e-3)
    r = drop_test(SpringGround("stiff", 2e7))
    assert r.force_max_N == pytest.approx(rigid_peak_force(spring=2e6 * 2e7 / (2e6 + 2e7)), rel=5e-3)


@pytest.mark.parametrize("k", [5e4, 2e5, 1e6])
def test_drop_figures_on_a_spring_of_known_rate_match_the_hand_calculation(k):
    """Under the test foot a spring of rate k: the peak force is that of the drop onto the two
    springs in series, k_s k / (k_s + k) (energy balance), the deformation that force over k, and
    a spring returns the energy it took."""
    r = drop_test(SpringGround("spring", k))
    k_eff = 2e6 * k / (2e6 + k)
    f = rigid_peak_force(spring=k_eff)
    assert r.force_max_N == pytest.approx(f, rel=0.01)
    assert r.force_reduction_pct == pytest.approx(100 * (1 - f / 6760.0), abs=1.0)
    assert r.vertical_deformation_mm == pytest.approx(1000 * f / k, rel=0.06)
    assert r.energy_restitution_pct > 80.0
    damped = drop_test(SpringGround("damped", k, damping=0.4 * 2 * math.sqrt(k * 20.0)))
    assert damped.energy_restitution_pct < r.energy_restitution_pct - 20.0


@pytest.mark.parametrize("name", ["rigid", "grass30", "grass50"])
def test_the_deformation_integrated_from_the_accelerometer_is_the_foots_own_travel(name):
    """The method never sees the foot: it integrates the mass's accelerometer twice and subtracts
    the spring's compression. On the simulated surface that equals the foot's own sinking (the
    simulator's ground truth) within 0.3 mm or 4 % of its depth, through the whole impact."""
    r = drop_test(SURFACES[name])
    assert len(r.t) > 50
    assert np.max(np.abs(r.deformation - r.foot_sink)) < max(3e-4, 0.04 * r.foot_sink.max())
    assert r.vertical_deformation_mm == pytest.approx(1000 * r.foot_sink.max(), abs=max(0.3, 40 * r.foot_sink.max()))


def test_rotation_on_a_hard_floor_is_coulomb_friction_at_the_studs():
    """46 kg on six studs on a 46 mm circle, friction 0.9: mu m g r = 18.7 N m; the rig's peak
    (averaged over 50 ms) within 10 %, and within 10 % of itself at the robot's 2 ms step."""
    t = RotationTest()
    coulomb = 0.9 * t.mass * 9.81 * t.stud_circle
    r = rotation_test(SURFACES["rigid"])
    assert r.rotational_torque_Nm == pytest.approx(coulomb, rel=0.10)
    coarse = rotation_test(SURFACES["rigid"], RotationTest(timestep=2e-3))
    assert coarse.rotational_torque_Nm == pytest.approx(r.rotational_torque_Nm, rel=0.10)
    assert rotation_test(WEBOTS_GRASS).rotational_torque_Nm == pytest.approx(0.5 * 46 * 9.81 * 0.046)


def test_webots_grass_is_odes_spring_and_damper():
    g = webots_ground()
    assert g.stiffness == pytest.approx(0.2 / (0.008 * 0.03)) and g.damping == pytest.approx(0.8 / 0.03)
    assert g.friction == 0.5


def test_a_robot_sole_sinks_deeper_into_deeper_soft_blades():
    assert sole_sink(SURFACES["rigid"]) < 0.1
    assert sole_sink(SURFACES["grass50"]) > sole_sink(SURFACES["carpet4"])


def test_surfaces_test_through_the_cli(gait_tuner_cmd, run_env, tmp_path):
    """Strict JSON per surface name with the four figures, the bands, the Webots grass; the text
    table names every surface; a surface YAML is tested too; a bad name is one line, exit 2."""
    r = run_cli(gait_tuner_cmd, ['surfaces', '--test', '--json'], run_env, timeout=600)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert set(doc["surfaces"]) == set(SURFACES) | {"webots-grass"}
    for name, row in doc["surfaces"].items():
        for key in ("force_reduction_pct", "vertical_deformation_mm", "energy_restitution_pct",
                    "rotational_torque_Nm"):
            assert isinstance(row[key], float), (name, key)
    assert doc["bands"]["force_reduction_pct"]["FIFA Quality"] == list(BANDS["force_reduction_pct"]["FIFA Quality"])
    assert doc["scale"]["robot_sole_kPa"] < doc["scale"]["drop_test_static_kPa"]
    text = run_cli(gait_tuner_cmd, ['surfaces', '--test'], run_env, timeout=600)
    assert text.returncode == 0 and all(n in text.stdout for n in doc["surfaces"]), text.stdout
    custom = tmp_path / "practice.yaml"
    custom.write_text("layer_height: 0.02\nlayer_timeconst: 0.02\ndrag: 100\n")
    r = run_cli(gait_tuner_cmd, ['surfaces', '--test', '--json', '--surface', str(custom), '--surface', 'carpet4'],
                run_env, timeout=600)
    assert r.returncode == 0, r.stderr
    assert set(json.loads(r.stdout)["surfaces"]) == {"practice", "carpet4", "webots-grass"}
    bad = run_cli(gait_tuner_cmd, ['surfaces', '--test', '--surface', 'moon'], run_env, timeout=600)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "moon" in bad.stderr


# --- the layer's behaviours at a robot's scale ---------------------------------------------

def test_a_sole_at_rest_settles_at_its_stated_depth():
    """A 4.95 kg robot's 10 x 6 cm sole at rest (the README's table): 2.3 mm into grass50's 50 mm
    blades, under 0.1 mm into the others (MuJoCo's layers stiffen from their tips down)."""
    from tuner.sim.turf_tests import sole_sink
    assert sole_sink(SURFACES["grass50"]) == pytest.approx(2.30, abs=0.1)
    for name in ("rigid", "carpet4", "grass10", "grass30"):
        assert 0.0 < sole_sink(SURFACES[name]) < 0.1, name


def test_a_sole_dragged_sideways_meets_more_resistance_deeper_in_the_blades():
    """Held 2, 10 and 20 mm below grass50's tips and moved sideways at 0.1 m/s: the resistance
    grows with depth; with ``drag_depth`` (ours) the blades' own share starts near zero at the
    tips and reaches the full drag at that depth."""
    from tuner.sim.turf_tests import sole_resistance
    g = SURFACES["grass50"]
    plain = [sole_resistance(g, depth=x) for x in (0.002, 0.01, 0.02)]
    assert plain[0] < plain[1] < plain[2]
    graded = g.replace(drag_depth=0.02)
    no_drag = g.replace(drag=0.0)
    share = [sole_resistance(graded, depth=x) - sole_resistance(no_drag, depth=x) for x in (0.002, 0.01, 0.02)]
    full = sole_resistance(g, depth=0.02) - sole_resistance(no_drag, depth=0.02)
    assert share[0] < 0.2 * full and share[0] < share[1] < share[2]
    assert share[2] == pytest.approx(full, rel=0.05)


def test_a_turned_sole_meets_the_torque_of_its_corners_drag():
    """Turned at 1 rad/s in grass50's blades, the sole meets its contacts' friction torque plus the
    corners' drag, drag x sum(r_i^2) x w = 80 x 4 x (0.05^2 + 0.03^2) x 1 = 1.088 N m (hand
    calculation, within 2 %)."""
    from tuner.sim.turf_tests import sole_resistance
    g = SURFACES["grass50"]
    with_drag = sole_resistance(g, depth=0.01, motion="turn", speed=1.0)
    without = sole_resistance(g.replace(drag=0.0), depth=0.01, motion="turn", speed=1.0)
    assert without > 0.0
    assert with_drag - without == pytest.approx(80.0 * 4 * (0.05 ** 2 + 0.03 ** 2), rel=0.02)


def test_drag_depth_is_a_surface_field_with_a_unit_and_a_bound(tmp_path):
    from tuner.errors import UserError
    from tuner.sim.surfaces import load_surface
    f = tmp_path / "deep.yaml"
    f.write_text("layer_height: 0.03\ndrag: 100\ndrag_depth: 0.01\n")
    assert load_surface(str(f)).drag_depth == 0.01
    f.write_text("layer_height: 0.03\ndrag: 100\ndrag_depth: 0.05\n")
    with pytest.raises(UserError, match="drag_depth = 0.05 m must not exceed layer_height = 0.03 m"):
        load_surface(str(f))
    old = tmp_path / "old.yaml"                  # a surface file written before the field existed
    old.write_text("layer_height: 0.02\nlayer_timeconst: 0.02\ndrag: 50\n")
    assert load_surface(str(old)).drag_depth == 0.0


def test_one_sole_on_grass50_is_held_against_rolling_barely_above_what_the_robot_needs():
    """The roll stiffness of one sole carrying the robot: tens of times the robot's m g h on every
    layer that carries the full-lift EROS walk, under twice it on grass50, the one soft enough to
    catch a toe (why no single contact layer does both: README)."""
    from tuner.sim.turf_tests import sole_roll_stiffness
    need = 4.95 * 9.81 * 0.22
    roll = {n: sole_roll_stiffness(s) for n, s in SURFACES.items()}
    assert need < roll["grass50"] < 2 * need
    assert all(roll[n] > 50 * need for n in ("rigid", "carpet4", "grass10", "grass30"))
    walkable = SURFACES["grass50"].replace(layer_timeconst=0.015, layer_dmin=0.7, drag=200.0)
    assert sole_roll_stiffness(walkable) > 50 * need
