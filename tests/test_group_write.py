"""Files written as one: a parameter set and its joint or servo table are all new or all old after
a kill at any moment (gaits/files.py ``write_files_atomic``).

The kill comes from inside, at each step of the write (before and after each fsync, chmod,
rename and removal ``gaits/files.py`` makes), with SIGKILL: no timing window. After each kill the
folder is read as a reader reads it (``load_gait_file``), and the set and its servo table must name
the same trial; nothing of the write may be left behind.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import run_in_process

import third_party_robot as T
from gaits.files import complete_pending_writes, write_files_atomic
from test_servo_table import servos_yaml

KILLER = """
import os, signal, sys, atexit
K = int(os.environ["KILL_AT"])
n = [0]
def step():
    if sys._getframe(2).f_code.co_filename.endswith(os.path.join("gaits", "files.py")):
        n[0] += 1
        if n[0] == K:
            os.kill(os.getpid(), signal.SIGKILL)
def wrap(fn):
    def w(*a, **k):
        step()
        r = fn(*a, **k)
        step()
        return r
    return w
for name in ("fsync", "replace", "unlink", "chmod"):
    setattr(os, name, wrap(getattr(os, name)))
atexit.register(lambda: print(f"STEPS {n[0]}", file=sys.stderr))
from tuner.cli import run
sys.argv = ["gait-tuner"] + sys.argv[1:]
run()
"""

STUDY = """\
name: pair
robot: {robot}
surfaces: [rigid]
gait: tlipfm
base: tkux-table2
fixed: {{n_steps: 4}}
space: {{z_c: {{low: 0.2, high: 0.22}}}}
trials: 2
enqueue: []
sampler_seed: 0
"""


def _trial_of(path: Path) -> int:
    first = path.read_text().splitlines()[0 if path.suffix == ".csv" else 1]
    return int(re.search(r"trial (\d+)", first).group(1))


@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pair")
    robot = T.write(tmp, T.mjcf(), T.map_yaml(extra=servos_yaml()))
    study = tmp / "pair.yaml"
    study.write_text(STUDY.format(robot=robot))
    r = run_in_process(['tune', str(study), '--runs', str(tmp / 'runs'), '--workers', '1'])
    assert r.returncode == 0, r.stderr
    return tmp, study


def _export(tmp, study, trial, env=None):
    return subprocess.run([sys.executable, "-c", KILLER, "export", str(study), "--runs", str(tmp / "runs"),
                           "--trial", str(trial), "--format", "servo", "--clip", "--out", str(tmp / "out" / "best.yaml")],
                          capture_output=True, text=True, env={**os.environ, **(env or {})})


def _kill_steps(steps: int, every: bool) -> list[int]:
    """Every step of an export, or (the default run) the first three, the middle three and the last
    three: the commit lies between the first and the last, so both outcomes are still seen."""
    if every:
        return list(range(1, steps + 1))
    mid = steps // 2
    return sorted({1, 2, 3, mid - 1, mid, mid + 1, steps - 2, steps - 1, steps})


@pytest.mark.parametrize("every", [False, pytest.param(True, marks=pytest.mark.slow)], ids=["sampled", "every"])
def test_a_kill_at_every_step_of_an_export_leaves_the_pair_whole(tuned, every):
    tmp, study = tuned
    out, table = tmp / "out" / "best.yaml", tmp / "out" / "best.servo.csv"
    r = _export(tmp, study, 0, {"KILL_AT": str(10 ** 9)})
    assert r.returncode == 0, r.stderr
    steps = int(re.search(r"STEPS (\d+)", r.stderr).group(1))
    assert steps >= 20, steps                 # before and after each of at least ten steps
    old = {path: path.read_bytes() for path in (out, table)}            # the old pair: trial 0, as exported
    seen = set()
    for k in _kill_steps(steps, every):
        for path, data in old.items():
            path.write_bytes(data)
        r = _export(tmp, study, 1, {"KILL_AT": str(k)})                 # killed while writing trial 1
        assert r.returncode == -9, (k, r.returncode, r.stderr[-500:])
        import gaits
        gaits.load_gait_file(out)                                       # as a reader reads it
        pair = (_trial_of(out), _trial_of(table))
        assert pair in ((0, 0), (1, 1)), (k, pair)
        seen.add(pair)
        left = [p.name for p in out.parent.iterdir() if p.name.startswith(".")]
        assert left == [], (k, left)
    assert seen == {(0, 0), (1, 1)}           # kills before the commit keep the old, after it the new


def test_write_files_atomic_refuses_two_folders(tmp_path):
    with pytest.raises(ValueError, match="share one folder"):
        write_files_atomic({tmp_path / "a": "1", tmp_path / "sub" / "b": "2"})
    assert write_files_atomic({tmp_path / "a": "1", tmp_path / "b": "2"}) == [tmp_path / "a", tmp_path / "b"]
    assert (tmp_path / "a").read_text() == "1" and complete_pending_writes(tmp_path) == 0
