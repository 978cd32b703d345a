"""CPU time of the command line's face: ``gait-tuner --help`` and a one-line refusal.

Each command runs ``--repeat`` times in a fresh interpreter (``python -m tuner.cli``); the figure is
the median of the child's user + system CPU seconds (``resource.getrusage``), not wall time, so a
busy machine moves it little. With ``--ref REV`` the same commands also run on that commit of the
house (a ``git worktree`` of it, with this environment's packages), beside today's:

    python benchmarks/bench_cli.py --ref d5dbd03^     # the last commit with one cli.py

Prints one line per command and commit, or ``--json``.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: --help; a verb that does not exist; an option value click refuses (the verb's module is loaded); a
#: robot that does not exist (refused after the robot wing is loaded: a one-line error, not a fast one)
COMMANDS = {"--help": ["--help"], "unknown verb": ["no-such-verb"], "bad value": ["simulate", "--duration", "abc"],
            "no such robot": ["simulate", "--robot", "no-such-robot"]}


def cpu_seconds(args: list[str], cwd: Path) -> float:
    """User + system CPU seconds of one ``python -m tuner.cli ARGS`` run in ``cwd``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-m", "tuner.cli", *args], cwd=cwd, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def measure(cwd: Path, repeat: int) -> dict[str, float]:
    cpu_seconds(["--help"], cwd)                      # warm the file cache and the .pyc files
    return {name: statistics.median(cpu_seconds(args, cwd) for _ in range(repeat)) for name, args in COMMANDS.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--ref", help="Also measure this commit (a git revision), in a worktree.")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    rows = {"HEAD": measure(ROOT, a.repeat)}
    if a.ref:
        with tempfile.TemporaryDirectory() as tmp:
            where = Path(tmp) / "ref"
            subprocess.run(["git", "worktree", "add", "--detach", str(where), a.ref], cwd=ROOT, check=True,
                           capture_output=True)
            try:
                rows[a.ref] = measure(where, a.repeat)
            finally:
                subprocess.run(["git", "worktree", "remove", "--force", str(where)], cwd=ROOT, check=False,
                               capture_output=True)
    if a.json:
        print(json.dumps(rows))
        return
    for rev, figures in rows.items():
        print(f"{rev}: " + ", ".join(f"{k} {v:.3f} s CPU" for k, v in figures.items()) + f" (median of {a.repeat})")


if __name__ == "__main__":
    main()
