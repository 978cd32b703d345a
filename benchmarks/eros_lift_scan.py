"""Why the EROS experiment scales the paper's lift by 0.2: stability and progress by lift scale.

Usage: ``python benchmarks/eros_lift_scan.py``

For each lift scale (the paper's Z x s) and surface, the EROS gait without and
with its optimisation at 0, 8, 16 and 24 mm (Y, Z per ``tuner.experiments.eros_params``):
S = stayed up, U = fell, followed by the distance covered as a fraction of the plan.
"""

from __future__ import annotations

import gaits
from tuner import experiments as ex
from tuner.metrics import summarize
from tuner.robot import load_robot
from tuner.simulate import Simulator
from tuner.surfaces import SURFACES


def main() -> None:
    robot = load_robot("kidsize")
    for surface in ("carpet4", "grass50"):
        sim = Simulator(robot, SURFACES[surface])
        for scale in (0.2, 0.3, 0.5, 1.0):
            cells = []
            for optimised in (False, True):
                for step in (0, 8, 16, 24):
                    p = ex.eros_params(step, optimised)
                    p = p.replace(foot_lift=p.foot_lift * scale)
                    traj = gaits.generate(p, robot.leg, sim.control_period)
                    m = summarize(sim.rollout(traj))
                    plan = traj.p_world_pelvis[-1, 0] - traj.p_world_pelvis[0, 0]
                    cover = f"{m.distance_m / plan:.1f}" if abs(plan) > 1e-3 else "-"
                    cells.append(("U" if m.fell else "S") + cover)
            print(f"{surface:8s} lift x{scale:<4g} without {' '.join(cells[:4])}   with {' '.join(cells[4:])}")


if __name__ == "__main__":
    main()
