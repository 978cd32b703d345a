"""The sports-turf test methods simulated (tuner/sim/turf_tests.py): each figure computed from the
falling mass's accelerometer as the method defines it, checked against hand calculations on
springs of known rate, and `gait-tuner surfaces --test` through the CLI."""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest

from tuner.sim.surfaces import SURFACES
from tuner.sim.turf_tests import (BANDS, WEBOTS_GRASS, DropTest, RotationTest, SpringGround, drop_test,
                                  rigid_peak_force, rotation_test, sole_sink, webots_ground)


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
    r = subprocess.run(gait_tuner_cmd + ["surfaces", "--test", "--json"], capture_output=True, text=True,
                       env=run_env, timeout=600)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert set(doc["surfaces"]) == set(SURFACES) | {"webots-grass"}
    for name, row in doc["surfaces"].items():
        for key in ("force_reduction_pct", "vertical_deformation_mm", "energy_restitution_pct",
                    "rotational_torque_Nm"):
            assert isinstance(row[key], float), (name, key)
    assert doc["bands"]["force_reduction_pct"]["FIFA Quality"] == list(BANDS["force_reduction_pct"]["FIFA Quality"])
    assert doc["scale"]["robot_sole_kPa"] < doc["scale"]["drop_test_static_kPa"]
    text = subprocess.run(gait_tuner_cmd + ["surfaces", "--test"], capture_output=True, text=True, env=run_env,
                          timeout=600)
    assert text.returncode == 0 and all(n in text.stdout for n in doc["surfaces"]), text.stdout
    custom = tmp_path / "practice.yaml"
    custom.write_text("layer_height: 0.02\nlayer_timeconst: 0.02\ndrag: 100\n")
    r = subprocess.run(gait_tuner_cmd + ["surfaces", "--test", "--json", "--surface", str(custom), "--surface",
                                         "carpet4"], capture_output=True, text=True, env=run_env, timeout=600)
    assert r.returncode == 0, r.stderr
    assert set(json.loads(r.stdout)["surfaces"]) == {"practice", "carpet4", "webots-grass"}
    bad = subprocess.run(gait_tuner_cmd + ["surfaces", "--test", "--surface", "moon"], capture_output=True,
                         text=True, env=run_env, timeout=600)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "moon" in bad.stderr
