"""The journal file's hardening: a kernel lock, writes rolled back on a full disk, torn lines cut.

Two kinds of storage:
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from optuna.storages.journal import JournalFileBackend
from optuna.storages.journal._file import BaseJournalFileLock  # the lock interface JournalFileBackend takes
from optuna.storages.journal._storage import JournalOperation as Op   # the records' op codes
from optuna.trial import TrialState

from ..errors import UserError

__all__ = ["DISK_FULL", "StorageFull", "FlockLock", "repair_journal", "SafeJournalBackend"]

DISK_FULL = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


class StorageFull(UserError):
    """The disk (or a file-size limit) refused a write; the storage was left whole."""


class FlockLock(BaseJournalFileLock):
    """A kernel ``flock`` on ``<target>.flock``: released by the kernel if the holder dies."""

    def __init__(self, target: str | Path, suffix: str = ".flock") -> None:
        self.path = str(Path(target).resolve()) + suffix
        self._fd: int | None = None

    def acquire(self) -> bool:
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd
        return True

    def release(self) -> None:
        fd, self._fd = self._fd, None
        if fd is not None:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)

    def __enter__(self) -> "FlockLock":
        self.acquire()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()


def _cut_torn_tail(path: Path, warn: bool = True) -> int:
    """Truncate ``path`` after its last newline; the cut bytes go to ``<path>.torn-<time>``.
    Returns the number of bytes cut. The caller holds the journal lock."""
    size = path.stat().st_size
    if size == 0:
        return 0
    with open(path, "rb+") as f:
        block = 1 << 16
        pos = size
        tail = b""
        while pos > 0:
            start = max(0, pos - block)
            f.seek(start)
            chunk = f.read(pos - start)
            i = chunk.rfind(b"\n")
            if i >= 0:
                keep = start + i + 1
                break
            tail = chunk + tail
            pos = start
        else:
            keep = 0
        if keep == size:
            return 0
        f.seek(keep)
        torn = f.read()
        f.truncate(keep)
        f.flush()
        os.fsync(f.fileno())
    keep_as = path.with_name(f"{path.name}.torn-{time.strftime('%Y%m%d-%H%M%S')}")
    with contextlib.suppress(OSError):
        keep_as.write_bytes(torn)
    if warn:
        print(f"gait-tuner: warning: {path}: cut a torn last line of {len(torn)} bytes "
              f"(an interrupted write; kept in {keep_as.name})", file=sys.stderr)
    return len(torn)


def repair_journal(path: Path) -> int:
    """Cut a torn last line (bytes after the last newline: Optuna writes each record and its
    newline in one write, so a kill or a full disk mid-write leaves exactly that), under its lock.

    Returns the bytes cut. A whole line that is not JSON is not guessed at: opening the journal
    then fails with a :class:`UserError` naming the file, since dropping it could lose a trial.
    """
    if not path.exists() or path.stat().st_size == 0:
        return 0
    with FlockLock(path):
        cut = _cut_torn_tail(path)
        size = path.stat().st_size
        with open(path, "rb") as f:
            f.seek(max(0, size - (1 << 20)))
            lines = f.read().split(b"\n")
    last = lines[-2] if len(lines) >= 2 else b""
    if size:
        try:
            json.loads(last)
        except ValueError:      # Optuna's reader skips a bad last line silently: say so instead
            raise UserError(f"journal {path} is corrupt: its last line is not a journal record "
                            f"(not a file written by gait-tuner, or edited)") from None
    return cut


#: Journal records that need not reach the disk at once: a running trial's parameters,
#: attributes and intermediate values. They are written (the kernel holds them: a killed process
#: loses nothing) and made durable by the next record that is not one of them; a trial's
#: finishing record is never one of them, so a trial costs one fsync, not one per record.
#: A power cut between two fsyncs loses the running trials' latest records only: such a trial is
#: found dead at the next open and walked again.
_DEFERRED_OPS = frozenset({Op.SET_TRIAL_PARAM, Op.SET_TRIAL_INTERMEDIATE_VALUE, Op.SET_TRIAL_USER_ATTR,
                           Op.SET_TRIAL_SYSTEM_ATTR})
_RUNNING = int(TrialState.RUNNING)        # a new trial, or one popped from the queue


def _durable(logs: list[dict[str, Any]]) -> bool:
    """Whether ``logs`` must be on the disk before the append returns (see _DEFERRED_OPS)."""
    for log in logs:
        op = log.get("op_code")
        if op in _DEFERRED_OPS:
            continue
        if op == Op.SET_TRIAL_STATE_VALUES and log.get("state") == _RUNNING:
            continue
        if op == Op.CREATE_TRIAL and log.get("state", _RUNNING) == _RUNNING:   # not enqueued, not added
            continue
        return True
    return False


class SafeJournalBackend(JournalFileBackend):
    """Optuna's journal file with our lock, a torn-tail check before each append, a failed
    append rolled back to the size it had (a full disk leaves the file whole), and one fsync per
    trial (:data:`_DEFERRED_OPS`) instead of one per record."""

    def __init__(self, file_path: str | Path) -> None:
        path = Path(file_path).resolve()
        super().__init__(str(path), lock_obj=FlockLock(path))
        self._path = path
        self.fsyncs = 0           # counted for the tests and the scale benchmark

    def append_logs(self, logs: list[dict[str, Any]]) -> None:
        data = ("\n".join(json.dumps(log, separators=(",", ":")) for log in logs) + "\n").encode()
        durable = _durable(logs)
        with self._lock:
            size = self._path.stat().st_size
            if size:
                size -= _cut_torn_tail_if_any(self._path, size)
            try:
                with open(self._path, "ab") as f:
                    f.write(data)
                    f.flush()
                    if durable:
                        os.fsync(f.fileno())
                        self.fsyncs += 1
            except OSError as exc:
                with contextlib.suppress(OSError):
                    os.truncate(self._path, size)
                if exc.errno in DISK_FULL:
                    raise StorageFull(f"disk full writing {self._path} ({os.strerror(exc.errno)}); "
                                      f"the journal was left whole: free space and run the same "
                                      f"command to resume") from None
                raise


def _cut_torn_tail_if_any(path: Path, size: int) -> int:
    """:func:`_cut_torn_tail` when the file does not end with a newline (one byte read otherwise)."""
    with open(path, "rb") as f:
        f.seek(size - 1)
        if f.read(1) == b"\n":
            return 0
    return _cut_torn_tail(path)
