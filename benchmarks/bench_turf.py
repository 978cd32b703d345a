"""The turf models side by side: what a walk costs on each, the toe-first landing, the full-lift
EROS tables on the first pedestal, and the turf test methods.

    python benchmarks/bench_turf.py [--repeats 5] [--surfaces rigid,grass50,examples/surfaces/grass50-blades.yaml,...]
                                    [--parts table,foot,variants]

Cost: the same TLIPFM walk (tkux-table2, 10 s) on each surface, the surfaces interleaved in every
repeat (this machine is noisy), the minimum of the repeats, as a ratio to the rigid floor's.
Landing: ``Simulator.landing_test`` (3 deg pitched, 0.1 m/s forward), max and final torso pitch
beside carpet4's. Tables: the EROS experiment's Tables 7 and 8 on the surface as pedestal 1
(stable cells of 10). Turf tests: ``gait-tuner surfaces --test``'s figures.

``foot``: the drop test's force reduction and deformation with a 0.1, 1 and 3 kg test foot (the
apparatus' foot mass is not in our sources: how much the figures hang on it). ``variants``: the
blade layer's example file with one number changed at a time (by a fifth or more), its landing
and Tables 7 and 8 on pedestal 1: how much its figures hang on its numbers.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gaits  # noqa: E402
from tuner.report.experiments import eros_matrix, stability_percent  # noqa: E402
from tuner.robots import load_robot  # noqa: E402
from tuner.sim.rollout import Simulator  # noqa: E402
from tuner.sim.surfaces import load_surface  # noqa: E402
from tuner.sim.turf_tests import DropTest, drop_test, rotation_test, sole_roll_stiffness, sole_sink  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ["rigid", "carpet4", "grass50", str(ROOT / "examples/surfaces/grass50-blades.yaml"),
           str(ROOT / "examples/surfaces/grass50-blades-creep.yaml")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--surfaces", default=",".join(DEFAULT))
    ap.add_argument("--parts", default="table,foot,variants")
    a = ap.parse_args()
    parts = set(a.parts.split(","))
    if not parts <= {"table", "foot", "variants"}:
        ap.error(f"--parts {a.parts!r}: the parts are table, foot, variants")
    robot = load_robot("kidsize")
    surfaces = [load_surface(s) for s in a.surfaces.split(",")]
    if "table" in parts:
        table(robot, surfaces, a.repeats)
    if "foot" in parts:
        print("\ndrop test with the test foot's mass: force reduction % / vertical deformation mm")
        for s in surfaces:
            cells = [drop_test(s, DropTest(foot_mass=fm)) for fm in (0.1, 1.0, 3.0)]
            print(f"  {s.name:22s}" + "   ".join(f"{fm:g} kg {c.force_reduction_pct:5.1f} / {c.vertical_deformation_mm:5.2f}"
                                              for fm, c in zip((0.1, 1.0, 3.0), cells)))
    if "variants" in parts:
        variants(robot)


VARIANTS = ({}, {"blade_modulus": 1.8e7}, {"blade_modulus": 2.6e7}, {"blade_tip_depth": 0.01},
            {"blade_tip_depth": 0.02}, {"blade_tip_modulus": 5e4}, {"drag": 100.0}, {"blade_shear": 3e6},
            {"friction": 1.0}, {"blade_damping": 2e5})


def variants(robot) -> None:
    base = load_surface(str(ROOT / "examples/surfaces/grass50-blades.yaml"))
    q0 = gaits.generate(gaits.load_baseline("eros-x8-without").params, robot.leg).q_ref[0]
    print("\ngrass50-blades, one number changed: landing max / final deg, Table 7 / 8 % on pedestal 1")
    for change in VARIANTS:
        s = base.replace(**change)
        tr = Simulator(robot, s).landing_test(q0, pitch=math.radians(3.0), forward_speed=0.1)
        t7 = stability_percent(eros_matrix(robot, {1: s}, optimised=False))[1]
        t8 = stability_percent(eros_matrix(robot, {1: s}, optimised=True))[1]
        label = ", ".join(f"{k} {v:g}" for k, v in change.items()) or "as shipped"
        print(f"  {label:26s} {np.degrees(tr.pitch.max()):5.2f} / {np.degrees(tr.pitch[-1]):5.2f}   {t7:3.0f} / {t8:3.0f}",
              flush=True)


def table(robot, surfaces, repeats: int) -> None:
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, robot.sim.control_period)
    sims = {s.name: Simulator(robot, s) for s in surfaces}
    best = {n: math.inf for n in sims}
    for _ in range(repeats):
        for n, sim in sims.items():
            t0 = time.perf_counter()
            sim.rollout(traj)
            best[n] = min(best[n], time.perf_counter() - t0)
    rigid = best.get("rigid")
    q0 = gaits.generate(gaits.load_baseline("eros-x8-without").params, robot.leg).q_ref[0]
    print(f"{'surface':22s}{'walk s':>8s}{'x rigid':>8s}{'land max':>9s}{'final':>7s}{'T7 %':>6s}{'T8 %':>6s}"
          f"{'FR %':>7s}{'VD mm':>7s}{'RR N m':>7s}{'sink mm':>8s}{'roll':>7s}")
    for s in surfaces:
        tr = sims[s.name].landing_test(q0, pitch=math.radians(3.0), forward_speed=0.1)
        t7 = stability_percent(eros_matrix(robot, {1: s}, optimised=False))[1]
        t8 = stability_percent(eros_matrix(robot, {1: s}, optimised=True))[1]
        d, r = drop_test(s), rotation_test(s)
        ratio = best[s.name] / rigid if rigid else float("nan")
        print(f"{s.name:22s}{best[s.name]:8.3f}{ratio:8.2f}{np.degrees(tr.pitch.max()):9.2f}"
              f"{np.degrees(tr.pitch[-1]):7.2f}{t7:6.0f}{t8:6.0f}{d.force_reduction_pct:7.1f}"
              f"{d.vertical_deformation_mm:7.1f}{r.rotational_torque_Nm:7.1f}{sole_sink(s):8.2f}"
              f"{sole_roll_stiffness(s):7.0f}")


if __name__ == "__main__":
    main()
