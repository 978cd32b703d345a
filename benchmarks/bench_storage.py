"""Study throughput by storage and number of worker processes, measured side by side in one run.

    python benchmarks/bench_storage.py [--trials 40] [--workers 1,2,8]

For each storage (the default journal file, SQLite, PostgreSQL on 127.0.0.1 from the pgserver
wheel) and each worker count, a fresh study of the same small space is run with
``gait-tuner tune`` in a subprocess; the table gives wall time, trials per minute and the ratio
to the journal with one worker, and checks the budget was met exactly (finished trials, none
left running, none failed). The trials are short (two surfaces, 6 s walks, ~0.1-0.4 s each), so
storage overhead shows; with the shipped studies' longer trials it matters less. This machine
has 2 cores: 8 workers oversubscribe it on purpose (the lock's cost under contention).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

STUDY = """name: bench
robot: kidsize
surfaces: [grass50, carpet4]
gait: tlipfm
base: tkux-table2
fixed: {{n_steps: 8}}
space:
  period: {{low: 0.5, high: 0.8}}
  h_z: {{low: 0.02, high: 0.06}}
objectives: [pitch_rms]
trials: {trials}
duration: 6.0
enqueue: [casadi, baselines]
sampler_seed: 1
"""


def main() -> None:
    import subprocess

    import optuna

    from postgres_server import PostgresServer
    from tuner.store.storage import StudyStore

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--workers", default="1,2,8")
    args = ap.parse_args()
    counts = [int(w) for w in args.workers.split(",")]
    exe = [sys.executable, "-m", "tuner.cli"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp, PostgresServer() as pg:
        tmp = Path(tmp)
        study = tmp / "bench.yaml"
        study.write_text(STUDY.format(trials=args.trials))
        for kind in ("journal", "sqlite", "postgresql"):
            for w in counts:
                tag = f"{kind}-{w}"
                storage = {"journal": None, "sqlite": f"sqlite:///{tmp / (tag + '.db')}",
                           "postgresql": pg.create_database(tag.replace("-", "_"))}[kind]
                runs = tmp / f"runs-{tag}"
                cmd = exe + ["tune", str(study), "--workers", str(w), "--runs", str(runs)]
                if storage:
                    cmd += ["--storage", storage]
                t0 = time.perf_counter()
                r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
                wall = time.perf_counter() - t0
                if r.returncode != 0:
                    print(f"{tag}: failed: {r.stderr.strip().splitlines()[-1]}")
                    continue
                s = optuna.load_study(study_name="bench",
                                      storage=StudyStore.open("bench", storage, runs).optuna_storage())
                states = [t.state.name for t in s.get_trials(deepcopy=False)]
                rows.append((kind, w, wall, states.count("COMPLETE") + states.count("PRUNED"),
                             states.count("RUNNING"), states.count("FAIL")))
                print(f"{tag}: {wall:.1f} s", flush=True)
    base = next((r[2] for r in rows if r[0] == "journal" and r[1] == 1), None)
    print(f"\n{args.trials} trials per run (2 surfaces x 6 s walks)")
    print(f"{'storage':11s} {'workers':>7s} {'wall s':>7s} {'trials/min':>10s} {'vs journal-1':>12s} "
          f"{'finished':>8s} {'running':>7s} {'failed':>6s}")
    for kind, w, wall, done, running, failed in rows:
        ratio = f"{base / wall:.2f}x" if base else "-"
        print(f"{kind:11s} {w:7d} {wall:7.1f} {60 * done / wall:10.1f} {ratio:>12s} {done:8d} {running:7d} {failed:6d}")


if __name__ == "__main__":
    main()
