"""``gait-tuner surfaces --test``: the sports-turf test methods on every surface, beside the published
bands for football turf and beside the robot's own scale (``tuner/sim/turf_tests.py`` runs them).

Plain data out (strict-JSON friendly); ``tuner/report/tables.py`` formats it for a terminal.
"""

from __future__ import annotations

import math
from typing import Any, Iterable

from gaits.trajectory import GRAVITY

from ..sim.surfaces import Surface
from ..sim.turf_tests import (BANDS, WEBOTS_GRASS, DropTest, RotationTest, SpringGround, drop_test, rotation_test,
                              sole_roll_stiffness, sole_sink)

__all__ = ["surface_tests", "FIGURES"]

#: The four figures of each surface, in print order: (key, unit, what it is).
FIGURES = (("force_reduction_pct", "%", "force reduction (drop test)"),
           ("vertical_deformation_mm", "mm", "vertical deformation (drop test)"),
           ("energy_restitution_pct", "%", "energy restitution (drop test)"),
           ("rotational_torque_Nm", "N m", "rotational resistance, peak torque"))


def _finite(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), 3)


def _in_bands(key: str, value: float | None) -> list[str]:
    if value is None:
        return []
    return [mark for mark, (lo, hi) in BANDS[key].items() if lo <= value <= hi]


def _one(ground: Surface | SpringGround, robot_mass: float, sole: tuple[float, float]) -> dict[str, Any]:
    d = drop_test(ground)
    r = rotation_test(ground)
    row: dict[str, Any] = {
        "force_reduction_pct": _finite(d.force_reduction_pct),
        "vertical_deformation_mm": _finite(d.vertical_deformation_mm),
        "energy_restitution_pct": _finite(d.energy_restitution_pct),
        "rotational_torque_Nm": _finite(r.rotational_torque_Nm),
        "force_max_N": _finite(d.force_max_N),
        "stud_sink_mm": _finite(r.sink_mm),
    }
    if isinstance(ground, Surface):
        row["layer_mm"] = round(ground.layer_height * 1000.0, 3)
        row["robot_sole_sink_mm"] = _finite(sole_sink(ground, mass=robot_mass, sole=sole))
        row["robot_sole_roll_Nm_per_rad"] = _finite(sole_roll_stiffness(ground, mass=robot_mass, sole=sole))
        row["description"] = ground.description
    else:
        row["layer_mm"] = None
        row["robot_sole_sink_mm"] = _finite(1000.0 * robot_mass * GRAVITY / (4 * ground.stiffness))
        # four springs at the sole's corners: 4 k (w/2)^2
        row["robot_sole_roll_Nm_per_rad"] = _finite(4 * ground.stiffness * (sole[1] / 2) ** 2)
        row["description"] = ground.description
    row["in_bands"] = {key: _in_bands(key, row[key]) for key, _, _ in FIGURES}
    return row


def surface_tests(surfaces: Iterable[Surface], *, robot_mass: float = 4.95,
                  sole: tuple[float, float] = (0.10, 0.06), robot_com_height: float = 0.22,
                  webots: bool = True) -> dict[str, Any]:
    """Every figure of every surface (and the Webots grass unless ``webots`` is off), the bands, the
    methods' numbers and the two scales (drop test vs a robot's sole at rest)."""
    t, rt = DropTest(), RotationTest()
    g = GRAVITY
    drop_kpa = (t.mass + t.foot_mass) * g / (math.pi * (t.foot_diameter / 2) ** 2) / 1000.0
    robot_kpa = robot_mass * g / (sole[0] * sole[1]) / 1000.0
    out: dict[str, Any] = {"surfaces": {s.name: _one(s, robot_mass, sole) for s in surfaces}}
    if webots:
        out["surfaces"][WEBOTS_GRASS.name] = _one(WEBOTS_GRASS, robot_mass, sole)
        out["surfaces"][WEBOTS_GRASS.name]["note"] = (
            "one contact point under the test foot, four under the robot's sole (ODE's box on a plane); "
            "the rotation is Coulomb friction at the studs (no layer to enter)")
    out["bands"] = {k: {m: list(v) for m, v in marks.items()} for k, marks in BANDS.items()}
    out["methods"] = {
        "drop": {"mass_kg": t.mass, "drop_m": t.drop, "spring_N_per_m": t.spring, "foot_diameter_m": t.foot_diameter,
                 "foot_mass_kg": t.foot_mass, "reference_force_N": t.reference_force, "filter_hz": t.filter_hz},
        "rotation": {"mass_kg": rt.mass, "disc_diameter_m": rt.disc_diameter, "studs": rt.studs,
                     "stud_circle_m": rt.stud_circle, "drop_m": rt.drop, "speed_deg_s": round(math.degrees(rt.speed), 3),
                     "turn_deg": round(math.degrees(rt.turn), 3)},
    }
    out["scale"] = {"drop_test_static_kPa": round(drop_kpa, 2), "robot_sole_kPa": round(robot_kpa, 2),
                    "robot_topple_Nm_per_rad": round(robot_mass * g * robot_com_height, 2),
                    "robot_com_height_m": robot_com_height,
                    "robot_mass_kg": robot_mass, "robot_sole_m": list(sole),
                    "drop_test_peak_kPa": round(t.reference_force / (math.pi * (t.foot_diameter / 2) ** 2) / 1000.0, 1)}
    return out
