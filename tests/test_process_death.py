"""No process of the tool outlives its parent, whatever ends the parent (SIGKILL, SIGTERM, or
Ctrl-C, which a terminal sends to the whole process group), and an interrupt is one line from
the parent, nothing from its workers.

Each verb starts in a session of its own; once its workers exist (polled, not waited for), the
signal goes to the parent (Ctrl-C: to the group), and every process that was its descendant must
then be gone (polled, with a generous deadline: the kernel's death signal is immediate, so only a
survivor would take long).
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest

from conftest import ROOT


def _children() -> dict[int, int]:
    """pid -> parent pid of every process."""
    out = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            out[int(d.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    return out


def _descendants(pid: int) -> set[int]:
    ppid = _children()
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in ppid.items() if pp in frontier} - found
        found |= frontier
    return found


def _alive(pid: int) -> bool:
    try:
        return "zombie" not in Path(f"/proc/{pid}/status").read_text().split("State:")[1].split("\n")[0].lower() \
            and Path(f"/proc/{pid}").exists()
    except (OSError, IndexError):
        return False


def _as_a_terminal_starts_it() -> None:
    """In the child before it runs: Ctrl-C as a shell gives it to a program it starts (default,
    unblocked), whatever this test process inherited or had changed by an earlier test or library
    (the test process's own handler is inherited until the exec: :func:`_maps_mujoco` waits for it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT])


def _maps_mujoco(pid: int) -> bool:
    """The program has loaded MuJoCo: its command line is no longer this process's (it has exec'd: a child
    between its fork and its exec maps this test process's own MuJoCo, and a Ctrl-C sent then is
    taken by this process's handler in the child and lost at the exec), then its maps hold it."""
    try:
        if Path(f"/proc/{pid}/cmdline").read_bytes() == Path("/proc/self/cmdline").read_bytes():
            return False                # not exec'd yet
        return "mujoco" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


def _poll(cond, deadline: float = 120.0) -> bool:
    end = time.monotonic() + deadline
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.05)
    return cond()


VERBS = {
    "tune": (["tune", str(ROOT / "studies" / "quickstart.yaml"), "--workers", "2", "--trials", "500"], 2),
    "robustness": (["robustness", "--params", "kidsize-robust-grass50", "--surface", "grass50", "--rollouts", "400",
                    "--workers", "2", "--pushes", ""], 2),
    "calibrate": (["calibrate", "--workers", "2"], 2),
    "challenge": (["challenge", "push", "--params", "kidsize-engine-carpet4", "--surface", "carpet4"], 0),
}


@pytest.mark.parametrize("how", ["SIGKILL", "SIGTERM", "ctrl-c"])
@pytest.mark.parametrize("verb", list(VERBS))
def test_no_process_outlives_its_parent(tmp_path, gait_tuner_cmd, run_env, verb, how):
    args, workers = VERBS[verb]
    p = subprocess.Popen(gait_tuner_cmd + args + (["--runs", str(tmp_path / "runs")] if verb == "tune" else []),
                         cwd=tmp_path, env=run_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=_as_a_terminal_starts_it)
    try:
        if workers:
            assert _poll(lambda: len(_descendants(p.pid)) >= workers or p.poll() is not None), "no workers started"
        else:
            # no workers to wait for: wait until it loads MuJoCo (its command line is loading)
            assert _poll(lambda: _maps_mujoco(p.pid) or p.poll() is not None), "MuJoCo never loaded"
        assert p.poll() is None, p.stderr.read()
        family = _descendants(p.pid)
        if how == "ctrl-c":
            os.killpg(p.pid, signal.SIGINT)
        else:
            os.kill(p.pid, getattr(signal, how))
        out, err = p.communicate(timeout=120)
        assert _poll(lambda: not any(_alive(c) for c in family)), f"left running: {[c for c in family if _alive(c)]}"
        if how == "ctrl-c":
            assert p.returncode == 130, (p.returncode, err[-2000:])
            assert "Traceback" not in err and "KeyboardInterrupt" not in err and "BrokenPipe" not in err, err[-2000:]
            last = err.rstrip().splitlines()[-1]
            assert last == "gait-tuner: interrupted" or last.startswith("interrupted: finished trials are kept"), \
                err[-2000:]
            assert sum("interrupted" in line for line in err.splitlines()) == 1, err[-2000:]
        else:
            assert p.returncode == -getattr(signal, how), (p.returncode, err[-2000:])
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


@pytest.mark.parametrize("module", ["mujoco", "click", "optuna"])
def test_ctrl_c_while_the_libraries_load_is_one_line(tmp_path, module):
    """A real SIGINT sent to itself while the libraries load (inside the package's own imports,
    the command line's, a verb's lazy one): one line, 130, whichever module it lands in. No timing: the signal
    is sent from the import itself."""
    code = ("import builtins, os, signal, sys\n"
            "sys.argv = ['/usr/bin/gait-tuner', 'studies']\n"
            "real = builtins.__import__\n"
            "def imp(name, *a, **k):\n"
            f"    if name.startswith({module!r}):\n"
            "        os.kill(os.getpid(), signal.SIGINT)\n"
            "    return real(name, *a, **k)\n"
            "builtins.__import__ = imp\n"
            "from tuner.cli import run\n"
            "run()\n")
    r = subprocess.run([os.sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path,
                       preexec_fn=_as_a_terminal_starts_it)
    # (after loading, click ends the terminal's "^C" line first: a newline, then the one line)
    assert r.returncode == 130 and r.stderr.strip() == "gait-tuner: interrupted", (r.returncode, r.stderr[-1500:])


def test_ctrl_c_after_loading_is_pythons_again(tmp_path):
    """Once the command line runs, Ctrl-C is Python's KeyboardInterrupt again (the verbs tidy up
    their work on it; the handler counts it, so a Ctrl-C that breaks a library's import is still an
    interrupt), and a library import of the package never touches the handler."""
    code = ("import signal, sys\n"
            "sys.argv = ['/usr/bin/gait-tuner', '--version']\n"
            "import tuner\n"
            "assert signal.getsignal(signal.SIGINT) is tuner._interrupted_while_loading\n"
            "from tuner.cli import main\n"
            "main(['--version'])\n"
            "import os, time\n"
            "try:\n"
            "    os.kill(os.getpid(), signal.SIGINT)\n"
            "    time.sleep(5)\n"
            "except KeyboardInterrupt:\n"
            "    print('ok')\n")
    r = subprocess.run([os.sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path,
                       preexec_fn=_as_a_terminal_starts_it)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), (r.returncode, r.stdout, r.stderr[-1500:])
    r = subprocess.run([os.sys.executable, "-c", "import signal, tuner\n"
                        "assert signal.getsignal(signal.SIGINT) is signal.default_int_handler"],
                       capture_output=True, text=True, cwd=tmp_path, preexec_fn=_as_a_terminal_starts_it)
    assert r.returncode == 0, r.stderr[-1500:]


def test_a_ctrl_c_while_forking_reaches_the_parent_and_no_child():
    """forking_without_ctrl_c blocks SIGINT while workers are forked: a child starts with it
    blocked (a Ctrl-C landing before its ignore_ctrl_c waits, then is dropped: it exits 0, no
    traceback), and the parent takes a Ctrl-C sent during the block when the block ends."""
    from tuner.process_pool import forking_without_ctrl_c, ignore_ctrl_c
    reached = []
    # Python's own handler, whatever an earlier test (or the CLI's loading guard) left installed
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        _fork_under_the_block(forking_without_ctrl_c, ignore_ctrl_c, reached)
    finally:
        signal.signal(signal.SIGINT, before)
    assert reached == [0]                                  # the block held it past the child's end
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, set())


def _fork_under_the_block(forking_without_ctrl_c, ignore_ctrl_c, reached: list) -> None:
    with pytest.raises(KeyboardInterrupt):
        with forking_without_ctrl_c():
            pid = os.fork()
            if pid == 0:                                   # the child: SIGINT still blocked here
                try:
                    blocked = signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, set())
                    os.kill(os.getpid(), signal.SIGINT)    # a Ctrl-C before the worker's set-up
                    ignore_ctrl_c()
                    os._exit(0 if blocked else 3)
                except BaseException:
                    os._exit(4)
            # the parent's Ctrl-C, held until the block ends: sent to this thread (a signal sent to
            # the process goes to any thread not blocking it, and pytest may have others by now)
            signal.pthread_kill(threading.get_ident(), signal.SIGINT)
            _, status = os.waitpid(pid, 0)
            reached.append(os.waitstatus_to_exitcode(status))
        pytest.fail("the Ctrl-C sent during the block never came")
