"""What a walk tells of the servos (issue: servos as they are, "from walking recordings"), run as a
script:

    python tests/bench_walk_servos.py [--seconds 3] [--surface carpet4] [--workers 2]
        [--robot MAP] [--params SET | --controller CONTROLLER.yaml]

A hidden robot of its own: the robot (default the built-in one) whose knees' gain is 20 % below its
map's and its hips' 20 % above (a motor's through its P register), its commands two ticks late; one
walk of ``--seconds`` (``--params`` or ``--controller``, as ``simulate`` takes them; default the carpet4
engine set; at 0.15 m/s, the randomisation's
sensor noise) recorded on ``--surface``, and ``identify_servos_from_walks`` on it from the map's
servos. Prints the fitted gains against the truth, the latency, the residuals and the cost. Not
collected by pytest (its name); ``test_identify.py`` records its walk with :func:`hidden_walk`.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: the hidden servos: gain factors per leg group (ours), and the latency in ticks
TRUTH = {"hips": 1.2, "knees": 0.8, "ankles": 1.0}
LATENCY_TICKS = 2


def hidden_walk(path, seconds: float, surface: str = "carpet4", seed: int = 7, robot_name: str = "kidsize",
                params: str | None = "kidsize-engine-carpet4", controller: str | None = None):
    """Record a walk of the hidden robot (the module's docstring) into ``path`` (MCAP)."""
    from gaits import parse_command
    from tuner.identify.servos import group_of
    from tuner.identify.walk_servos import scaled_gain
    from tuner.params_io import resolve_drive
    from tuner.robots import load_robot
    from tuner.sim.randomisation import SENSORS_ONLY, draw
    from tuner.sim.record import recording
    from tuner.sim.rollout import Simulator
    from tuner.sim.surfaces import load_surface
    robot = load_robot(robot_name)
    servos = dict(robot.servos)
    for ours, (theirs, _) in robot.joint_map.items():
        if group_of(ours) in TRUTH:
            servos[theirs] = scaled_gain(servos[theirs], TRUTH[group_of(ours)])
    truth = dataclasses.replace(robot, servos={t: s.replace(latency=LATENCY_TICKS * robot.sim.control_period)
                                               for t, s in servos.items()})
    drive = resolve_drive(None if controller else params, None, command=parse_command("0.15,0,0"), controller=controller)
    ground = load_surface(surface)
    sim = Simulator(truth, ground)
    options = {**drive.run_options(), "duration": seconds}
    with recording(drive.controller(truth, sim.control_period), sim, drive, Path(path), "walk") as walker:
        trace = sim.run(walker, perturb=draw(SENSORS_ONLY, seed, *sim.n_random()), **options)
    if not trace.completed:
        raise RuntimeError("the hidden robot fell in its walk")
    return path


def main() -> None:
    import tempfile

    from tuner.identify.ground import read_walk_logs
    from tuner.identify.walk_servos import identify_servos_from_walks
    from tuner.robots import load_robot
    from tuner.sim.surfaces import load_surface
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--surface", default="carpet4")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--robot", default="kidsize")
    ap.add_argument("--params", default="kidsize-engine-carpet4", help="the set that walks (as simulate takes it)")
    ap.add_argument("--controller", help="a controller or policy file that walks instead (as simulate takes it)")
    a = ap.parse_args()
    robot = load_robot(a.robot)
    with tempfile.TemporaryDirectory() as tmp:
        walk = hidden_walk(Path(tmp) / "walk.mcap", a.seconds, a.surface, robot_name=a.robot, params=a.params,
                           controller=a.controller)
        logs, _ = read_walk_logs([walk], robot)
    t0 = time.monotonic()
    fit = identify_servos_from_walks(robot, load_surface(a.surface), logs, threads=a.workers)
    print(f"{robot.name}, {a.controller or a.params}: {a.seconds:g} s walk on {a.surface}: {fit.rollouts} replays, "
          f"{time.monotonic() - t0:.0f} s")
    for k, v in fit.values.items():
        g = k.split(".")[0]
        print(f"  {k:10s} {v:.4f} (truth {TRUTH[g]:.2f}, off {100 * (v / TRUTH[g] - 1):+.2f} %) +- {fit.intervals[k]:.2g}"
              f"{'' if fit.identifiable[k] else ' not identifiable'}")
    print(f"  latency {fit.latency_ticks} ticks (truth {LATENCY_TICKS}), "
          f"{'identified' if fit.latency_identified else 'not identifiable'}")
    print(f"  replayed over the first {fit.horizon:g} s (the longest horizon whose replays stay within 2 noises)")
    print("  residual RMS [noises] before -> after: " + ", ".join(f"{k} {fit.rms_before[k]:.2f} -> {v:.2f}"
                                                                  for k, v in fit.rms_after.items()))


if __name__ == "__main__":
    main()
