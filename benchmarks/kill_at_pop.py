"""Benchmark (not a test): a worker killed from outside as it pops an enqueued start, in fresh
studies (issue 62: "a kill at the pop loses nothing in 50 of 50 fresh studies, from outside,
unpatched, journal and PostgreSQL"; figures in docs/studies-at-scale.md).

    python benchmarks/kill_at_pop.py --studies 50 --storage journal|postgresql [--seed 11] [--out DIR]

Each study is tests/test_storage.py's STUDY (the CasADi seed and a baseline enqueued, 5 trials,
two short surfaces); `gait-tuner tune STUDY --workers 2` runs in its own process; once both workers
exist, one of them gets SIGKILL after a random 0-1.5 s (the seed's), when the workers pop the two
starts and walk them. Then every enqueued start must have ended walked (complete or pruned, itself
or its retry). Prints one line per study and the count of studies that lost a start. PostgreSQL:
a server from the pgserver wheel (tests/postgres_server.py), a fresh database per study.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def one(i: int, folder: Path, storage: str | None, rng: random.Random, study_text: str) -> tuple[int | None, dict]:
    import optuna
    from tuner.store.storage import StudyStore
    d = folder / f"s{i}"
    d.mkdir(parents=True, exist_ok=True)
    (d / "study.yaml").write_text(study_text.format(name=f"s{i}", trials=5, surfaces="[grass50, carpet4]"))
    where = ["--storage", storage] if storage else ["--runs", str(d / "runs")]
    p = subprocess.Popen([sys.executable, "-m", "tuner.cli", "tune", str(d / "study.yaml"), "--workers", "2", *where],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0, kids = time.monotonic(), []
    while len(kids) < 2 and time.monotonic() - t0 < 60 and p.poll() is None:
        kids = [k for k in subprocess.run(["pgrep", "-P", str(p.pid)], capture_output=True, text=True).stdout.split()
                if k]
        time.sleep(0.01)
    time.sleep(rng.uniform(0.0, 1.5))
    victim = None
    if kids:
        victim = int(rng.choice(kids))
        try:
            os.kill(victim, signal.SIGKILL)
        except ProcessLookupError:
            victim = None
    p.communicate(timeout=600)
    url = storage or StudyStore.open(f"s{i}", None, d / "runs").optuna_storage()
    trials = optuna.load_study(study_name=f"s{i}", storage=url).get_trials(deepcopy=False)
    starts: dict[str, list[str]] = {}
    for t in trials:
        if t.user_attrs.get("start") is not None:
            starts.setdefault(t.user_attrs["start"], []).append(t.state.name)
    return victim, starts


def main() -> None:
    import optuna
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--studies", type=int, default=50)
    ap.add_argument("--storage", choices=("journal", "postgresql"), default="journal")
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    study_text = (ROOT / "tests" / "test_storage.py").read_text().split('STUDY = """', 1)[1].split('"""', 1)[0]
    rng = random.Random(args.seed)
    folder = args.out or Path(tempfile.mkdtemp(prefix="kill-at-pop-"))
    lost, killed, retried = [], 0, 0
    server = None
    if args.storage == "postgresql":
        from postgres_server import PostgresServer
        server = PostgresServer().start()
    try:
        for i in range(args.studies):
            url = server.create_database(f"s{i}") if server else None
            victim, starts = one(i, folder, url, rng, study_text)
            killed += victim is not None
            retried += any("FAIL" in v for v in starts.values())
            walked = {s for s, states in starts.items() if {"COMPLETE", "PRUNED"} & set(states)}
            if walked != {"casadi seed", "baseline 0"} or set(starts) != walked:
                lost.append((i, starts))
            print(f"study {i}: killed worker {victim}, starts {starts}", flush=True)
    finally:
        if server is not None:
            server.stop()
    print(f"{args.storage}: {args.studies} studies, a worker killed in {killed}, a start retried in {retried}, "
          f"a start lost in {len(lost)}")
    for x in lost:
        print("lost:", x)


if __name__ == "__main__":
    main()
