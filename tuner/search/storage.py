"""Where a study lives, and what keeps it whole: the one adapter between the tuner and Optuna storage.

Two kinds of storage:

* the default **journal file** ``runs/<study>.journal`` (no server; one machine, or a shared
  disk). Optuna's own file lock is a symlink whose staleness is judged by the link target's
  mtime; with a relative ``--runs`` the target does not resolve and a lock left by a killed
  process made every later run spin forever. Ours (:class:`FlockLock`) is a kernel
  ``flock`` on ``<journal>.flock``: the kernel drops it when its holder dies, so there is no
  stale lock to recover. A write that fails (full disk, size limit) is rolled back to the last
  whole line before the error is raised (:class:`SafeJournalBackend`), and a torn last line
  left by a kill mid-write is cut off on open, with a warning and the bytes kept beside the
  journal (:func:`repair_journal`); a journal is never appended onto a torn line.
* a **database URL**: ``sqlite:///file.db`` or ``postgresql://user@host/db`` (the PostgreSQL
  driver is the optional extra ``gait-tuner[postgres]``, psycopg 3; a plain ``postgresql://``
  is mapped to whichever of psycopg / psycopg2 is installed). Schema creation is serialised
  (a PostgreSQL advisory lock, a file lock for SQLite), since Optuna's ``create_all`` races
  when several processes meet a fresh database.

:class:`StudyStore` also gives the *budget lock*: the critical section in which a worker
reaps dead trials, counts the study's trials and asks for a new one, so that any number of
processes on any number of machines run exactly the study's budget (``pg_advisory_lock`` on
PostgreSQL, ``flock`` on the journal and SQLite).

Liveness. Every trial records its worker (host, pid, process start time). A RUNNING trial
is dead when its worker is on this host and that process is gone, or when its heartbeat is
older than ``grace_s``: on a database Optuna's heartbeat table (``record_heartbeat``), on the
journal a file per worker under ``runs/<study>.heartbeats/`` touched every ``interval_s``.
A dead trial is failed and enqueued again once with the same parameters and user
attributes (so a CasADi seed that died is still evaluated); a retry that dies is not retried.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import socket
import sys
import threading
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import optuna
from optuna.storages import JournalStorage
from optuna.storages.journal import JournalFileBackend
from optuna.storages.journal._file import BaseJournalFileLock  # the lock interface JournalFileBackend takes
from optuna.trial import TrialState

from ..errors import UserError

__all__ = ["FlockLock", "SafeJournalBackend", "StorageFull", "StudyStore", "repair_journal",
           "normalise_url", "process_identity", "HEARTBEAT_INTERVAL_S", "HEARTBEAT_GRACE_S"]

HEARTBEAT_INTERVAL_S = 10.0     # [s] how often a worker proves it is alive
HEARTBEAT_GRACE_S = 60.0        # [s] a trial whose heartbeat is older is dead (other hosts)
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


def normalise_url(url: str) -> str:
    """Check a storage URL and pick an installed driver; one-line :class:`UserError` otherwise."""
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    if not url.strip():
        raise UserError("--storage: empty URL (give sqlite:///FILE.db or postgresql://USER@HOST/DB, "
                        "or leave it out for the journal file)")
    try:
        u = make_url(url)
    except (ArgumentError, ValueError) as exc:
        raise UserError(f"--storage {url!r}: not a database URL ({exc}); expected "
                        f"sqlite:///FILE.db or postgresql://USER@HOST[:PORT]/DB") from None
    backend, _, driver = u.drivername.partition("+")
    if backend == "sqlite":
        if driver:
            raise UserError(f"--storage {url!r}: use plain sqlite:///FILE.db")
        db = u.database or ""
        if db in ("", ":memory:"):
            raise UserError(f"--storage {url!r}: an in-memory database loses the study when the "
                            f"process ends; give a file, sqlite:///FILE.db")
        folder = Path(db).expanduser().resolve().parent
        if not folder.is_dir():
            raise UserError(f"--storage {url!r}: folder {folder} does not exist")
        if Path(db).is_dir():
            raise UserError(f"--storage {url!r}: {db} is a directory, not a database file")
        if not os.access(folder, os.W_OK):
            raise UserError(f"--storage {url!r}: folder {folder} is not writable")
        return url
    if backend in ("postgresql", "postgres"):
        wanted = {"": ("psycopg", "psycopg2"), "psycopg": ("psycopg",),
                  "psycopg2": ("psycopg2",)}.get(driver)
        if wanted is None:
            raise UserError(f"--storage {url!r}: driver {driver!r} is not supported; use "
                            f"postgresql:// (psycopg 3) or postgresql+psycopg2://")
        import importlib.util
        for mod in wanted:
            if importlib.util.find_spec(mod) is not None:
                return u.set(drivername=f"postgresql+{mod}").render_as_string(hide_password=False)
        raise UserError(f"--storage {url!r}: no PostgreSQL driver installed; install it with "
                        f"pip install 'gait-tuner[postgres]' (psycopg 3)")
    if backend == "mysql":
        return url
    raise UserError(f"--storage {url!r}: unsupported database {backend!r}; use sqlite:///FILE.db "
                    f"or postgresql://USER@HOST[:PORT]/DB (or no --storage for the journal file)")


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


def _alive_here(ident: dict[str, Any]) -> bool | None:
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


@dataclass
class StudyStore:
    """A study's storage, opened the same way in the parent and in every worker.

    ``journal`` is the absolute journal path, or None when ``url`` is a database URL.
    """

    journal: Path | None = None
    url: str | None = None
    grace_s: float = HEARTBEAT_GRACE_S
    interval_s: float = HEARTBEAT_INTERVAL_S
    _storage: Any = field(default=None, repr=False)
    _engine: Any = field(default=None, repr=False)

    @classmethod
    def open(cls, name: str, storage: str | None, runs_dir: Path) -> "StudyStore":
        """The journal ``runs_dir/<name>.journal`` unless ``storage`` is a URL."""
        if storage is not None:
            return cls(url=normalise_url(storage))
        runs = Path(runs_dir)
        if runs.exists() and not runs.is_dir():
            raise UserError(f"--runs {runs}: not a folder")
        try:
            runs.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UserError(f"--runs {runs}: cannot create it ({exc.strerror})") from None
        if not os.access(runs, os.W_OK | os.X_OK):
            raise UserError(f"--runs {runs}: folder is not writable")
        path = (runs / f"{name}.journal").resolve()
        if path.is_dir():
            raise UserError(f"journal {path} is a directory")
        return cls(journal=path)

    @property
    def where(self) -> str:
        if self.journal is not None:
            return str(self.journal)
        from sqlalchemy.engine import make_url
        return make_url(self.url).render_as_string(hide_password=True)

    @property
    def kind(self) -> str:
        if self.journal is not None:
            return "journal"
        return self.url.split(":", 1)[0].split("+", 1)[0]

    # -- opening -------------------------------------------------------------------------------

    def optuna_storage(self) -> Any:
        """The Optuna storage object (opened once per process)."""
        if self._storage is not None:
            return self._storage
        if self.journal is not None:
            try:
                repair_journal(self.journal)
                self._storage = JournalStorage(SafeJournalBackend(self.journal))
            except (ValueError, json.JSONDecodeError) as exc:
                raise UserError(f"journal {self.journal} is corrupt ({exc}); it is not a journal "
                                f"written by gait-tuner, or was edited") from None
            except UnicodeDecodeError:
                raise UserError(f"journal {self.journal} is not a journal (binary content)") from None
            except OSError as exc:
                if exc.errno in DISK_FULL:
                    raise StorageFull(f"disk full opening {self.journal}") from None
                raise UserError(f"journal {self.journal}: {exc.strerror}") from None
            return self._storage
        from optuna.storages import RDBStorage
        from sqlalchemy.exc import SQLAlchemyError
        last: Exception | None = None
        for attempt in range(6):
            try:
                with self._schema_lock(), warnings.catch_warnings():
                    warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                    self._storage = RDBStorage(self.url, heartbeat_interval=int(self.interval_s),
                                               grace_period=int(self.grace_s),
                                               engine_kwargs=self._engine_kwargs())
                return self._storage
            except UserError:
                raise
            except (SQLAlchemyError, OSError) as exc:
                last = exc
                time.sleep(0.2 * (attempt + 1))
        msg = str(getattr(last, "orig", None) or last).strip().splitlines()[0] if last else "?"
        raise UserError(f"--storage {self.where}: cannot open the database ({msg})")

    def _engine_kwargs(self) -> dict[str, Any]:
        if self.kind == "postgresql":
            return {"pool_pre_ping": True, "connect_args": {"connect_timeout": 10}}
        if self.kind == "sqlite":
            return {"connect_args": {"timeout": 60}}
        return {}

    def _sa_engine(self) -> Any:
        if self._engine is None:
            import sqlalchemy
            self._engine = sqlalchemy.create_engine(self.url, poolclass=sqlalchemy.pool.NullPool,
                                                    **self._engine_kwargs())
        return self._engine

    @contextlib.contextmanager
    def _pg_lock(self, key: str) -> Iterator[None]:
        import sqlalchemy
        from sqlalchemy.exc import OperationalError
        k = int.from_bytes(hashlib.sha1(key.encode()).digest()[:8], "big", signed=True)
        try:
            conn = self._sa_engine().connect()
        except OperationalError as exc:
            msg = str(exc.orig).strip().splitlines()[0] if exc.orig else str(exc)
            raise UserError(f"--storage {self.where}: cannot connect ({msg})") from None
        try:
            conn.execute(sqlalchemy.text("SELECT pg_advisory_lock(:k)"), {"k": k})
            yield
        finally:
            with contextlib.suppress(Exception):
                conn.execute(sqlalchemy.text("SELECT pg_advisory_unlock(:k)"), {"k": k})
            conn.close()

    @contextlib.contextmanager
    def _lock(self, key: str) -> Iterator[None]:
        if self.kind == "postgresql":
            with self._pg_lock(key):
                yield
            return
        if self.journal is not None:
            base = Path(f"{self.journal}.{key}")
        elif self.kind == "sqlite":
            from sqlalchemy.engine import make_url
            base = Path(f"{Path(make_url(self.url).database).resolve()}.{key}")
        else:               # other databases: no cross-process lock (documented)
            yield
            return
        with FlockLock(base, suffix=".lock"):
            yield

    def _schema_lock(self) -> contextlib.AbstractContextManager:
        return self._lock("gait-tuner-schema")

    def budget_lock(self, study_name: str) -> contextlib.AbstractContextManager:
        """Held while a worker reaps dead trials, counts and asks: exact budgets across processes."""
        return self._lock(f"budget-{study_name}" if self.journal is None else "budget")

    # -- liveness ------------------------------------------------------------------------------

    def heartbeat_dir(self, study_name: str) -> Path | None:
        return None if self.journal is None else self.journal.with_name(f"{study_name}.heartbeats")

    def beat(self, study_name: str, trial_id: int | None) -> None:
        """Record that this process is alive (and, on a database, that its trial is)."""
        folder = self.heartbeat_dir(study_name)
        if folder is not None:
            folder.mkdir(exist_ok=True)
            (folder / _worker_file()).touch()
        elif trial_id is not None:
            storage = self.optuna_storage()
            if getattr(storage, "is_heartbeat_enabled", lambda: False)():
                storage.record_heartbeat(trial_id)

    def dead_trials(self, study: optuna.Study) -> list[optuna.trial.FrozenTrial]:
        """RUNNING trials whose worker is gone (see the module docstring); under the budget lock."""
        running = study.get_trials(deepcopy=False, states=(TrialState.RUNNING,))
        if not running:
            return []
        stale_db: set[int] = set()
        storage = study._storage
        if self.journal is None:
            base = getattr(storage, "_backend", storage)
            if getattr(base, "is_heartbeat_enabled", lambda: False)():
                stale_db = set(base._get_stale_trial_ids(study._study_id))
        now = time.time()
        dead = []
        for t in running:
            ident = t.user_attrs.get("worker") or {}
            if not ident:
                # a worker asks and records itself in one hold of the budget lock, which the
                # caller holds now: a trial without its worker was asked by a process that
                # died inside that section
                dead.append(t)
                continue
            here = _alive_here(ident)
            if here is False:
                dead.append(t)
                continue
            if here is True:
                continue
            if t._trial_id in stale_db:
                dead.append(t)
            elif self.journal is not None and ident:
                beat = self.heartbeat_dir(study.study_name) / _worker_file(ident)
                try:
                    age = now - beat.stat().st_mtime
                except OSError:
                    age = now - (t.datetime_start.timestamp() if t.datetime_start else now)
                if age > self.grace_s:
                    dead.append(t)
        return dead

    def reap(self, study: optuna.Study) -> list[str]:
        """Fail the study's dead trials and enqueue each once more; call under the budget lock."""
        notes = []
        for t in self.dead_trials(study):
            try:
                study._storage.set_trial_user_attr(t._trial_id, "failed", "its worker died")
                study._storage.set_trial_state_values(t._trial_id, TrialState.FAIL)
            except (RuntimeError, optuna.exceptions.UpdateFinishedTrialError):
                continue          # finished meanwhile
            if t.user_attrs.get("retry_of") is not None:
                notes.append(f"trial {t.number} died again (a retry of trial "
                             f"{t.user_attrs['retry_of']}): not retried")
                continue
            attrs = {k: v for k, v in t.user_attrs.items() if k not in ("worker", "result", "params")}
            attrs["retry_of"] = t.number
            study.enqueue_trial(dict(t.params), user_attrs=attrs, skip_if_exists=False)
            notes.append(f"trial {t.number} died with its worker: failed, enqueued again")
        return notes


def _worker_file(ident: dict[str, Any] | None = None) -> str:
    ident = ident or process_identity()
    return f"{ident.get('host')}-{ident.get('pid')}"


class Heartbeat:
    """A daemon thread beating for this process every ``interval_s`` while it works a trial."""

    def __init__(self, store: StudyStore, study_name: str) -> None:
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
                (folder / _worker_file()).unlink()
