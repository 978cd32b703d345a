import os
import subprocess
import sys
from pathlib import Path

import pytest

import tuner

ROOT = Path(__file__).resolve().parents[1]
#: ``tuner`` chooses MuJoCo's GL backend (EGL on a headless Linux) when it is imported before
#: mujoco: imported here, before any test module, so which module a worker collects first (one that
#: imports mujoco first) cannot leave a render in the same worker without a GL context
GL_BACKEND = tuner.__name__


@pytest.fixture
def gait_tuner_cmd():
    """The real console script of this environment (falls back to python -m)."""
    exe = Path(sys.executable).with_name("gait-tuner")
    if exe.exists():
        return [str(exe)]
    return [sys.executable, "-m", "tuner.cli"]


@pytest.fixture
def run_env():
    env = dict(os.environ)
    env["MPLBACKEND"] = "Agg"
    return env


def run_in_process(args, cwd=None) -> "subprocess.CompletedProcess":
    """The command line run in this process (``tuner.cli.main``, what the console script calls), its
    output captured: a ``subprocess.CompletedProcess`` (returncode, stdout, stderr), as a subprocess
    run would give it, without a second of imports per call. For what a verb says and writes; a
    test of processes (a kill, Ctrl-C, the environment) keeps the subprocess."""
    import contextlib
    import io
    import signal

    from tuner.cli import main
    args = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    here, handler = os.getcwd(), signal.getsignal(signal.SIGINT)
    os.environ.setdefault("MPLBACKEND", "Agg")
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(args)
    finally:
        os.chdir(here)
        signal.signal(signal.SIGINT, handler)
    return subprocess.CompletedProcess(["gait-tuner", *args], code, out.getvalue(), err.getvalue())


#: Variables whose values do not make a run in this process differ from a subprocess's: the plots'
#: backend (Agg either way here), the test pytest is in (it changes between a fixture's setup, where
#: ``run_env`` copies the environment, and the call) and the GL backend ``tuner`` sets when unset.
_SAME_IN_PROCESS = frozenset({"MPLBACKEND", "PYTEST_CURRENT_TEST", "MUJOCO_GL"})


def run_cli(cmd, args, env=None, cwd=None, timeout=600, **kw) -> "subprocess.CompletedProcess":
    """``cmd + args`` as the tests' helpers ran it: in this process when nothing about the process
    is asked (the test's own environment, no input, no other keyword), in a subprocess otherwise."""
    same_env = env is None or {k: v for k, v in env.items() if k not in _SAME_IN_PROCESS} == \
        {k: v for k, v in os.environ.items() if k not in _SAME_IN_PROCESS}
    if same_env and not kw:
        return run_in_process(args, cwd=cwd)
    return subprocess.run(list(cmd) + [str(a) for a in args], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=timeout, **kw)


#: The default run's longest tests (over 15 s on this 2-core machine), started first: on two
#: workers (make test) a long test begun last would run alone at the end.
LONG_FIRST = ("test_readme.py::test_readme_commands_run", "test_group_write.py::test_a_kill_at_every_step",
              "test_bus.py::test_a_sweep_through_the_bus", "test_init.py::test_init_writes_a_study",
              "test_identify.py::test_a_sweep_stays_within", "test_packaging.py::test_the_robot_part_installs",
              "test_calibration.py::test_a_one_point_blade_calibration", "test_byo_robot.py::test_compare_uses")


def pytest_collection_modifyitems(config, items):
    """The longest tests first (:data:`LONG_FIRST`), the rest in their order: the same on every worker."""
    def rank(item) -> int:
        return next((k for k, key in enumerate(LONG_FIRST) if key in item.nodeid), len(LONG_FIRST))
    items[:] = sorted(items, key=rank)            # stable: the rest keep their order
