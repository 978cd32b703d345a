"""The shipped sets' figures on round one's servos beside the real ones (docs/servos.md's table).

    python benchmarks/servo_figures.py [--walks 20] [--seed 11] [--robots kidsize-pd,kidsize,kidsize@13.5V]
                                       [--sets kidsize-engine-carpet4,...] [--workers 2] [--json OUT]

Per robot (``kidsize-pd``: round one's pd servos; ``kidsize``: BAM's MX-64 on the legs at 15 V;
``kidsize@13.5V``: the same at a drained battery's voltage) and shipped engine set:

* the speed a held 0.2 and 0.3 m/s forward command walks on carpet4 (``gait-tuner simulate --params
  SET --robot R --surface carpet4 --command V,0,0``: vx over the steady window; '-' a walk that fell);
* randomised match walks on carpet4 and grass50, evaluation seed ``--seed`` (no study tunes on the
  evaluation namespace): the shipped match study's streams (0.2 m/s forward, 0.15 back, 0.06
  sideways, 0.6 rad/s; ``studies/kidsize-engine-match.yaml``) and the wider default ones (0.3 / 0.2 /
  0.1 / 1.0: ``gait-tuner transfer``'s); survival and vx RMSE over the walks that survived;
* the 2025 push challenge's fully successful D on carpet4, push seed 5 (``gait-tuner challenge push
  --params SET --robot R --surface carpet4 --seed 5``) for the push set.

Deterministic: the same arguments give the same table on any machine and any --workers.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tuner.params_io import resolve_drive          # noqa: E402
from tuner.sim.metrics import summarize             # noqa: E402
from tuner.sim.robustness import scenario_walks     # noqa: E402
from tuner.sim.match_walks import MatchDistribution    # noqa: E402

SETS = ("kidsize-engine-carpet4", "kidsize-engine-match", "kidsize-engine-grass50", "kidsize-engine-push")
MATCH = MatchDistribution(duration=12.0, forward=0.2, backward=0.15, sideways=0.06, turn=0.6)
WIDE = MatchDistribution()


def held_speed(robot: str, set_name: str, v: float) -> float | None:
    from gaits import parse_command
    from tuner.sim.cache import simulator
    sim = simulator(robot, "carpet4")
    drive = resolve_drive(set_name, None, command=parse_command(f"{v},0,0"))
    trace = sim.run(drive.controller(sim.robot, sim.control_period), **drive.run_options())
    start = float(getattr(drive.engine, "t_stand", 0.0) or 0.0) + 2.0
    trace.meta["steady"] = (start, float(drive.the_stream().t[-1]))
    m = summarize(trace)
    return None if not trace.survived else float(m.vx_mps)


def walks(robot: str, surface: str, set_name: str, scenario: MatchDistribution, n: int, seed: int,
          workers: int) -> dict:
    rows = scenario_walks(robot, surface, resolve_drive(set_name, None), scenario, walks=n, seed=seed,
                          workers=workers)
    alive = [r for r in rows if r["survived"]]   # completed: not fallen, diverged or impossible
    rmse = [r["tracking"]["vx_rmse_mps"] for r in alive if r.get("tracking") and r["tracking"].get("vx_rmse_mps")
            is not None]
    return {"survival": len(alive) / len(rows), "vx_rmse": float(np.mean(rmse)) if rmse else None}


def push_d(robot: str, set_name: str) -> float | None:
    from tuner.challenge.rules import challenge_2025
    from tuner.sim.rollout import Simulator
    from tuner.robots import load_robot
    from tuner.sim.surfaces import load_surface
    from tuner.sim.scene import BOTTLES
    sim = Simulator(load_robot(robot), load_surface("carpet4"), pendulum=1.5, bottle=BOTTLES[3])
    report = challenge_2025(sim, resolve_drive(set_name, None), seed=5)
    return report["full"]["distance_m"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--walks", type=int, default=20)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--robots", default="kidsize-pd,kidsize,kidsize@13.5V")
    ap.add_argument("--sets", default=",".join(SETS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-push", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args()
    out = {}
    for robot in a.robots.split(","):
        for set_name in a.sets.split(","):
            row = {"0.2": held_speed(robot, set_name, 0.2), "0.3": held_speed(robot, set_name, 0.3)}
            for surface in ("carpet4", "grass50"):
                row[f"match/{surface}"] = walks(robot, surface, set_name, MATCH, a.walks, a.seed, a.workers)
                row[f"wide/{surface}"] = walks(robot, surface, set_name, WIDE, a.walks, a.seed, a.workers)
            if set_name.endswith("push") and not a.no_push:
                row["push_d"] = push_d(robot, set_name)
            out[f"{robot}|{set_name}"] = row
            f = lambda v: "-" if v is None else f"{v:.3f}"
            cells = [f(row["0.2"]), f(row["0.3"])] + [
                f"{row[k]['survival']:.0%} ({f(row[k]['vx_rmse'])})" for k in
                ("match/carpet4", "match/grass50", "wide/carpet4", "wide/grass50")]
            if "push_d" in row:
                cells.append(f"D {f(row['push_d'])} m")
            print(f"| {robot} | {set_name} | " + " | ".join(cells) + " |", flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
