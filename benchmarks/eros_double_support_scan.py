"""How the EROS double-support share and T_mn were chosen: walks at the paper's full lift.

Usage: ``python benchmarks/eros_double_support_scan.py [--steps 20]``

For each double-support share (0 = the paper's literal cycle) and T_mn, the
un-optimised EROS gait at the paper's three settings (X, Y, Z) = (8, 45, 100),
(16, 35, 95), (24, 25, 90) mm with its full lift, stance 2Y + 5 mm (at least
65 mm; ``tuner.report.experiments.eros_params``), walks ``--steps`` steps on
the rigid floor and each pedestal. Printed per cell: S = stayed up, U = fell,
then the step time. The baselines take the share and T_mn that walk every
setting on the rigid floor and carpet4.
"""

from __future__ import annotations

import argparse
import math

import gaits
from gaits import eros
from tuner.report import experiments as ex
from tuner.robots import load_robot
from tuner.sim.metrics import summarize
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES

SURFACE_NAMES = ("rigid", "carpet4", "grass10", "grass30", "grass50")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20)
    args = ap.parse_args()
    robot = load_robot("kidsize")
    sims = {name: Simulator(robot, SURFACES[name]) for name in SURFACE_NAMES}
    print(f"{'share':>5s} {'T_mn':>5s} {'step':>6s}  " + "  ".join(f"{n:>8s}" for n in SURFACE_NAMES)
          + "   (cells: X = 8 / 16 / 24 mm)")
    for share in (0.0, 0.3, 0.35, 0.4, 0.45, 0.5):
        for t_mn_deg in (3.0, 4.0, 5.0):
            row = []
            for sim in sims.values():
                cells = ""
                for x in (8, 16, 24):
                    p = ex.eros_params(x, False, double_support=share).replace(
                        t_mn=math.radians(t_mn_deg), n_steps=args.steps)
                    m = summarize(sim.rollout(gaits.generate(p, robot.leg, sim.control_period)))
                    cells += "U" if m.fell else "S"
                row.append(cells)
            step_s = (2 * len(eros.angle_steps(p.t_mn)) + 2 * eros.dsp_ticks(p)) * p.tick
            print(f"{share:5.2f} {t_mn_deg:5.1f} {step_s:5.2f}s  " + "  ".join(f"{c:>8s}" for c in row), flush=True)


if __name__ == "__main__":
    main()
