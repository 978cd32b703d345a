"""The walk's cost per tick: its controller's ``step`` timed over one forward walk (docs/walk.md).

    python benchmarks/bench_tick.py --robot examples/robots/wolfgang/wolfgang.yaml --params SET [--parts]

Walks SET forward on rigid at --speed (the forward walk `gait-tuner versus` times), prints the
median and p99 of ``step`` over its ticks, and with --parts the engine's parts (the legs' IK, the
estimator, the servos' give, the step machine) timed around their calls. Run it on an idle machine;
the figures are this machine's.
"""

from __future__ import annotations

import argparse
import subprocess
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

#: the online engine's parts timed with --parts (its own methods; a benchmark's view, not an API)
PARTS = ("_joints", "_estimate", "_load_offsets", "_advance")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", default="kidsize")
    ap.add_argument("--params", required=True)
    ap.add_argument("--surface", default="rigid")
    ap.add_argument("--speed", type=float, default=0.2)
    ap.add_argument("--parts", action="store_true", help="also time the engine's parts")
    args = ap.parse_args()
    from gaits.engine import WalkEngine
    from tuner.params_io import resolve_drive
    from tuner.report.versus import speed_walk
    from tuner.robots import load_robot
    from tuner.sim.rollout import Simulator
    from tuner.sim.surfaces import load_surface
    parts: dict[str, list[float]] = defaultdict(list)
    if args.parts:
        for name in PARTS:
            inner = getattr(WalkEngine, name)

            def timed(*a, _inner=inner, _name=name, **k):
                t0 = time.perf_counter()
                out = _inner(*a, **k)
                parts[_name].append(time.perf_counter() - t0)
                return out
            setattr(WalkEngine, name, timed)
    sim = Simulator(load_robot(args.robot), load_surface(args.surface))
    r = speed_walk(sim, resolve_drive(args.params, None), "forward", args.speed)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=Path(__file__).parent).stdout.strip()
    t = np.array(r["step_times"]) * 1000
    print(f"{args.params} on {args.robot} / {args.surface}, forward {args.speed:g} m/s, {r['outcome']}, "
          f"{len(t)} ticks, commit {commit or '?'}")
    print(f"  step          median {np.median(t):.3f} ms  p99 {np.percentile(t, 99):.3f} ms")
    for name, v in parts.items():
        v = np.array(v) * 1000
        print(f"  {name:13s} median {np.median(v):.3f} ms  ({len(v)} calls; timing adds ~1 us a call)")


if __name__ == "__main__":
    main()
