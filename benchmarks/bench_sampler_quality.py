"""Search quality of the windowed sampler beside the sampler it replaced, in one run.

    python benchmarks/bench_sampler_quality.py [--seeds 5] [--parts bowl,quickstart,speed]
                                               [--bowl-trials 600] [--study-trials 30]

Two arms: "full" is the sampler every study used before (Optuna's multivariate TPE reading every
trial, 8 random start-up trials); "window" is ``tuner.store.history.WindowedTPESampler`` (the
same TPE given the best 30 and the latest 90 trials, with the constant liar). Per part and sampler
seed, the best value each arm found within the same budget, and the median over the seeds:

* ``bowl``: a smooth bowl over the quick-start's 8-dimensional space (no walk), ``--bowl-trials``
  trials: beyond the window's 120 trials, so it measures the window itself;
* ``quickstart``: the real quick-start study (walks on grass50), ``--study-trials`` trials per
  seed, one worker; the casadi seed and baselines are enqueued in both arms alike;
* ``speed``: the ``kidsize-omni-rigid`` speed study (its speed score: the weighted stairs held
  forward, backward, sideways and turning, maximised), ``--study-trials`` trials per seed.

The studies' budgets are within the window, so there the arms differ only by the constant liar
and the fixed search space; they are here because the issue asks for them.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _full(spec, seed, index=None):
    import optuna
    return optuna.samplers.TPESampler(seed=seed, multivariate=True, n_startup_trials=8)


def bowl(seed: int, arm: str, trials: int) -> float:
    import optuna

    from tuner.store.history import WindowedTPESampler
    from tuner.search.study import load_study
    from tuner.search.workers import trial_distributions

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    spec = load_study("quickstart")
    space = trial_distributions(spec)
    sampler = (WindowedTPESampler(space, seed=seed, n_startup_trials=8, constant_liar=True) if arm == "window"
               else _full(spec, seed))
    study = optuna.create_study(sampler=sampler)

    def f(trial):
        s = 0.0
        for r in spec.space:
            d = space[r.label]
            v = trial.suggest_float(r.label, d.low, d.high)
            s += ((v - (d.low + 0.37 * (d.high - d.low))) / (d.high - d.low)) ** 2
        return s
    study.optimize(f, n_trials=trials)
    return study.best_value


def study_run(name: str, seed: int, arm: str, trials: int) -> float:
    import optuna

    from tuner.search import workers
    from tuner.store.storage import StudyStore
    from tuner.search.study import load_study
    from tuner.search.trials import best_trial

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    orig = getattr(workers, "_window_sampler", None) or workers._sampler
    workers._window_sampler = orig                   # a pool process runs both arms in turn
    workers._sampler = _full if arm == "full" else orig
    spec = replace(load_study(name), name=f"q-{arm}-{seed}", trials=trials)
    with tempfile.TemporaryDirectory() as tmp:
        store = StudyStore.open(spec.name, None, Path(tmp))
        study, budget, _ = workers.prepare_study(spec, store, trials, seed, log=lambda m: None)
        workers.work(spec, store, budget, seed, log=lambda m: None)
        try:
            return best_trial(study).value
        except Exception:           # no feasible trial
            return float("nan")


def _one(task):
    part, seed, arm, n = task
    if part == "bowl":
        return bowl(seed, arm, n)
    return study_run("quickstart" if part == "quickstart" else "kidsize-omni-rigid", seed, arm, n)


def main() -> None:
    from tuner.process_pool import map_in_order

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--parts", default="bowl,quickstart,speed")
    ap.add_argument("--bowl-trials", type=int, default=600)
    ap.add_argument("--study-trials", type=int, default=30)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    for part in args.parts.split(","):
        n = args.bowl_trials if part == "bowl" else args.study_trials
        tasks = [(part, s, arm, n) for s in range(args.seeds) for arm in ("full", "window")]
        vals = map_in_order(_one, tasks, args.workers)
        full, window = vals[0::2], vals[1::2]
        what = {"bowl": "lowest bowl value", "quickstart": "lowest pitch score [deg]",
                "speed": "highest speed score"}[part]
        print(f"{part}: {what}, {n} trials, seeds 0-{args.seeds - 1}")
        print("  seed " + " ".join(f"{s:>9}" for s in range(args.seeds)) + "     median")
        for arm, v in (("full", full), ("window", window)):
            print(f"  {arm:<6}" + " ".join(f"{x:>9.4f}" for x in v) + f"  {statistics.median(v):>9.4f}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
