"""What the servo law costs a rollout: the built-in robot on round one's pd servos, on BAM's MX-64 as
MuJoCo's own pieces (M1), and with the extended friction run in every physics step (M6, the native
step), the same walks, in turn, in one process.

    python benchmarks/bench_servo_law.py [--repeats 7] [--surface carpet4]

Each repeat walks, for each law, the carpet4 engine set's 0.2 m/s walk (10 s, the tick loop) and
the TLIPFM table walk (``tkux-table2``, 10 s, MuJoCo's native rollout), timing the process's CPU
(``time.process_time``) per walk; it prints each law's median and its ratio to the pd law's
(ratios taken repeat by repeat, then their median, so a machine's drift cancels).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gaits                                        # noqa: E402
from tuner.params_io import resolve_drive           # noqa: E402
from tuner.robots import load_robot                 # noqa: E402
from tuner.servos import MotorServo, preset         # noqa: E402
from tuner.sim.rollout import Simulator             # noqa: E402
from tuner.sim.surfaces import load_surface         # noqa: E402


def robots() -> dict[str, object]:
    m1 = load_robot("kidsize")
    m6 = dataclasses.replace(m1, name="kidsize-m6", servos={
        j: (preset(s.preset, "m6").replace(voltage=s.voltage) if isinstance(s, MotorServo) and s.preset == "MX-64"
            else s) for j, s in m1.servos.items()})
    return {"pd": load_robot("kidsize-pd"), "M1": m1, "M6": m6}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--surface", default="carpet4")
    a = ap.parse_args()
    surface = load_surface(a.surface)
    sims = {k: Simulator(r, surface) for k, r in robots().items()}
    engine = resolve_drive("kidsize-engine-carpet4", None, command=gaits.parse_command("0.2,0,0"))
    table = gaits.generate(gaits.load_baseline("tkux-table2").params, sims["pd"].robot.leg, 0.01)
    walks = {"engine (tick loop)": lambda s: s.run(engine.controller(s.robot, s.control_period),
                                                   **engine.run_options()),
             "table (native rollout)": lambda s: s.rollout(table, duration=10.0)}
    for label, walk in walks.items():
        times: dict[str, list[float]] = {k: [] for k in sims}
        walked: dict[str, float] = {}
        for _ in range(a.repeats + 1):                      # the first round warms up, not counted
            for k, sim in sims.items():
                t0 = time.process_time()
                trace = walk(sim)
                times[k].append(time.process_time() - t0)
                walked[k] = float(trace.t[-1])
        base = times["pd"][1:]
        print(f"{label} on {a.surface}, {a.repeats} repeats (CPU seconds, median; ratio to pd, median of pairs):")
        for k, ts in times.items():
            ts = ts[1:]
            ratio = statistics.median(t / b for t, b in zip(ts, base))
            print(f"  {k:3s} {statistics.median(ts):7.3f} s   x{ratio:.3f}   ({walked[k]:.2f} s walked, {sims[k].robot.name})")


if __name__ == "__main__":
    main()
