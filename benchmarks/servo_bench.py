"""Our servo law on BAM's pendulum bench against BAM's own trajectories (docs/servos.md).

    python benchmarks/servo_bench.py [--step 0.002|0.0002] [--noslip 0|1]

For every BAM model in ``tests/data/bam/reference.npz`` (MX-64 and MX-106 M1 and M6, XL-320,
XL-330 and STS3215 M1), its preset on our bench (``tuner/sim/servo_bench.py``) through the ten
runs (two benches: 0.567 kg at 0.105 m, 1.5 kg at 0.2 m; steps to 0.1 and 1 rad, 0.5 rad sines at
1, 2, 3 Hz), at physics step ``--step`` [s], compared with BAM's MuJoCo simulator at the same step
(2 ms) or at 0.2 ms (the converged law): RMS [mrad] per run and the worst. Round one's MX-64 (the
pd law) too, against BAM's MX-64 M1.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tuner.servos import preset                     # noqa: E402
from tuner.sim.servo_bench import Bench, track      # noqa: E402

OURS = {"mx64": "MX-64", "mx106": "MX-106", "xl320": "XL-320", "xl330": "XL-330", "feetech_sts3215_7_4V": "STS3215"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=float, default=0.002)
    ap.add_argument("--noslip", type=int, default=1)
    a = ap.parse_args()
    ref = np.load(ROOT / "tests" / "data" / "bam" / "reference.npz")
    meta = json.loads(str(ref["meta"]))
    which = "fine" if a.step < meta["dt"] else "mujoco"
    t = np.arange(int(round(meta["duration"] / a.step))) * a.step
    every = max(1, int(round(meta["dt"] / a.step)))
    cases = [(k, preset(OURS[k.split("/")[0]], k.split("/")[1])) for k in meta["models"]]
    cases.append(("mx64/m1", preset("MX-64-pd")))
    print(f"physics step {a.step * 1000:g} ms, noslip {a.noslip}, against BAM's MuJoCo simulator at "
          f"{'0.2' if which == 'fine' else '2'} ms; RMS [mrad] per run: "
          + ", ".join(f"{b[0]}/{x}" for b in meta["benches"] for x in meta["targets"]))
    for key, servo in cases:
        if servo.law == "dc-motor" and servo.profile_speed:     # BAM's simulator advances the Feetech's cap twice a step
            servo = servo.replace(profile_speed=2 * servo.profile_speed)
        rows = []
        for bench, g in meta["benches"].items():
            for target in meta["targets"]:
                goal = (np.full_like(t, float(target[4:])) if target.startswith("step")
                        else 0.5 * np.sin(2 * math.pi * float(target[3:]) * t))
                q = track(servo, Bench(g["mass"], g["length"], g["arm_mass"]), goal, a.step, noslip=a.noslip)[::every]
                rows.append(1000 * float(np.sqrt(np.mean((q - ref[f"{key}/{bench}/{target}/{which}"]) ** 2))))
        label = f"{key} ({'ours' if servo.law == 'dc-motor' else 'round one pd'})"
        print(f"  {label:34s} worst {max(rows):6.1f}: " + " ".join(f"{r:.1f}" for r in rows))


if __name__ == "__main__":
    main()
