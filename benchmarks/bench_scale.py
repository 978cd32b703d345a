"""How a study's search overhead grows with its size, and how many processes its storage feeds.

    python benchmarks/bench_scale.py [--sizes 100,1000,5000,10000] [--storages journal,postgresql]
                                     [--trials 30] [--procs 1,2,8,32] [--walk-s 1.0] [--skip-procs]

Part 1, overhead per trial. For each storage and size N, a study of the quick-start's space is
filled with N finished trials through the real storage (Optuna's ``create_new_trial`` with a
trial carrying the attributes a real trial stores: its walked set, its result, the fall
constraint), then a fresh process resumes it and runs ``--trials`` more trials through the
tuner's own worker loop (``tuner.search.workers.work``: reap, count, reserve, sample, duplicate
check, tell) with the walk replaced by a canned result (a smooth function of the parameters, so
the sampler has something to model). Printed per trial: the whole overhead, the time spent
sampling, the time holding the budget lock and the storage's own lock (the journal's file
lock; PostgreSQL has no client-side lock, its rows are locked by the server), and per process
the peak memory and the time to resume (open the storage, load the study).

Part 2, throughput. ``--procs`` processes share one study on each storage, each trial's walk a
``--walk-s`` sleep (it uses no core): trials per second, and the ratio to one process. This
machine has 2 cores, so 32 processes share them for their search overhead.

The figures depend on the machine's load; run it idle, and compare rows of one run.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import random
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

STUDY = "quickstart"


def _spec(name: str):
    from dataclasses import replace

    from tuner.search.study import load_study
    spec = load_study(STUDY)
    return replace(spec, name=name, enqueue=())


def _canned_result(spec):
    """One real walk's stored attributes (so that filled trials weigh what real ones do)."""
    from tuner.search.objective import Evaluator
    drive = spec.drive_for({}, source="bench")
    res = Evaluator(spec).evaluate(drive)
    walked = drive.params.to_mapping()
    return walked, res


def _score(spec, sampled: dict) -> float:
    """A smooth bowl over the space (its minimum inside it), in degrees like a pitch score."""
    s = 0.0
    for r in spec.space:
        v = sampled[r.name]
        mid = r.low + 0.37 * (r.high - r.low)
        s += ((v - mid) / (r.high - r.low)) ** 2
    return 0.5 + 4.0 * s


def fill(args) -> None:
    """Fill the study to ``args.size`` finished trials (child process)."""
    import optuna
    from optuna.distributions import FloatDistribution
    from tuner.search.workers import open_study, trial_distributions

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    spec = _spec(args.name)
    store = _store(args)
    study = open_study(spec, store.optuna_storage(), 0)
    dists = trial_distributions(spec)
    walked, res = _canned_result(spec)
    rng = random.Random(args.size)
    have = len(study.get_trials(deepcopy=False))
    for _ in range(args.size - have):
        params = {k: rng.uniform(d.low, d.high) for k, d in dists.items() if isinstance(d, FloatDistribution)}
        sampled = {r.name: params[r.label] for r in spec.space}
        t = optuna.trial.create_trial(params=params, distributions=dists, value=_score(spec, sampled),
                                      user_attrs={"worker": {"host": "bench", "pid": 1, "start": 0},
                                                  "params": {**walked, **sampled}, "result": res.stored()},
                                      system_attrs={"constraints": [-1.0]})
        study.add_trial(t)
    study.set_user_attr("budget", args.budget or args.size)       # part 2: the budget the processes share


def _store(args):
    from tuner.store.storage import StudyStore
    return StudyStore.open(args.name, args.url or None, Path(args.runs))


class _Timer:
    def __init__(self) -> None:
        self.total = 0.0
        self.count = 0

    @contextlib.contextmanager
    def held(self):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.total += time.perf_counter() - t0
            self.count += 1


def measure(args) -> None:
    """Resume the filled study and run ``args.trials`` trials with a canned walk (child process)."""
    import optuna

    import tuner.search.objective as objective
    import tuner.store.journal as journal
    import tuner.store.storage as storage
    import tuner.search.workers as workers

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    spec = _spec(args.name)
    walked, res = _canned_result(spec)
    from dataclasses import replace

    def evaluate(self, drive, report=None):
        if args.walk_s:
            time.sleep(args.walk_s)
        sampled = {r.name: getattr(drive.params, r.name) for r in spec.space}
        return replace(res, score=_score(spec, sampled))

    objective.Evaluator.evaluate = evaluate

    budget_t, journal_t, sample_t = _Timer(), _Timer(), _Timer()
    lock = storage.StudyStore.budget_lock

    @contextlib.contextmanager
    def timed_budget(self, name):
        with lock(self, name), budget_t.held():
            yield
    storage.StudyStore.budget_lock = timed_budget

    acquire, release = journal.FlockLock.acquire, journal.FlockLock.release
    held_since: dict[int, float] = {}

    def acq(self):
        out = acquire(self)
        if self.path.endswith(".flock"):
            held_since[id(self)] = time.perf_counter()
        return out

    def rel(self):
        t0 = held_since.pop(id(self), None)
        if t0 is not None:
            journal_t.total += time.perf_counter() - t0
            journal_t.count += 1
        return release(self)
    journal.FlockLock.acquire, journal.FlockLock.release = acq, rel

    tpe = optuna.samplers.TPESampler
    for meth in ("sample_relative", "sample_independent"):
        orig = getattr(tpe, meth)

        def wrapped(self, *a, _orig=orig, **k):
            with sample_t.held():
                return _orig(self, *a, **k)
        setattr(tpe, meth, wrapped)

    build_t = _Timer()

    class TimedIndex(workers.TrialIndex):
        def refresh(self, study):
            if self._storage is not None:
                return super().refresh(study)
            with build_t.held():                  # the first read of the whole study: resume time
                return super().refresh(study)
    workers.TrialIndex = TimedIndex
    freeze = workers._freeze_history

    def timed_freeze(n_done, frozen_at):           # the first: part of resuming, as the first read
        if frozen_at >= 0:
            return freeze(n_done, frozen_at)
        with build_t.held():
            return freeze(n_done, frozen_at)
    workers._freeze_history = timed_freeze

    t0 = time.perf_counter()
    store = _store(args)
    study = workers.open_study(spec, store.optuna_storage(), args.seed)
    from tuner.store.rdb import lean
    rdb = lean(study._storage)
    # the study's size; on a database without reading it into Optuna's cache, which would count
    # the benchmark's own read in the worker's memory
    n0 = (len(rdb.trial_states(study._study_id, 0, (), "budget")[0]) if rdb is not None
          else len(study.get_trials(deepcopy=False)))
    resume_s = time.perf_counter() - t0
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    budget = n0 + args.trials
    if args.procs_mode:
        from tuner.search.objective import record_constraint, suggest

        def stub_objective_for(spec_, evaluator):
            def objective(trial):                   # every trial walks: a sleep, then a canned result
                sampled = suggest(trial, spec_)
                time.sleep(args.walk_s)
                record_constraint(trial, -1.0)
                trial.set_user_attr("params", {**walked, **sampled})
                trial.set_user_attr("result", res.stored())
                return _score(spec_, sampled)
            return objective
        workers.objective_for = stub_objective_for
        barrier = Path(args.barrier)
        Path(f"{barrier}.ready-{args.seed}").touch()
        while not barrier.exists():
            time.sleep(0.01)
    study.set_user_attr("budget", budget) if not args.procs_mode else None
    budget_t.total = journal_t.total = sample_t.total = 0.0
    budget_t.count = journal_t.count = 0
    t1 = time.perf_counter()
    ran = workers.work(spec, store, budget if not args.procs_mode else args.budget, args.seed,
                       log=lambda m: None, poll=0.05)
    wall = time.perf_counter() - t1 - build_t.total
    ran = max(ran, 1)
    out = {"size": n0, "ran": ran, "wall_s": wall, "resume_s": resume_s + build_t.total,
           "overhead_ms": 1e3 * (wall / ran - args.walk_s),
           "sample_ms": 1e3 * sample_t.total / ran, "budget_lock_ms": 1e3 * budget_t.total / ran,
           "journal_lock_ms": 1e3 * journal_t.total / ran, "journal_holds": journal_t.count / ran,
           "rss_open_mb": rss0, "rss_peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    print(json.dumps(out), flush=True)


def _child(mode: str, **kw) -> subprocess.Popen:
    cmd = [sys.executable, __file__, "--mode", mode]
    for k, v in kw.items():
        cmd += [f"--{k.replace('_', '-')}", str(v)]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, cwd=ROOT)


def _run(mode: str, **kw) -> dict | None:
    p = _child(mode, **kw)
    out, _ = p.communicate()
    if p.returncode:
        raise SystemExit(f"bench_scale: a {mode} child failed (exit {p.returncode})")
    lines = [ln for ln in out.splitlines() if ln.startswith("{")]
    return json.loads(lines[-1]) if lines else None


def _place(pg, tmp: str, kind: str, what: str, i: int) -> tuple[str, str, str]:
    """A fresh study's name, storage URL ("" for the journal) and runs folder."""
    url = pg.create_database(f"{what}_{kind}_{i}") if kind == "postgresql" else ""
    return f"{what}{i}", url, str(Path(tmp) / f"{what}-{kind}-{i}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100,1000,5000,10000")
    ap.add_argument("--storages", default="journal,postgresql")
    ap.add_argument("--trials", type=int, default=30)
    ap.add_argument("--procs", default="1,2,8,32")
    ap.add_argument("--walk-s", type=float, default=1.0)
    ap.add_argument("--proc-trials", type=int, default=6, help="trials per process in part 2")
    ap.add_argument("--skip-procs", action="store_true")
    ap.add_argument("--skip-sizes", action="store_true")
    # child modes
    ap.add_argument("--mode", default="main", choices=["main", "fill", "measure"])
    ap.add_argument("--name", default="scale")
    ap.add_argument("--url", default="")
    ap.add_argument("--runs", default="")
    ap.add_argument("--size", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--budget", type=int, default=0)
    ap.add_argument("--barrier", default="")
    ap.add_argument("--procs-mode", type=int, default=0)
    args = ap.parse_args()
    if args.mode == "fill":
        return fill(args)
    if args.mode == "measure":
        return measure(args)

    storages = args.storages.split(",")
    sizes = [int(s) for s in args.sizes.split(",")]
    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        pg = None
        if "postgresql" in storages:
            from postgres_server import PostgresServer
            pg = stack.enter_context(PostgresServer())
        if not args.skip_sizes:
            print(f"part 1: overhead per trial ({args.trials} trials after filling, walk replaced by a canned result)")
            print(f"{'storage':<11}{'trials':>7}{'overhead':>10}{'sampling':>10}{'budget lk':>10}"
                  f"{'journal lk':>11}{'peak RSS':>10}{'resume':>8}")
            for kind in storages:
                for i, n in enumerate(sizes):
                    name, url, runs = _place(pg, tmp, kind, "scale", i)
                    t0 = time.perf_counter()
                    _run("fill", name=name, url=url, runs=runs, size=n)
                    fill_s = time.perf_counter() - t0
                    r = _run("measure", name=name, url=url, runs=runs, trials=args.trials, walk_s=0.0)
                    print(f"{kind:<11}{r['size']:>7}{r['overhead_ms']:>8.1f}ms{r['sample_ms']:>8.1f}ms"
                          f"{r['budget_lock_ms']:>8.1f}ms{r['journal_lock_ms']:>9.2f}ms"
                          f"{r['rss_peak_mb']:>8.0f}MB{r['resume_s']:>7.2f}s   (filled in {fill_s:.0f} s)",
                          flush=True)
        if not args.skip_procs:
            counts = [int(p) for p in args.procs.split(",")]
            print(f"\npart 2: throughput, each walk a {args.walk_s} s sleep, {args.proc_trials} trials per process")
            print(f"{'storage':<11}{'procs':>6}{'trials':>7}{'wall':>8}{'trials/s':>10}{'vs 1':>7}")
            for kind in storages:
                base = None
                for j, n in enumerate(counts):
                    name, url, runs = _place(pg, tmp, kind, "procs", j)
                    budget = n * args.proc_trials
                    _run("fill", name=name, url=url, runs=runs, size=0, budget=budget)
                    barrier = Path(tmp) / f"go-{kind}-{j}"
                    kids = [_child("measure", name=name, url=url, runs=runs, trials=args.proc_trials,
                                   walk_s=args.walk_s, seed=k, budget=budget, barrier=barrier, procs_mode=1)
                            for k in range(n)]
                    while len(list(Path(tmp).glob(f"{barrier.name}.ready-*"))) < n:
                        time.sleep(0.1)             # every child has imported and opened the study
                    t0 = time.perf_counter()
                    barrier.touch()
                    for k in kids:
                        k.communicate()
                    wall = time.perf_counter() - t0
                    if any(k.returncode for k in kids):
                        raise SystemExit("bench_scale: a worker failed")
                    rate = budget / wall
                    base = base or rate
                    print(f"{kind:<11}{n:>6}{budget:>7}{wall:>7.1f}s{rate:>10.2f}{rate / base:>6.1f}x", flush=True)


if __name__ == "__main__":
    main()
