"""The identification benchmark (issue: the field back in the simulator), run as a script:

    python tests/bench_identification.py --out runs/bench-id [--trials 120] [--walks 100]

A hidden world of its own (kid3kg with servos 30-40 % off the map's, a 20 ms latency and a 6 mrad
backlash, on grass30 with its layer 40 % slower and 40 % more drag), and what a team would do in it:

1. record a 30 s sweep (`gait-tuner excite`) on the hidden robot hanging in its harness, and three
   4 s walks of the robot on the hidden ground (the init set: forward, turning, sideways; sensor noise);
2. `identify servos`, then `identify ground` with the identified servos;
3. tune init's match study three times, same budget and seed: on the default world (the map,
   grass30), on the identified one (the written robot.yaml and surface.yaml), and on the hidden one
   itself (the bound: what a perfect identification would give this study and budget);
4. walk the sets in the hidden world over ``--walks`` randomised match walks (the study's match
   distribution, the default randomisation), and each in the world it was tuned in: survival and
   tracking.

Prints one JSON document (also written to OUT/benchmark.json) with every figure and its cost.
Not collected by pytest (its name): it tunes three studies, ~45 min on 2 cores.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
KID3KG = ROOT / "examples" / "robots" / "kid3kg" / "kid3kg.yaml"


def sh(out: Path, *args: str) -> tuple[float, str]:
    t0 = time.monotonic()
    r = subprocess.run([str(Path(sys.executable).parent / "gait-tuner"), *args], capture_output=True, text=True,
                       cwd=out)
    if r.returncode != 0:
        raise SystemExit(f"gait-tuner {' '.join(args)}: exit {r.returncode}\n{r.stderr[-3000:]}")
    return time.monotonic() - t0, r.stdout


def hidden_world(out: Path) -> tuple[Path, Path]:
    from tuner.robots import load_robot
    from tuner.sim.surfaces import SURFACES
    from tuner.report.calibration import surface_yaml
    doc = yaml.safe_load(KID3KG.read_text())
    doc["mjcf"] = str(KID3KG.parent / doc["mjcf"])
    base = load_robot(KID3KG).servos
    leg = base[doc["joints"]["l_knee"]]
    arm = base[doc["joints"]["l_elbow"]]
    doc["servo"] = {"hips": {"kp": leg.kp * 0.7, "damping": leg.damping * 1.4, "frictionloss": leg.frictionloss * 1.3,
                             "backlash": 0.006, "latency": 0.02},
                    "knees": {"kp": leg.kp * 0.65, "damping": leg.damping * 1.3, "frictionloss": leg.frictionloss * 1.4,
                              "backlash": 0.006, "latency": 0.02},
                    "ankles": {"kp": leg.kp * 0.7, "damping": leg.damping * 1.4, "frictionloss": leg.frictionloss * 1.3,
                               "backlash": 0.006, "latency": 0.02},
                    "arms": {"kp": arm.kp * 1.3, "damping": arm.damping * 0.7, "backlash": 0.006, "latency": 0.02},
                    "head": {"backlash": 0.006, "latency": 0.02}, **{k: v for k, v in (doc.get("servo") or {}).items()
                                                                    if k in ("legs",)}}
    robot = out / "hidden-robot.yaml"
    robot.write_text(yaml.safe_dump(doc, sort_keys=False))
    g = SURFACES["grass30"]
    surface = dataclasses.replace(g, name="hidden-grass", layer_timeconst=g.layer_timeconst * 1.4, drag=g.drag * 1.4)
    path = out / "hidden-grass.yaml"
    path.write_text(surface_yaml(surface, "the benchmark's hidden ground"))
    return robot, path


def record_walk(robot_map: Path, surface: Path, set_path: Path, command: str, seconds: float, path: Path, seed: int):
    from gaits import parse_command
    from gaits.robot.recorder import Recorder, RecordingController, RecordingMeta
    from tuner.params_io import resolve_drive
    from tuner.robots import load_robot
    from tuner.sim.randomisation import SENSORS_ONLY as noise, draw
    from tuner.sim.rollout import Simulator
    from tuner.sim.surfaces import load_surface
    robot = load_robot(robot_map)
    drive = resolve_drive(str(set_path), None, command=parse_command(command))
    sim = Simulator(robot, load_surface(str(surface)))
    options = drive.run_options()
    options["duration"] = seconds
    rec = Recorder(path, RecordingMeta(robot=robot.name, task="walk", simulated=False), start_ns=0)
    try:
        trace = sim.run(RecordingController(drive.controller(robot, sim.control_period), rec),
                        perturb=draw(noise, seed, *sim.n_random()), **options)
    finally:
        rec.close()
    return trace.reason


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="runs/bench-id")
    ap.add_argument("--trials", type=int, default=120)
    ap.add_argument("--walks", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    fig: dict = {"trials": args.trials, "walks": args.walks}
    hidden_robot, hidden_surface = hidden_world(out)

    # 1. what a team records: a sweep in the harness, two walks on the field
    from tuner.robots import load_robot
    from tuner.identify.harness import Harness, record_sweep
    sh(out, "excite", "--robot", str(KID3KG), "--out", "sweep.csv", "--duration", "30")
    targets = np.loadtxt(out / "sweep.csv", delimiter=",", skiprows=1)[:, 1:]
    h = Harness(load_robot(hidden_robot))
    record_sweep(h, targets, h.servo_arrays(), out / "sweep.mcap", noise=1e-3, seed=1)
    sh(out, "init", "--robot", str(KID3KG), "--surface", "grass30", "--for", "match", "--out", "init")
    start_set = out / "init" / "kid3kg-grass30-match-start.yaml"
    walks = ("0.15,0,0", "0.05,0,0.3", "0,0.05,0")           # forward, turning, sideways: 4 s each
    fig["recorded_walks"] = [record_walk(hidden_robot, hidden_surface, start_set, c, 4.0, out / f"walk{i}.mcap", i)
                             for i, c in enumerate(walks)]

    # 2. identification
    t, text = sh(out, "identify", "servos", "--robot", str(KID3KG), "--recording", "sweep.mcap", "--out", "servos",
                 "--json")
    servos = json.loads(text)
    fig["identify_servos"] = {"seconds": round(t, 1), "rollouts": servos["rollouts"],
                              "rms_after_rad": float(np.sqrt(np.mean(np.square(list(servos["rms_after_rad"].values())))))}
    t, text = sh(out, "identify", "ground", "--robot", "servos/robot.yaml", "--surface", "grass30",
                 *[a for i in range(len(walks)) for a in ("--recording", f"walk{i}.mcap")], "--out", "ground", "--json")
    ground = json.loads(text)
    fig["identify_ground"] = {"seconds": round(t, 1), "replays": ground["replays"], "values": ground["values"],
                              "rms_after": ground["rms_after"]}

    # 3. the same study tuned in both worlds, and in the hidden world itself: the bound a perfect
    #    identification would give this study and budget
    study = yaml.safe_load((out / "init" / "kid3kg-grass30-match.yaml").read_text())
    scenario = study["scenario"]
    sets = {}
    worlds = {"default": (str(KID3KG), "grass30"),
              "identified": (str(out / "servos" / "robot.yaml"), str(out / "ground" / "surface.yaml")),
              "hidden": (str(hidden_robot), str(hidden_surface))}
    for world, (robot, surface) in worlds.items():
        doc = dict(study, name=f"bench-{world}", robot=robot, surfaces=[surface], trials=args.trials,
                   base=str(out / "init" / "kid3kg-grass30-match-start.yaml"))
        path = out / f"study-{world}.yaml"
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        t, _ = sh(out, "tune", str(path), "--workers", str(args.workers), "--runs", "runs")
        sh(out, "export", str(path), "--runs", "runs", "--out", f"best-{world}.yaml")
        sets[world] = out / f"best-{world}.yaml"
        fig[f"tune_{world}_seconds"] = round(t, 1)

    # 4. both sets in the hidden world
    from tuner.report.transfer import world_summary
    from tuner.sim.robustness import scenario_walks
    from tuner.sim.match_walks import scenario_from_mapping
    from tuner.params_io import resolve_drive
    dist = scenario_from_mapping({k: v for k, v in scenario.items() if k not in ("walks", "min_survival",
                                                                                 "tracking_weight")}, "scenario")
    for world, path in sets.items():
        rows = scenario_walks(str(hidden_robot), str(hidden_surface), resolve_drive(str(path), None), dist,
                              walks=args.walks, seed=1, workers=args.workers)
        fig[f"hidden_{world}_set"] = world_summary(rows)
        if world != "hidden":                 # and in the world it was tuned in (what the tool predicted)
            rows = scenario_walks(*worlds[world], resolve_drive(str(path), None), dist, walks=args.walks, seed=1,
                                  workers=args.workers)
            fig[f"{world}_{world}_set"] = world_summary(rows)
    (out / "benchmark.json").write_text(json.dumps(fig, indent=1))
    print(json.dumps(fig, indent=1))


if __name__ == "__main__":
    os.environ.setdefault("MPLBACKEND", "Agg")
    main()
