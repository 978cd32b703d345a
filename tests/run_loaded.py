"""Run tests with the machine loaded: ``python tests/run_loaded.py [pytest args]``.

Starts one busy process per core (pure Python loops, ``os.nice`` 0, so they compete with the
tests on equal terms), runs pytest on the given arguments, stops the busy processes, and exits
with pytest's code: a test that waits for a window in wall time fails here. ``make test`` keeps
both cores busy with its own two workers (pytest-xdist); this loads a machine for any other run.
"""

from __future__ import annotations

import os
import subprocess
import sys

BUSY = "while True:\n    pass\n"


def main(argv: list[str]) -> int:
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 2)
    busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(cores)]
    print(f"run_loaded: {cores} busy process(es) competing with the tests", flush=True)
    try:
        return subprocess.call([sys.executable, "-m", "pytest", "-q", *argv])
    finally:
        for p in busy:
            p.kill()
        for p in busy:
            p.wait()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
