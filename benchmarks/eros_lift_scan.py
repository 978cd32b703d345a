"""Why the paper's literal EROS cycle cannot take its own lift: stability and progress by lift scale.

Usage: ``python benchmarks/eros_lift_scan.py``

For each lift scale (the paper's Z x s) and surface, the EROS gait without and
with its optimisation at 0, 8, 16 and 24 mm (Y, Z per ``tuner.experiments.eros_params``):
S = stayed up, U = fell, followed by the distance covered as a fraction of the plan.
The gait is the literal cycle (``double_support = 0``); before the double-support
phase of ``gaits/eros.py`` the experiment scaled the lift by 0.2 because of this.

Then, why a high lift falls (rigid floor, 8 mm, without optimisation): the
paper's cycle has no double-support time and its hip sway is a sinusoid
through the centre at every lift-off, so when the foot leaves the ground the
CoM is not over the stance sole (it lags the hip: at the first lift-off it is
still on the swing side). A low foot touches down again and catches the robot
(it shuffles); a high one cannot. Printed per lift scale: the swing foot's
take-off speed (eq 38 starts at full speed), the torso's peak roll rate in the
0.2 s after the first lift-off, and the CoM's lateral distance from the stance
sole's centre at that lift-off.
"""

from __future__ import annotations

import numpy as np

import gaits
from tuner.report import experiments as ex
from tuner.sim.metrics import summarize
from tuner.robots import load_robot
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES


def main() -> None:
    robot = load_robot("kidsize")
    for surface in ("carpet4", "grass50"):
        sim = Simulator(robot, SURFACES[surface])
        for scale in (0.2, 0.3, 0.5, 1.0):
            cells = []
            for optimised in (False, True):
                for step in (0, 8, 16, 24):
                    p = ex.eros_params(step, optimised, double_support=0.0)
                    p = p.replace(foot_lift=p.foot_lift * scale)
                    traj = gaits.generate(p, robot.leg, sim.control_period)
                    m = summarize(sim.rollout(traj))
                    plan = traj.p_world_pelvis[-1, 0] - traj.p_world_pelvis[0, 0]
                    cover = f"{m.distance_m / plan:.1f}" if abs(plan) > 1e-3 else "-"
                    cells.append(("U" if m.fell else "S") + cover)
            print(f"{surface:8s} lift x{scale:<4g} without {' '.join(cells[:4])}   with {' '.join(cells[4:])}")
    sim = Simulator(robot, SURFACES["rigid"])
    print("\nlift-off on the rigid floor, 8 mm, without optimisation:")
    for scale in (0.2, 0.3, 0.5, 1.0):
        p = ex.eros_params(8, False, double_support=0.0)
        p = p.replace(foot_lift=p.foot_lift * scale)
        traj = gaits.generate(p, robot.leg, sim.control_period)
        tr = sim.rollout(traj)
        k0 = int(np.flatnonzero(traj.support != 0)[0])
        k1 = min(k0 + int(round(0.2 / sim.control_period)), len(tr.t) - 1)
        roll_rate = np.degrees(np.abs(np.diff(tr.roll[k0:k1 + 1])) / sim.control_period).max()
        stance = tr.p_sole_r if traj.support[k0] < 0 else tr.p_sole_l
        off = abs(tr.p_com[k0, 1] - stance[k0, 1])
        take_off = p.foot_lift * p.t_mn / p.tick
        print(f"  lift x{scale:<4g} Z = {p.foot_lift * 1000:5.1f} mm: take-off speed {take_off:.2f} m/s, "
              f"peak roll rate {roll_rate:5.1f} deg/s, CoM {off * 1000:4.1f} mm from the stance sole's "
              f"centre (sole half-width {robot.foot_size[1] / 2 * 1000:.0f} mm); "
              f"{'fell' if tr.fell else 'stayed up'}")


if __name__ == "__main__":
    main()
