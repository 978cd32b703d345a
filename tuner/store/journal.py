"""The journal file's hardening (a kernel lock, writes rolled back on a full disk, torn lines cut)
and its replay held packed (a finished trial in memory as a compressed record, not objects).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import pickle
import sys
import threading
import time
import uuid
import zlib
from pathlib import Path
from typing import Any

from optuna.storages import JournalStorage
from optuna.storages.journal import JournalFileBackend
from optuna.trial import FrozenTrial, TrialState

from ..errors import UserError
from .optuna_compat import BaseJournalFileLock  # the lock interface JournalFileBackend takes
from .optuna_compat import FROZEN_TRIAL_FIELDS, BaseJournalSnapshot
from .optuna_compat import JournalOperation as Op   # the records' op codes
from .optuna_compat import JournalStorageReplayResult

__all__ = ["DISK_FULL", "StorageFull", "FlockLock", "repair_journal", "SafeJournalBackend", "PackedTrial",
           "PackedJournalStorage", "unpacked"]

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



# -- the replay held packed -----------------------------------------------------------------------

#: a packed trial's fields kept as objects: read for every trial by a scan of the study (its
#: number, its state for a filter by state, its id) or by Optuna's median pruner at every report
#: (its intermediate values: empty, or a few numbers per trial)
_KEPT = ("_number", "state", "_trial_id", "intermediate_values")
#: FrozenTrial's fields in the order its constructor sets them (its repr and hash follow it)
_ORDER = FROZEN_TRIAL_FIELDS


class PackedTrial(FrozenTrial):
    """A finished trial as a worker's journal replay holds it: its number, state, id and
    intermediate values as objects, every other field (parameters, distributions, values,
    attributes, times) one zlib-compressed pickle, unpacked at each read of such a field.

    Ours. Optuna's replay keeps every trial of the journal as objects (~11 kB a trial of a
    gait-tuner study: its walked set and result as dicts), so a worker's memory grew by ~100 MB
    over 10k trials; packed, ~1 kB. It is a FrozenTrial for every reader (its fields read as
    Optuna's, equal to the unpacked trial); a field read is a fresh copy, so changing what a read
    returns changes nothing held (as Optuna's ``deepcopy=True`` reads). A field set on it is
    kept as an object, ahead of the packed one. Hot readers take :func:`unpacked` once.
    """

    def __init__(self, trial: FrozenTrial, zdict: bytes = b"") -> None:   # FrozenTrial's init: packed here
        d = unpacked(trial).__dict__
        own = self.__dict__
        for k in _KEPT:
            own[k] = d[k]
        rest = {k: v for k, v in d.items() if k not in _KEPT}
        # ``zdict``: a like trial's record (one bytes object shared by the replay's trials), so
        # that what trials share (parameter names, distributions, attribute keys) packs to little
        pack = zlib.compressobj(1, zdict=zdict) if zdict else zlib.compressobj(1)
        own["_packed"] = pack.compress(pickle.dumps(rest, protocol=pickle.HIGHEST_PROTOCOL)) + pack.flush()
        own["_zdict"] = zdict

    def _rest(self) -> dict[str, Any]:
        own = self.__dict__
        unpack = zlib.decompressobj(zdict=own["_zdict"]) if own["_zdict"] else zlib.decompressobj()
        return pickle.loads(unpack.decompress(own["_packed"]) + unpack.flush())

    def _fields(self) -> dict[str, Any]:
        """Every field, unpacked (a fresh copy), in FrozenTrial's order."""
        rest = self._rest()
        rest.update((k, v) for k, v in self.__dict__.items() if k not in ("_packed", "_zdict"))
        return {k: rest[k] for k in _ORDER if k in rest} | {k: v for k, v in rest.items() if k not in _ORDER}

    def __getattr__(self, name: str) -> Any:            # only for names not held as objects
        if name.startswith("__") or name in ("_packed", "_zdict") or "_packed" not in self.__dict__:
            raise AttributeError(name)
        try:
            return self._rest()[name]
        except KeyError:
            raise AttributeError(name) from None

    def __eq__(self, other: Any) -> bool:
        if not isinstance(other, FrozenTrial):
            return NotImplemented
        return unpacked(other).__dict__ == self._fields()

    def __hash__(self) -> int:
        return hash(unpacked(self))

    def __repr__(self) -> str:
        return repr(unpacked(self)).replace("FrozenTrial(", "PackedTrial(", 1)


def unpacked(trial: FrozenTrial) -> FrozenTrial:
    """``trial`` as a plain FrozenTrial (a :class:`PackedTrial` unpacked; any other as it is)."""
    if not isinstance(trial, PackedTrial):
        return trial
    out = FrozenTrial.__new__(FrozenTrial)
    out.__dict__.update(trial._fields())
    return out


class _PackedReplay(JournalStorageReplayResult):
    """Optuna's replay of the journal, a trial packed when it is read finished (created finished,
    or its state set to a finished one); a finished trial is never changed again."""

    _zdict = b""

    def _pack(self, trial_id: int) -> None:
        t = self._trials.get(trial_id)
        if t is None or not t.state.is_finished() or isinstance(t, PackedTrial):
            return
        if not self._zdict:          # the first finished trial's record: the others' dictionary
            rest = {k: v for k, v in t.__dict__.items() if k not in _KEPT}
            self._zdict = pickle.dumps(rest, protocol=pickle.HIGHEST_PROTOCOL)
        self._trials[trial_id] = PackedTrial(t, self._zdict)

    def _apply_create_trial(self, log: dict[str, Any]) -> None:
        before = len(self._trials)
        super()._apply_create_trial(log)
        if len(self._trials) > before:
            self._pack(before)                          # Optuna numbers trial ids from 0 in replay order

    def _apply_set_trial_state_values(self, log: dict[str, Any]) -> None:
        super()._apply_set_trial_state_values(log)
        self._pack(log["trial_id"])


class PackedJournalStorage(JournalStorage):
    """Optuna's journal storage whose replay holds finished trials packed (:class:`PackedTrial`).

    Its ``__init__`` and ``__setstate__`` are Optuna's (optuna<6 pinned) with our replay; a
    backend with snapshots (Optuna's Redis) would restore Optuna's own replay, unpacked, so it
    is refused here (gait-tuner's journal is a file)."""

    def __init__(self, log_storage: Any) -> None:       # noqa: D107 - Optuna's, with our replay
        if isinstance(log_storage, BaseJournalSnapshot):
            raise TypeError("PackedJournalStorage: a journal backend with snapshots is not supported")
        self._worker_id_prefix = str(uuid.uuid4()) + "-"
        self._backend = log_storage
        self._thread_lock = threading.Lock()
        self._replay_result = _PackedReplay(self._worker_id_prefix)
        with self._thread_lock:
            self._sync_with_backend()

    def __setstate__(self, state: dict[Any, Any]) -> None:
        super().__setstate__(state)
        self._replay_result = _PackedReplay(self._worker_id_prefix)
