"""How fast does the built-in robot walk, per direction and surface, after a speed study?

Usage: ``python benchmarks/bench_speed.py [--workers 2] [--shipped]``

1. Runs the shipped speed studies (``studies/kidsize-omni-{rigid,carpet4,grass10,grass30,grass50,robust}.yaml``,
   at most 1,000 trials each, their own sampler seeds) afresh into a temporary folder with
   ``--workers`` processes, timing each study's wall time; ``--shipped`` skips this and
   measures the shipped results in ``studies/results/`` instead.
2. Walks each best set's staircases (the study's own: stairs, tops, steps per stair) in every direction on
   every built-in surface and prints the highest stair held (commanded) and the velocity
   measured on it, and for forward on each surface the servos that hit their torque or speed
   limit on the stair after it (where the walk stopped gaining).
3. The issue's acceptance walk: ``kidsize-omni-grass50`` on grass50 at 0.2 m/s forward
   (``simulate --command 0.2,0,0``), measured velocity as a share of the command.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from gaits import CommandRamp, WalkCommand, load_gait_file
from tuner.sim.metrics import summarize
from tuner.robots import load_robot
from tuner.sim.rollout import Simulator
from tuner.search.study import load_study
from tuner.sim.surfaces import SURFACES, load_surface
from gaits import command_walk
from tuner.sim.walk_speed import speed_test

ROOT = Path(__file__).resolve().parents[1]
STUDIES = ("rigid", "carpet4", "grass10", "grass30", "grass50", "robust")


def tune(name: str, folder: Path, workers: int) -> tuple[Path, float]:
    exe = [sys.executable, "-m", "tuner.cli"]
    study = str(ROOT / "studies" / f"kidsize-omni-{name}.yaml")
    t0 = time.perf_counter()
    subprocess.run(exe + ["tune", study, "--workers", str(workers), "--runs", str(folder)], check=True,
                   capture_output=True, text=True)
    wall = time.perf_counter() - t0
    out = folder / f"kidsize-omni-{name}.yaml"
    subprocess.run(exe + ["export", study, "--runs", str(folder), "--out", str(out)], check=True,
                   capture_output=True, text=True)
    return out, wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--shipped", action="store_true", help="measure studies/results/ instead of tuning")
    args = ap.parse_args()
    robot = load_robot("kidsize")
    sims = {s: Simulator(robot, load_surface(s)) for s in SURFACES}
    with tempfile.TemporaryDirectory() as tmp:
        sets = {}
        for name in STUDIES:
            spec = load_study(str(ROOT / "studies" / f"kidsize-omni-{name}.yaml"))
            if args.shipped:
                sets[name] = (ROOT / "studies" / "results" / f"kidsize-omni-{name}.yaml", None, spec)
            else:
                path, wall = tune(name, Path(tmp), args.workers)
                sets[name] = (path, wall, spec)
                print(f"study kidsize-omni-{name}: {spec.trials} trials, {wall / 60:.1f} min wall on "
                      f"{args.workers} worker(s)", flush=True)
        print()
        for name, (path, wall, spec) in sets.items():
            params = load_gait_file(path).params
            print(f"== kidsize-omni-{name} (period {params.period:.3f} s, h_z {params.h_z * 1000:.0f} mm, "
                  f"z_c {params.z_c * 1000:.0f} mm, lean {params.torso_pitch:+.2f} rad)")
            print(f"{'surface':9s} " + " ".join(f"{d:>22s}" for d, _, _ in spec.settings.directions))
            for surface, sim in sims.items():
                cells, sat = [], None
                for d, top, _ in spec.settings.directions:
                    r = speed_test(sim, params, spec.settings.staircase(d, top), spec.settings.tolerance,
                                   limits=(d == "forward"))
                    cells.append(f"{r.reached:6.3f} ({r.measured:6.3f}) {r.unit:>5s}")
                    if d == "forward":
                        sat = r.extra
                print(f"{surface:9s} " + " ".join(f"{c:>22s}" for c in cells))
                if sat and sat.get("saturation"):
                    top3 = ", ".join(f"{x['joint']} torque {x['torque_share']:.0%} speed {x['speed_share']:.0%}"
                                     for x in sat["saturation"])
                    print(f"{'':9s}   forward stair {sat['saturation_stair']:.3f} m/s: {top3}")
            print()
        path = sets["grass50"][0]
        params = load_gait_file(path).params
        m = summarize(sims["grass50"].rollout(command_walk(params, robot, WalkCommand(0.2), 0.01, CommandRamp(
            WalkCommand(0.2)))))
        print(f"acceptance: kidsize-omni-grass50 on grass50 at 0.2 m/s: "
              f"{'fell' if m.fell else 'stayed up'}, vx {m.vx_mps:.3f} m/s ({m.vx_mps / 0.2:.0%} of the command)")


if __name__ == "__main__":
    main()
