"""Worker liveness: who runs a trial, whether that process is still alive, and its heartbeat.

Liveness. Every trial records its worker (host, pid, process start time). A RUNNING trial
is dead when its worker is on this host and that process is gone, or when its heartbeat is
older than ``grace_s``: on a database Optuna's heartbeat table (``record_heartbeat``), on the
journal a file per worker under ``runs/<study>.heartbeats/`` touched every ``interval_s``.
A dead trial is failed and enqueued again once with the same parameters and user
attributes (so a CasADi seed that died is still evaluated); a retry that dies is not retried.

"""

from __future__ import annotations

import contextlib
import os
import socket
import threading
from pathlib import Path
from typing import Any

__all__ = ["HEARTBEAT_INTERVAL_S", "HEARTBEAT_GRACE_S", "process_identity", "alive_here", "worker_file",
           "Heartbeat"]

HEARTBEAT_INTERVAL_S = 10.0     # [s] how often a worker proves it is alive
HEARTBEAT_GRACE_S = 60.0        # [s] a trial whose heartbeat is older is dead (other hosts)


def process_identity(pid: int | None = None) -> dict[str, Any]:
    """host, pid and the process's start time (``/proc``; guards against pid reuse)."""
    pid = os.getpid() if pid is None else pid
    return {"host": socket.gethostname(), "pid": pid, "start": _start_time(pid)}


def _proc_stat(pid: int) -> list[str] | None:
    """Fields of /proc/PID/stat after the command name (state first), or None."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None


def _start_time(pid: int) -> int | None:
    fields = _proc_stat(pid)
    return None if fields is None else int(fields[19])


def alive_here(ident: dict[str, Any]) -> bool | None:
    """True/False for a worker on this host, None when it runs elsewhere (cannot tell)."""
    if ident.get("host") != socket.gethostname():
        return None
    pid = int(ident.get("pid", -1))
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    fields = _proc_stat(pid)
    if fields is None:
        return True                 # no /proc: the signal said it exists
    if fields[0] in ("Z", "X"):     # a zombie (killed, not yet reaped) is dead
        return False
    start = ident.get("start")
    return start is None or int(fields[19]) == start


def worker_file(ident: dict[str, Any] | None = None) -> str:
    ident = ident or process_identity()
    return f"{ident.get('host')}-{ident.get('pid')}"


class Heartbeat:
    """A daemon thread beating for this process every ``interval_s`` while it works a trial."""

    def __init__(self, store: Any, study_name: str) -> None:
        """``store``: the study's ``tuner.store.storage.StudyStore`` (it writes the beats)."""
        self.store, self.study_name = store, study_name
        self.trial_id: int | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="gait-tuner-heartbeat")

    def start(self) -> "Heartbeat":
        self.store.beat(self.study_name, None)
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.wait(self.store.interval_s):
            with contextlib.suppress(Exception):
                self.store.beat(self.study_name, self.trial_id)

    def stop(self) -> None:
        self._stop.set()
        folder = self.store.heartbeat_dir(self.study_name)
        if folder is not None:
            with contextlib.suppress(OSError):
                (folder / worker_file()).unlink()
