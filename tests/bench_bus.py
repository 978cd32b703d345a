"""Benchmark (not a test): a match stream walked through the simulated Dynamixel bus against the same
walks in process (issue 50's comparison; figures in docs/robot-side.md).

    python tests/bench_bus.py [--walks 20] [--seed 1] [--set kidsize-engine-carpet4] [--parallel 2]

For each walk i of the evaluation seed: `gait-tuner bus serve --randomisation default --seed S --walk i`
(the same perturbation as `robustness`'s rollout i) and `gait-tuner-loop SET --commands STREAM --port`
(the robot side, its own process, real Protocol 2.0 packets, the sole boards read on the bus). Beside it,
`robustness` of the same set, stream and seed in process, with and without the foot sensors. A walk
through the bus survives when the loop walked its time (exit 0) and the simulator saw no fall.
Prints one JSON object (survival of each, per walk, the ticks without readings, the wire time).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STREAM = ROOT / "examples" / "streams" / "match-carpet4.csv"


def bus_walk(i: int, args, robot_file: Path, tmp: Path) -> dict:
    link = tmp / f"bus{i}"
    server = subprocess.Popen([sys.executable, "-m", "tuner.cli", "bus", "serve", "--robot", args.robot, "--surface",
                               args.surface, "--link", str(link), "--randomisation", "default", "--seed",
                               str(args.seed), "--walk", str(i), "--idle", "30"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    while not link.exists() and server.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    loop = subprocess.run([sys.executable, "-m", "gaits.robot.loop", str(ROOT / "studies" / "results" / f"{args.set}.yaml"),
                           "--robot", str(robot_file), "--port", str(link), "--commands", str(STREAM),
                           "--watchdog", "300"], capture_output=True, text=True, timeout=600)
    out, err = server.communicate(timeout=120)
    served = re.search(r"served (\d+) ticks", out)
    wire = re.search(r"([\d.]+) ms at", out)
    unread = re.search(r"(\d+) tick\(s\) without readings", loop.stdout)
    fell = "fell" in out or loop.returncode != 0
    return {"walk": i, "survived": not fell, "loop_exit": loop.returncode, "loop_said": loop.stdout.strip()[-200:],
            "served_ticks": int(served.group(1)) if served else None,
            "unread_ticks": int(unread.group(1)) if unread else None,
            "wire_ms_per_tick": float(wire.group(1)) if wire else None, "server_said": out.strip()[-300:]}


def in_process(args, no_feet: bool) -> dict:
    cmd = [sys.executable, "-m", "tuner.cli", "robustness", "--params", args.set, "--robot", args.robot, "--surface",
           args.surface, "--commands", str(STREAM), "--rollouts", str(args.walks), "--seed", str(args.seed),
           "--pushes", "", "--workers", str(args.parallel), "--json"]
    if no_feet:
        cmd.append("--no-foot-sensors")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    d = json.loads(r.stdout)
    return {"survival": d["survival"], "falls": d["falls"], "rollouts": d["rollouts"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--walks", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--set", default="kidsize-engine-carpet4")
    ap.add_argument("--robot", default="kidsize")
    ap.add_argument("--surface", default="carpet4")
    ap.add_argument("--parallel", type=int, default=2, help="bus walks at once (each is two processes)")
    args = ap.parse_args()
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        robot_file = tmp / "robot.yaml"
        subprocess.run([sys.executable, "-m", "tuner.cli", "robot", "export", args.robot, "--out", str(robot_file)],
                       check=True, capture_output=True)
        with ThreadPoolExecutor(args.parallel) as pool:
            walks = list(pool.map(lambda i: bus_walk(i, args, robot_file, tmp), range(args.walks)))
    bus_seconds = time.monotonic() - t0
    result = {"set": args.set, "robot": args.robot, "surface": args.surface, "stream": STREAM.name, "seed": args.seed,
              "bus": {"survival": sum(w["survived"] for w in walks) / len(walks), "walks": walks,
                      "seconds": round(bus_seconds)},
              "in_process": in_process(args, no_feet=False),
              "in_process_without_foot_sensors": in_process(args, no_feet=True)}
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
