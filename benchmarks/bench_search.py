"""Search benchmarks, measured side by side in one run on this machine.

Usage: ``python benchmarks/bench_search.py [--seeds 5] [--max-trials 60] [--rate-trials 24]``

1. Trials to the first non-falling gait on grass50
   (the ``quickstart`` study: TLIPFM on grass50), with and without the CasADi seed
   enqueued first (no baselines in either arm, so the seed alone is measured);
   also trials to the first *feasible* gait (stays up and walks at least half
   its plan: the search's own constraint, since a gait that stays up by
   shuffling in place is no answer);
   median over ``--seeds`` sampler seeds. A run that finds none within
   ``--max-trials`` counts as max-trials + 1 (stated in the output).
2. Trials per hour of that study with 1 and 2 worker processes on one journal,
   beside the same walks in a plain 2-process pool (the machine's own scaling).
3. Seed solve time after the build (median of 20 solves), and the build time.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

import optuna

import gaits
from gaits.params import ParamError

from tuner.search.objective import Evaluator, objective_for
from tuner.store.storage import StudyStore
from tuner.search.trials import trial_feasible, trial_fell
from tuner.search.workers import enqueue_starts, run_study
from tuner.search.seed import SeedProblem
from tuner.search.study import load_study


def trials_to_first_stable(spec, with_seed: bool, seed: int, max_trials: int,
                           evaluator: Evaluator) -> tuple[int, int]:
    """(first trial that did not fall, first feasible trial: no fall and >= half the plan walked)."""
    spec = dataclasses.replace(spec, enqueue=("casadi",) if with_seed else (), baselines=(),
                               name=f"bench-{with_seed}-{seed}")
    study = optuna.create_study(directions=spec.directions,
                                sampler=optuna.samplers.TPESampler(seed=seed, multivariate=True,
                                                                   n_startup_trials=8))
    enqueue_starts(study, spec)
    objective = objective_for(spec, evaluator)
    first_up = first_feasible = max_trials + 1
    for i in range(1, max_trials + 1):
        study.optimize(objective, n_trials=1)
        trial = study.trials[-1]
        if first_up > max_trials and not trial_fell(trial):
            first_up = i
        if first_feasible > max_trials and trial_feasible(trial):
            first_feasible = i
            break
    return first_up, first_feasible


_SPEC = None
_EVALUATOR = None


def _walk(params: dict) -> None:
    """One trial's rollouts, no Optuna: the machine's own scaling for the same work."""
    global _EVALUATOR
    if _EVALUATOR is None:
        _EVALUATOR = Evaluator(_SPEC)
    names = {r.label: r.name for r in _SPEC.space}       # Optuna's names carry units
    try:
        params = _SPEC.params_for({names.get(k, k): v for k, v in params.items()})
    except ParamError:
        return                          # the study scores these without walking, too
    _EVALUATOR.evaluate(gaits.Drive(params))


def main() -> None:
    global _SPEC
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", default="quickstart")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--max-trials", type=int, default=60)
    ap.add_argument("--rate-trials", type=int, default=24)
    args = ap.parse_args()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    spec = _SPEC = load_study(args.study)
    evaluator = Evaluator(spec)

    print(f"1. trials to the first non-falling gait, study {spec.name} ({spec.gait} on "
          f"{', '.join(spec.surfaces)}), max {args.max_trials} (none found counts {args.max_trials + 1})")
    res = {}
    for with_seed in (False, True):
        res[with_seed] = [trials_to_first_stable(spec, with_seed, s, args.max_trials, evaluator)
                          for s in range(args.seeds)]
    for k, what in enumerate(("non-falling", "feasible (up, >= half the plan)")):
        print(f"   first {what}:")
        for with_seed in (False, True):
            counts = [r[k] for r in res[with_seed]]
            print(f"     {'with' if with_seed else 'without'} CasADi seed: {counts} -> median "
                  f"{statistics.median(counts)}, mean {statistics.mean(counts):.1f}")
        ratio = (statistics.median(r[k] for r in res[False]) / statistics.median(r[k] for r in res[True]))
        print(f"     ratio of medians (without / with): {ratio:.2f}x")

    print(f"2. trials per hour: the {args.rate_trials} parameter sets a 1-worker TPE run of {spec.name} "
          f"chose, enqueued again and walked with 1 and with 2 workers (identical work)")
    with tempfile.TemporaryDirectory() as tmp:
        s0 = dataclasses.replace(spec, name="rate-source")
        src = run_study(s0, StudyStore.open(s0.name, None, Path(tmp)), args.rate_trials, 1, 0)
        fixed_sets = [dict(t.params) for t in src.trials][:args.rate_trials]
    rates = {}
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            s2 = dataclasses.replace(spec, enqueue=(), name=f"rate{workers}")
            store = StudyStore.open(s2.name, None, Path(tmp))
            study = optuna.create_study(study_name=s2.name, storage=store.optuna_storage(),
                                        directions=s2.directions)
            for params in fixed_sets:
                study.enqueue_trial(params)
            t0 = time.perf_counter()
            run_study(s2, store, args.rate_trials, workers, 0)
            el = time.perf_counter() - t0
        rates[workers] = args.rate_trials / el * 3600
        print(f"   {workers} worker(s): {el:.1f} s -> {rates[workers]:,.0f} trials/hour")
    print(f"   2 workers / 1 worker: {rates[2] / rates[1]:.2f}x")
    raw = {}
    for procs in (1, 2):
        t0 = time.perf_counter()
        if procs == 1:
            for params in fixed_sets:
                _walk(params)
        else:
            with mp.get_context("fork").Pool(2) as pool:
                pool.map(_walk, fixed_sets, chunksize=1)
        raw[procs] = time.perf_counter() - t0
    print(f"   the same walks without Optuna (a plain process pool): 1 process {raw[1]:.1f} s, "
          f"2 processes {raw[2]:.1f} s -> {raw[1] / raw[2]:.2f}x, what these two cores give this work")

    t0 = time.perf_counter()
    problem = SeedProblem()
    build = time.perf_counter() - t0
    times = [problem.solve(step_length=0.01 + 0.0025 * (i % 20)).solve_time for i in range(20)]
    print(f"3. CasADi seed: build {build:.3f} s, solve median {statistics.median(times) * 1000:.1f} ms "
          f"(max {max(times) * 1000:.1f} ms) over 20 step lengths")


if __name__ == "__main__":
    main()
