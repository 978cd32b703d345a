"""The turf models side by side: what a walk costs on each, the toe-first landing, the full-lift
EROS tables on the first pedestal, and the turf test methods.

    python benchmarks/bench_turf.py [--repeats 5] [--surfaces rigid,grass50,examples/surfaces/grass50-blades.yaml,...]

Cost: the same TLIPFM walk (tkux-table2, 10 s) on each surface, the surfaces interleaved in every
repeat (this machine is noisy), the minimum of the repeats, as a ratio to the rigid floor's.
Landing: ``Simulator.landing_test`` (3 deg pitched, 0.1 m/s forward), max and final torso pitch
beside carpet4's. Tables: the EROS experiment's Tables 7 and 8 on the surface as pedestal 1
(stable cells of 10). Turf tests: ``gait-tuner surfaces --test``'s figures.
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
from tuner.sim.turf_tests import drop_test, rotation_test, sole_roll_stiffness, sole_sink  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ["rigid", "carpet4", "grass50", str(ROOT / "examples/surfaces/grass50-blades.yaml"),
           str(ROOT / "examples/surfaces/grass50-blades-creep.yaml")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--surfaces", default=",".join(DEFAULT))
    a = ap.parse_args()
    robot = load_robot("kidsize")
    surfaces = [load_surface(s) for s in a.surfaces.split(",")]
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, robot.sim.control_period)
    sims = {s.name: Simulator(robot, s) for s in surfaces}
    best = {n: math.inf for n in sims}
    for _ in range(a.repeats):
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
