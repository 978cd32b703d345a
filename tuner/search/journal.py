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


class SafeJournalBackend(JournalFileBackend):
    """Optuna's journal file with our lock, a torn-tail check before each append, and a failed
    append rolled back to the size it had, so a full disk leaves the file whole."""

    def __init__(self, file_path: str | Path) -> None:
        path = Path(file_path).resolve()
        super().__init__(str(path), lock_obj=FlockLock(path))
        self._path = path

    def append_logs(self, logs: list[dict[str, Any]]) -> None:
        data = ("\n".join(json.dumps(log, separators=(",", ":")) for log in logs) + "\n").encode()
        with self._lock:
            _cut_torn_tail(self._path)
            size = self._path.stat().st_size
            try:
                with open(self._path, "ab") as f:
                    f.write(data)
                    f.flush()
                    os.fsync(f.fileno())
            except OSError as exc:
                with contextlib.suppress(OSError):
                    os.truncate(self._path, size)
                if exc.errno in DISK_FULL:
                    raise StorageFull(f"disk full writing {self._path} ({os.strerror(exc.errno)}); "
                                      f"the journal was left whole: free space and run the same "
                                      f"command to resume") from None
                raise
