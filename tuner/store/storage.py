"""Where a study lives, and what keeps it whole: the one adapter between the tuner and Optuna storage.

Two kinds of storage:

* the default **journal file** ``runs/<study>.journal`` (no server; one machine, or a shared
  disk), with a kernel lock, writes rolled back on a full disk and torn lines cut
  (``journal.py``);
* a **database URL**: ``sqlite:///file.db`` or ``postgresql://user@host/db`` (the PostgreSQL
  driver is the optional extra ``gait-tuner[postgres]``, psycopg 3; a plain ``postgresql://``
  is mapped to whichever of psycopg / psycopg2 is installed). Schema creation is serialised
  (a PostgreSQL advisory lock, a file lock for SQLite), since Optuna's ``create_all`` races
  when several processes meet a fresh database.

:class:`StudyStore` also gives the *budget lock*: the critical section in which a worker
reaps dead trials, counts the study's trials and asks for a new one, so that any number of
processes on any number of machines run exactly the study's budget (``pg_advisory_lock`` on
PostgreSQL, ``flock`` on the journal and SQLite).

Liveness (``liveness.py``): a trial whose worker is gone is failed and, unless the worker crashed
by itself (a native fault or an abort, which its parent records), enqueued again with the same
parameters, at most :data:`MAX_RETRIES` times (:meth:`StudyStore.reap`); the heartbeat file of a
worker judged dead is removed.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import socket
import stat
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import optuna
from optuna.trial import TrialState

from gaits.files import make_folder

from ..errors import UserError
from . import optuna_compat as compat
from .journal import DISK_FULL, FlockLock, PackedJournalStorage, SafeJournalBackend, StorageFull, repair_journal
from .liveness import HEARTBEAT_GRACE_S, HEARTBEAT_INTERVAL_S, alive_here, worker_file

__all__ = ["StudyStore", "normalise_url", "CRASH_SIGNALS", "MAX_RETRIES", "storage_full", "full_disk_in_one_line", "disk_full"]

#: Signals by which a process crashes by itself (a fault in native code, an abort): the trial it
#: walked is left failed, not retried. Any other death (SIGKILL, SIGTERM, a lost machine: killed
#: from outside) is retried with the same parameters, at most MAX_RETRIES times (the OOM killer's
#: SIGKILL looks like one from outside, and a set that always exhausts memory must not loop).
CRASH_SIGNALS = frozenset({"SIGSEGV", "SIGBUS", "SIGFPE", "SIGILL", "SIGABRT"})
MAX_RETRIES = 3
WORKER_DIED = "its worker died"


_FULL_WORDS = ("database or disk is full", "disk full", "no space left on device", "could not extend file",
               "file too large", "disk quota exceeded", "disk i/o error")


def storage_full(exc: BaseException) -> str | None:
    """The reason, when ``exc`` (or what caused it) is the storage's disk refusing a write: an
    ``OSError`` of a full disk, SQLite's SQLITE_FULL, PostgreSQL's disk_full (SQLSTATE 53100) as
    SQLAlchemy raises them; else None. So that SQLite and PostgreSQL say it in one line, as the
    journal does."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, StorageFull):
            return str(exc)
        if isinstance(exc, OSError) and exc.errno in DISK_FULL:
            return os.strerror(exc.errno)
        orig = getattr(exc, "orig", None)
        if getattr(orig, "sqlstate", None) == "53100" or getattr(orig, "pgcode", None) == "53100":
            return "PostgreSQL: disk full"
        text = str(exc).lower()
        for words in _FULL_WORDS:
            if words in text and type(exc).__module__.split(".")[0] in ("sqlalchemy", "sqlite3", "psycopg",
                                                                         "psycopg2", "optuna"):
                return words
        exc = orig if orig is not None else (exc.__cause__ or exc.__context__)
    return None


@contextlib.contextmanager
def full_disk_in_one_line(where: str) -> Iterator[None]:
    """A full disk met writing the storage ``where`` in the block (opening, enqueueing, reaping) raised
    as one :class:`StorageFull` line that says how to resume; a user's error, an interruption and
    anything else go through unchanged."""
    try:
        yield
    except (UserError, KeyboardInterrupt, SystemExit):
        raise
    except Exception as exc:  # noqa: BLE001
        full = storage_full(exc)
        if full is None:
            raise
        raise disk_full(where, full) from None


def disk_full(where: str, reason: str) -> StorageFull:
    """The one line a full disk under the study's storage ``where`` is said in (``reason``: what
    :func:`storage_full` found), with how to resume."""
    return StorageFull(f"disk full writing the study's storage {where} ({reason}); free space and run the "
                       f"same command to resume")


def _retries(t: optuna.trial.FrozenTrial) -> int:
    """How many times ``t``'s parameters were retried before it (a retry from before the count
    was kept counts once)."""
    return int(t.user_attrs.get("retries", 1 if t.user_attrs.get("retry_of") is not None else 0))


def _planned_params(t: optuna.trial.FrozenTrial) -> dict:
    """What a trial was to walk: its stored parameters, or, when its worker died between popping it
    and storing them, the ones it was enqueued with (a start, a retry, the CasADi seed)."""
    return dict(t.params) or compat.enqueued_params(t)


def _not_retried(t: optuna.trial.FrozenTrial) -> str | None:
    """Why a trial whose worker died is not retried, or None: it had no parameters yet (a sampled
    trial whose worker died between reserving it and sampling; an enqueued one has its enqueued
    parameters), its worker crashed by itself, or its parameters have died :data:`MAX_RETRIES`
    times."""
    if not _planned_params(t):   # reserved under the lock, its worker died before it sampled: nothing walked
        return (f"trial {t.number}'s worker died before it drew the trial's parameters: failed, "
                f"nothing to walk again")
    how = t.user_attrs.get("died")
    if how in CRASH_SIGNALS:
        return f"trial {t.number} crashed its worker ({how}): failed, not retried"
    if _retries(t) >= MAX_RETRIES:
        return (f"trial {t.number}'s worker died {_retries(t) + 1} times with these parameters "
                f"(first as trial {t.user_attrs.get('retry_of')}): failed, not retried")
    return None


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










def advisory_key(name: str) -> int:
    """The PostgreSQL advisory-lock key of a named lock (``StudyStore._pg_lock``): 64 bits of its SHA-1."""
    return int.from_bytes(hashlib.sha1(name.encode()).digest()[:8], "big", signed=True)


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
            make_folder(runs)
        except OSError as exc:
            raise UserError(f"--runs {runs}: cannot create it: {exc.strerror}") from None
        if not os.access(runs, os.W_OK | os.X_OK):
            raise UserError(f"--runs {runs}: folder is not writable")
        link = runs / f"{name}.journal"
        try:
            path = link.resolve()
        except (RuntimeError, OSError):
            raise UserError(f"journal {link}: a loop of symbolic links, expected a journal file") from None
        if os.path.lexists(path):
            mode = os.stat(path).st_mode if path.exists() else 0
            if stat.S_ISDIR(mode):
                raise UserError(f"journal {path} is a directory")
            if not stat.S_ISREG(mode):
                kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a device"
                        if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")
                raise UserError(f"journal {path} is {kind}, expected a journal file")
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
                self._storage = PackedJournalStorage(SafeJournalBackend(self.journal))
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
        from sqlalchemy.exc import SQLAlchemyError

        from .rdb import LeanRDBStorage
        last: Exception | None = None
        for attempt in range(6):
            try:
                with self._schema_lock(), warnings.catch_warnings():
                    warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                    self._storage = LeanRDBStorage(self.url, heartbeat_interval=int(self.interval_s),
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
        """This process's engine for the advisory locks. Its connections are kept between locks
        (a new connection per lock cost ~2 ms, most of a trial's time under the budget lock);
        without a ping per checkout (a dead kept connection fails the lock's statement, which
        :meth:`_pg_lock` retries once on a fresh one). A forked child makes its own: the
        parent's sockets are never used from two processes."""
        if self._engine is None or self._engine[0] != os.getpid():
            import sqlalchemy
            kwargs = {k: v for k, v in self._engine_kwargs().items() if k != "pool_pre_ping"}
            # autocommit: the lock and the unlock are one round trip each, no BEGIN or COMMIT
            # (an advisory lock is the session's, not a transaction's)
            self._engine = (os.getpid(), sqlalchemy.create_engine(self.url, pool_size=2, isolation_level="AUTOCOMMIT",
                                                                  **kwargs))
        return self._engine[1]

    @contextlib.contextmanager
    def _pg_lock(self, key: str) -> Iterator[None]:
        import sqlalchemy
        from sqlalchemy.exc import DBAPIError, OperationalError
        k = advisory_key(key)
        for attempt in (0, 1):
            try:
                conn = self._sa_engine().connect()
            except OperationalError as exc:
                msg = str(exc.orig).strip().splitlines()[0] if exc.orig else str(exc)
                raise UserError(f"--storage {self.where}: cannot connect ({msg})") from None
            try:
                conn.execute(sqlalchemy.text("SELECT pg_advisory_lock(:k)"), {"k": k})
                break
            except DBAPIError:
                conn.invalidate()                # a kept connection the server closed: a fresh one
                conn.close()
                if attempt:
                    raise
        try:
            yield
        finally:
            try:
                conn.execute(sqlalchemy.text("SELECT pg_advisory_unlock(:k)"), {"k": k})
            except Exception:  # noqa: BLE001 - the lock must not outlive this block: close its session
                with contextlib.suppress(Exception):
                    conn.invalidate()
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
            (folder / worker_file()).touch()
        elif trial_id is not None:
            storage = self.optuna_storage()
            if getattr(storage, "is_heartbeat_enabled", lambda: False)():
                storage.record_heartbeat(trial_id)

    def dead_trials(self, study: optuna.Study, running: list | None = None) -> list[optuna.trial.FrozenTrial]:
        """RUNNING trials whose worker is gone (see the module docstring); under the budget lock."""
        if running is None:
            running = study.get_trials(deepcopy=False, states=(TrialState.RUNNING,))
        if not running:
            return []
        stale_db: set[int] = set()
        storage = compat.study_storage(study)
        if self.journal is None:
            base = compat.cached_backend(storage)
            if getattr(base, "is_heartbeat_enabled", lambda: False)():
                stale_db = set(compat.stale_trial_ids(base, compat.study_id(study)))
        now = time.time()
        dead = []
        for t in running:
            ident = t.user_attrs.get("worker") or {}
            if not ident:
                # read again now: ``running`` may have been read outside the lock, between the
                # two journal records that pop a waiting trial (its state, then its worker; a
                # database pops it in one write, LeanRDBStorage.claim), or by a foreign client
                t = storage.get_trial(compat.trial_id(t))
                if t.state != TrialState.RUNNING:
                    continue
                ident = t.user_attrs.get("worker") or {}
            if not ident:
                # a worker asks and records itself in one hold of the budget lock, which the
                # caller holds now: a trial without its worker was asked by a process that
                # died inside that section
                dead.append(t)
                continue
            here = alive_here(ident)
            if here is False:
                dead.append(t)
                continue
            if here is True:
                continue
            if compat.trial_id(t) in stale_db:
                dead.append(t)
            elif self.journal is not None and ident:
                beat = self.heartbeat_dir(study.study_name) / worker_file(ident)
                try:
                    age = now - beat.stat().st_mtime
                except OSError:
                    age = now - (t.datetime_start.timestamp() if t.datetime_start else now)
                if age > self.grace_s:
                    dead.append(t)
        return dead

    def mark_death(self, study: optuna.Study, pid: int, how: str) -> None:
        """Record on the running trial of this host's worker ``pid`` how it died (a signal's
        name), so that :meth:`reap` tells a crash from a kill; call under the budget lock."""
        host, storage = socket.gethostname(), compat.study_storage(study)
        for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
            ident = t.user_attrs.get("worker") or {}
            if ident.get("host") == host and int(ident.get("pid", -1)) == pid:
                with contextlib.suppress(RuntimeError, optuna.exceptions.UpdateFinishedTrialError):
                    storage.set_trial_user_attr(compat.trial_id(t), "died", how)

    def reap(self, study: optuna.Study, running: list | None = None, failed: list | None = None) -> list[str]:
        """Fail the study's dead trials; enqueue a retry of every trial failed so (now, or at an
        earlier open whose retry could not be stored: a full disk) unless its worker crashed by
        itself or the parameters have died :data:`MAX_RETRIES` times; remove dead workers'
        heartbeat files. Call under the budget lock. ``running`` and ``failed``: the study's
        RUNNING and FAIL trials when the caller knows them (a worker's :class:`TrialIndex`),
        so that nothing here reads the whole study."""
        notes, storage = [], compat.study_storage(study)
        for t in self.dead_trials(study, running):
            why = _not_retried(t)
            try:
                if why:
                    storage.set_trial_user_attr(compat.trial_id(t), "not_retried", why)
                storage.set_trial_user_attr(compat.trial_id(t), "failed", WORKER_DIED)
                storage.set_trial_state_values(compat.trial_id(t), TrialState.FAIL)
            except (RuntimeError, optuna.exceptions.UpdateFinishedTrialError):
                continue          # finished meanwhile
            if why:
                notes.append(why)
            if failed is not None:
                failed = [*failed, storage.get_trial(compat.trial_id(t))]
            self._forget_worker(study.study_name, t.user_attrs.get("worker"))
        notes += self._enqueue_retries(study, failed)
        self._sweep_heartbeats(study.study_name)
        return notes

    def _enqueue_retries(self, study: optuna.Study, failed: list | None = None) -> list[str]:
        """Enqueue a retry of each failed trial whose worker died and that has none yet. The
        study's ``retried`` attribute lists the trials retried already, so that this reads the
        failed trials only, not the whole study; a study from before that attribute is scanned
        once for its retries' ``retry_for`` and the attribute written."""
        notes = []
        if failed is None:
            failed = study.get_trials(deepcopy=False, states=(TrialState.FAIL,))
        died = [t for t in failed
                if t.user_attrs.get("failed") == WORKER_DIED and not t.user_attrs.get("not_retried")]
        if not died:
            return notes                    # the common case: no read of the study's attributes
        done = set(study.user_attrs.get("retried", ()))
        todo = [t for t in died if t.number not in done]
        if not todo:
            return notes
        older = {t.user_attrs.get("retry_for", t.user_attrs.get("retry_of"))
                 for t in study.get_trials(deepcopy=False) if t.number > min(u.number for u in todo)}
        for t in todo:
            a = t.user_attrs
            done.add(t.number)
            if t.number in older:
                continue
            how = a.get("died")
            attrs = {k: v for k, v in a.items() if k not in ("worker", "result", "params", "died", "failed")}
            attrs.update(retry_of=a.get("retry_of", t.number), retry_for=t.number, retries=_retries(t) + 1)
            study.enqueue_trial(_planned_params(t), user_attrs=attrs, skip_if_exists=False)
            notes.append(f"trial {t.number} died with its worker{f' ({how})' if how else ''}: "
                         f"failed, enqueued again")
        study.set_user_attr("retried", sorted(done))
        return notes

    def _forget_worker(self, study_name: str, ident: dict[str, Any] | None) -> None:
        folder = self.heartbeat_dir(study_name)
        if folder is not None and ident:
            with contextlib.suppress(OSError):
                (folder / worker_file(ident)).unlink()

    def _sweep_heartbeats(self, study_name: str) -> None:
        """Remove heartbeat files not touched for the grace time (their worker is dead)."""
        folder = self.heartbeat_dir(study_name)
        if folder is None:
            return
        now = time.time()
        with contextlib.suppress(OSError):
            for beat in folder.iterdir():
                with contextlib.suppress(OSError):
                    if now - beat.stat().st_mtime > self.grace_s:
                        beat.unlink()




