"""How far can the IMU stabiliser carry a push? Its gains tuned for pushes alone, beside it off.

Usage: ``python benchmarks/bench_push_stabiliser.py [--trials 120] [--push 1.5] [--push-rollouts 20]``

Issue 10 asks that with the stabiliser a gait survive a push at least twice as large as
without. The shipped ``kidsize-robust-fb-grass50`` co-tunes gait and gains for survival
under randomisation with one 0.75 N s push per walk, which does not ask for large pushes.
This benchmark gives the stabiliser its best chance on that set's gait:

1. Optuna (TPE, seed 0) searches the nine stabiliser numbers (gains in [0, 2] rad/rad and
   [0, 0.3] rad s/rad, limit in [0.05, 0.4] rad) for the survival of ``--tune-walks`` walks
   per pedestal on grass50 and carpet4, each under the default randomisation with one
   ``--push`` N s push (tuning seeds);
2. the push sweep of ``gait-tuner robustness`` (evaluation seeds, never used in 1.) for the
   gait with the stabiliser off, with the shipped gains and with the push-tuned gains, on
   every pedestal.
Prints the survival per push size and the largest push survived in >= 90%.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import optuna

import gaits
from gaits import StabiliserParams
from tuner.params_io import resolve_params
from tuner.process_pool import map_in_order
from tuner.sim.randomisation import TUNE, Randomisation, draw
from tuner.sim.robustness import evaluate
from tuner.sim.cache import simulator

SET = "kidsize-robust-fb-grass50"
PEDESTALS = ("grass50", "grass30", "grass10", "carpet4")
TUNE_ON = ("grass50", "carpet4")
PUSHES = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0)
GAINS = (("k_ankle_pitch", 2.0), ("d_ankle_pitch", 0.3), ("k_hip_pitch", 2.0), ("d_hip_pitch", 0.3),
         ("k_ankle_roll", 2.0), ("d_ankle_roll", 0.3), ("k_hip_roll", 2.0), ("d_hip_roll", 0.3))

_TABLES: dict[str, gaits.GaitTrajectory] = {}


def _walk(task: tuple) -> bool:
    """One pushed, randomised walk on tuning seeds: True if it stayed up."""
    surface, index, push, stabiliser = task
    sim = simulator("kidsize", surface)
    if surface not in _TABLES:
        _TABLES[surface] = gaits.generate(resolve_params(SET, None).params, sim.robot.leg, sim.control_period)
    p = draw(Randomisation().with_push(push), (0, index), *sim.n_random(), namespace=TUNE)
    return not sim.rollout(_TABLES[surface], perturb=p, stabiliser=stabiliser).fell


def tune_gains(trials: int, push: float, walks: int, workers: int) -> tuple[StabiliserParams, float]:
    def objective(trial: optuna.Trial) -> float:
        kw = {name: trial.suggest_float(name, 0.0, hi) for name, hi in GAINS}
        kw["limit"] = trial.suggest_float("limit", 0.05, 0.4)
        st = StabiliserParams(enabled=True, **kw)
        tasks = [(s, i, push, st) for s in TUNE_ON for i in range(walks)]
        return float(np.mean(map_in_order(_walk, tasks, workers, chunksize=2)))

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="maximize", sampler=optuna.samplers.TPESampler(seed=0))
    shipped = resolve_params(SET, None).stabiliser
    study.enqueue_trial({k: v for k, v in shipped.to_mapping().items() if k != "enabled"})
    study.optimize(objective, n_trials=trials)
    return StabiliserParams(enabled=True, **study.best_params), float(study.best_value)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=120)
    ap.add_argument("--push", type=float, default=1.5, help="push of the tuning walks [N s]")
    ap.add_argument("--tune-walks", type=int, default=8, help="tuning walks per pedestal and trial")
    ap.add_argument("--push-rollouts", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1, help="evaluation seed of the push sweep")
    args = ap.parse_args()
    gf = resolve_params(SET, None)
    t0 = time.perf_counter()
    tuned, best = tune_gains(args.trials, args.push, args.tune_walks, args.workers)
    print(f"{SET}: stabiliser gains tuned for {args.push:g} N s pushes ({args.trials} trials x "
          f"{args.tune_walks * len(TUNE_ON)} walks, {time.perf_counter() - t0:.0f} s): survival "
          f"{best:.0%} on the tuning walks")
    print("  " + ", ".join(f"{k} {v:.3g}" for k, v in tuned.to_mapping().items() if k != "enabled"))
    sets = {"stabiliser off": None, "shipped gains": gf.stabiliser, "push-tuned gains": tuned}
    print(f"\npush sweep, {args.push_rollouts} randomised walks per size (evaluation seed {args.seed}); "
          f"survival % per size {', '.join(f'{p:g}' for p in PUSHES)} N s; largest survived in >= 90%")
    largest: dict[str, list[float]] = {}
    for surface in PEDESTALS:
        for label, st in sets.items():
            drive = gaits.Drive(gf.params, st, source=label)
            rep = evaluate("kidsize", surface, drive, rollouts=0, seed=args.seed,
                           pushes=PUSHES, push_rollouts=args.push_rollouts, workers=args.workers)
            lp = rep.largest_push
            largest.setdefault(label, []).append(0.0 if lp is None else lp)
            row = " ".join(f"{v:4.0%}" for v in rep.push_survival.values())
            print(f"  {surface:8s} {label:17s} {row}   largest {'-' if lp is None else format(lp, 'g')}")
    for label in ("shipped gains", "push-tuned gains"):
        ratios = [f"{a / b:.2f}" if b else "- (off holds no push)"
                  for a, b in zip(largest[label], largest["stabiliser off"])]
        print(f"largest push with {label} / stabiliser off, per pedestal: " + ", ".join(ratios) + "  (target >= 2)")
    print(f"wall {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
