"""Record the reference walks that ``tests/test_loop_reference.py`` replays through the loop.

Recorded once with the table-replay loop of commit df58f72 (before the controller loop), so the
test proves that the controller loop walks every table exactly as that loop did. Re-running
this script with today's code rewrites the file from today's loop: do that only on purpose.

usage: python tests/data/record_reference_traces.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import gaits
from gaits import WalkCommand, command_walk
from tuner.params_io import resolve_params
from tuner.robots import load_robot
from tuner.sim.randomisation import EVALUATE, Randomisation, draw
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES

OUT = Path(__file__).with_name("reference_traces.npz")
FIELDS = ("t", "q", "q_cmd", "q_sent", "pitch", "roll", "yaw", "p_com", "force")
DURATION = 3.0

#: (name, params, surface, command or None, perturbed seed or None, push [N s], stabiliser on)
CASES = (
    [(f"table2-{s}", "tkux-table2", s, None, None, 0.0, False) for s in SURFACES]
    + [(f"table2-{s}-perturbed", "tkux-table2", s, None, 3, 0.0, False) for s in ("rigid", "carpet4", "grass50")]
    + [("fb-grass50-stabiliser", "kidsize-robust-fb-grass50", "grass50", None, None, 0.0, True),
       ("fb-grass50-stabiliser-perturbed-push", "kidsize-robust-fb-grass50", "grass50", None, 5, 1.0, True),
       ("fb-carpet4-stabiliser-perturbed", "kidsize-robust-fb-grass50", "carpet4", None, 11, 0.0, True),
       ("omni-carpet4-command", "kidsize-omni-carpet4", "carpet4", (0.2, 0.0, 0.3), None, 0.0, False),
       ("omni-grass30-command-perturbed-push", "kidsize-omni-grass30", "grass30", (0.15, 0.03, 0.0), 2, 0.75, False),
       ("eros-x8-carpet4", "eros-x8-with", "carpet4", None, None, 0.0, False)]
)


def walk(case, robot, sims):
    name, spec, surface, command, seed, push, stab = case
    sim = sims.setdefault(surface, Simulator(robot, SURFACES[surface]))
    gf = resolve_params(spec, None)
    if command is None:
        traj = gaits.generate(gf.params, robot.leg, sim.control_period)
    else:
        traj = command_walk(gf.params, robot, WalkCommand(*command), sim.control_period)
    pert = None if seed is None else draw(Randomisation(push=push), (seed, 0), *sim.n_random(), namespace=EVALUATE)
    return sim.rollout(traj, duration=DURATION, perturb=pert, stabiliser=gf.stabiliser if stab else None)


def main() -> None:
    robot = load_robot("kidsize-pd")
    sims: dict = {}
    arrays = {}
    for case in CASES:
        tr = walk(case, robot, sims)
        for f in FIELDS:
            arrays[f"{case[0]}/{f}"] = np.asarray(getattr(tr, f))
        arrays[f"{case[0]}/reason"] = np.array(tr.reason)
        print(f"{case[0]:40s} {len(tr.t):4d} ticks  {tr.reason}")
    np.savez_compressed(OUT, **arrays)
    print(f"wrote {OUT} ({OUT.stat().st_size / 1e6:.1f} MB)")


if __name__ == "__main__":
    main()
