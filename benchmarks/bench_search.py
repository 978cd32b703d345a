"""Search benchmarks, measured side by side in one run on this machine.

Usage: ``python benchmarks/bench_search.py [--seeds 5] [--max-trials 60] [--rate-trials 24]``

1. Trials to the first non-falling gait on grass50 at the paper's largest step
   (the ``quickstart`` study: EROS, 24 mm), with and without the CasADi seed
   enqueued first (no baselines in either arm, so the seed alone is measured);
   median over ``--seeds`` sampler seeds. A run that finds none within
   ``--max-trials`` counts as max-trials + 1 (stated in the output).
2. Trials per hour of that study with 1 and 2 worker processes on one journal.
3. Seed solve time after the build (median of 20 solves), and the build time.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

import optuna

from tuner.search import Evaluator, enqueue_starts, objective_for, open_storage, run_study, trial_fell
from tuner.seed import SeedProblem
from tuner.study import load_study


def trials_to_first_stable(spec, with_seed: bool, seed: int, max_trials: int, evaluator: Evaluator) -> int:
    spec = dataclasses.replace(spec, enqueue=("casadi",) if with_seed else (), baselines=(),
                               name=f"bench-{with_seed}-{seed}")
    study = optuna.create_study(directions=spec.directions,
                                sampler=optuna.samplers.TPESampler(seed=seed, multivariate=True,
                                                                   n_startup_trials=8))
    enqueue_starts(study, spec)
    objective = objective_for(spec, evaluator)
    for i in range(1, max_trials + 1):
        study.optimize(objective, n_trials=1)
        if not trial_fell(study.trials[-1]):
            return i
    return max_trials + 1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", default="quickstart")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--max-trials", type=int, default=60)
    ap.add_argument("--rate-trials", type=int, default=24)
    args = ap.parse_args()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    spec = load_study(args.study)
    evaluator = Evaluator(spec)

    print(f"1. trials to the first non-falling gait, study {spec.name} ({spec.gait} on "
          f"{', '.join(spec.surfaces)}), max {args.max_trials} (none found counts {args.max_trials + 1})")
    res = {}
    for with_seed in (False, True):
        counts = [trials_to_first_stable(spec, with_seed, s, args.max_trials, evaluator)
                  for s in range(args.seeds)]
        res[with_seed] = counts
        print(f"   {'with' if with_seed else 'without'} CasADi seed: {counts} -> median "
              f"{statistics.median(counts)}")
    print(f"   ratio (without / with): {statistics.median(res[False]) / statistics.median(res[True]):.2f}x")

    print(f"2. trials per hour: the {args.rate_trials} parameter sets a 1-worker TPE run of {spec.name} "
          f"chose, enqueued again and walked with 1 and with 2 workers (identical work)")
    with tempfile.TemporaryDirectory() as tmp:
        s0 = dataclasses.replace(spec, name="rate-source")
        store = open_storage(s0, None, Path(tmp))
        src = run_study(s0, store, str(Path(tmp) / "rate-source.journal"), args.rate_trials, 1, 0)
        fixed_sets = [dict(t.params) for t in src.trials][:args.rate_trials]
    rates = {}
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            s2 = dataclasses.replace(spec, enqueue=(), name=f"rate{workers}")
            store = open_storage(s2, None, Path(tmp))
            study = optuna.create_study(study_name=s2.name, storage=store, directions=s2.directions)
            for params in fixed_sets:
                study.enqueue_trial(params)
            t0 = time.perf_counter()
            run_study(s2, store, str(Path(tmp) / f"{s2.name}.journal"), args.rate_trials, workers, 0)
            el = time.perf_counter() - t0
        rates[workers] = args.rate_trials / el * 3600
        print(f"   {workers} worker(s): {el:.1f} s -> {rates[workers]:,.0f} trials/hour")
    print(f"   2 workers / 1 worker: {rates[2] / rates[1]:.2f}x")

    t0 = time.perf_counter()
    problem = SeedProblem()
    build = time.perf_counter() - t0
    times = [problem.solve(step_length=0.01 + 0.0025 * (i % 20)).solve_time for i in range(20)]
    print(f"3. CasADi seed: build {build:.3f} s, solve median {statistics.median(times) * 1000:.1f} ms "
          f"(max {max(times) * 1000:.1f} ms) over 20 step lengths")


if __name__ == "__main__":
    main()
