"""Optuna's RDB storage with a worker's hot path in few statements (PostgreSQL, SQLite).

Optuna's :class:`~optuna.storages.RDBStorage` runs every call through its ORM, one transaction
each: a trial of eight parameters made ~22 commits and ~75 statements through the worker loop,
~1.2 ms for each parameter and ~2.7 ms to read one running trial, so the search overhead of a
trial on PostgreSQL was 50-90 ms where the journal's is a few (``benchmarks/bench_scale.py``).
Ours: a subclass that keeps Optuna's schema, its cache (``_CachedStorage`` still wraps it) and
every other method, and changes only the calls a worker makes for every trial:

* **deferred writes** (:meth:`LeanRDBStorage.defer`): a worker's own running trial buffers its
  parameters and attributes in memory; :meth:`LeanRDBStorage.flush` writes them (the worker
  flushes after sampling, so that other workers see the parameters for their constant liar and
  duplicate check), and ``set_trial_state_values`` (``tell``) writes the rest together with the
  values and the state. On PostgreSQL each is one statement: a guard (the trial locked while it
  runs, or its state changed from RUNNING) and the inserts selected from it, so that nothing is
  written to a trial another process has ended; on SQLite one transaction. A reader in this
  process sees the buffered writes; a worker that dies loses only what was not flushed (its
  trial is failed by the reaper and retried from its flushed parameters, as before);
* **reads** of trials (``_get_trials``, which Optuna's cache calls for the new and unfinished
  trials, ``get_trial``, and :meth:`LeanRDBStorage.read_trials`, which a worker's index uses to
  read around Optuna's cache so that a worker does not hold the whole study) in two statements
  (the trials, then their rows of every table as one UNION ALL) through SQLAlchemy Core on
  Optuna's own tables (``optuna.storages._rdb.models``), in autocommit, building the same
  :class:`~optuna.trial.FrozenTrial` as Optuna's ``_build_frozen_trial_from_trial_model``;
  :meth:`LeanRDBStorage.trial_states`, the states the budget lock needs, in one;
* **creating** a running trial (optionally with its attributes, e.g. the worker's identity, in
  the same transaction): Optuna's steps (lock the study row, insert, number = the study's
  earlier trials, counted from the last trial this process saw) in Core.

Everything else (studies, enqueueing, heartbeats, schema versions) is Optuna's code. The
distribution check of a parameter against the study's earlier ones is Optuna's too: the first
parameter of each name in a process goes through Optuna's own ``_set_trial_param``, which finds
the study's distribution; later ones are checked against the distribution Optuna's cache holds.
Written against Optuna's schema of ``optuna<6`` (pinned); tests in ``tests/test_rdb.py`` compare
every method with Optuna's own on the same database.
"""

from __future__ import annotations

import copy
import datetime
import json
import threading
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Callable, Iterable, Sequence

from optuna import distributions
from optuna.exceptions import UpdateFinishedTrialError
from optuna.storages import RDBStorage
from optuna.trial import FrozenTrial, TrialState

from . import optuna_compat as compat

__all__ = ["LeanRDBStorage", "lean"]


@lru_cache(maxsize=256)
def _distribution(text: str) -> distributions.BaseDistribution:
    return distributions.json_to_distribution(text)


def _utc_naive(t: datetime.datetime) -> datetime.datetime:
    """How Optuna's schema stores a datetime (``TrialModel``: naive UTC)."""
    return t.astimezone(datetime.timezone.utc).replace(tzinfo=None)


def _local_naive(t: datetime.datetime | None) -> datetime.datetime | None:
    """How Optuna's ``TrialModel`` hands a stored datetime back (naive local time)."""
    if t is None:
        return None
    return t.replace(tzinfo=datetime.timezone.utc).astimezone().replace(tzinfo=None)


@dataclass
class _Pending:
    """A deferred trial's writes not yet in the database."""

    params: dict[str, tuple[float, distributions.BaseDistribution]] = field(default_factory=dict)
    user_attrs: dict[str, Any] = field(default_factory=dict)
    system_attrs: dict[str, Any] = field(default_factory=dict)

    def empty(self) -> bool:
        return not (self.params or self.user_attrs or self.system_attrs)


class LeanRDBStorage(RDBStorage):
    """:class:`~optuna.storages.RDBStorage` with the worker's hot path in Core (module docstring)."""

    #: at most this many trials this process ended are kept until its next :meth:`read_trials`
    #: (a process that does not call it keeps no more; beyond it, its trials are read back)
    ENDED_KEPT = 64

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._pending: dict[int, _Pending] = {}
        self._own: dict[int, FrozenTrial] = {}          # a deferred trial as this process wrote it
        self._recent: dict[int, FrozenTrial] = {}       # the trial this process created or ended last
        self._ended: dict[int, FrozenTrial] = {}        # trials this process ended, not yet read back
        self._anchor: dict[int, tuple[int, int]] = {}   # study id -> (trial id, number) seen last
        self._pending_lock = threading.Lock()

    def __getstate__(self) -> dict[Any, Any]:
        state = super().__getstate__()
        for key in ("_pending_lock", "_autocommit", "_statements"):
            state.pop(key, None)
        state.update(_pending={}, _own={}, _recent={}, _ended={}, _anchor={})
        return state

    def __setstate__(self, state: dict[Any, Any]) -> None:
        super().__setstate__(state)
        self._pending, self._own, self._recent, self._ended, self._anchor = {}, {}, {}, {}, {}
        self._pending_lock = threading.Lock()

    # -- tables ------------------------------------------------------------------------------

    @staticmethod
    def _models() -> Any:
        return compat.rdb_models()

    def _statement(self, key: Any, build: Callable[[], Any]) -> Any:
        """The statement ``build`` makes, built once per ``key`` (its values bound at each call),
        so that SQLAlchemy compiles it once and a hot call costs its round trip only."""
        cache = self.__dict__.setdefault("_statements", {})
        stmt = cache.get(key)
        if stmt is None:
            stmt = cache[key] = build()
        return stmt

    def _rows_cte(self, source: Any, model: Any, cols: Sequence[str], n: int, tag: str,
                  keys: Sequence[str] = (), update: Sequence[str] = ()) -> Any:
        """PostgreSQL: an INSERT into ``model``'s table, as a CTE, of ``n`` rows selected from
        ``source`` (a CTE whose ``trial_id`` names the trial; none if it returns no row), each
        row's ``cols`` bound as ``{tag}_{col}_{i}`` (:meth:`_rows_args`); on a clash of ``keys``,
        ``update`` overwritten (none: the row left as it is)."""
        import sqlalchemy as sa
        from sqlalchemy.dialects.postgresql import insert
        table = model.__table__
        rows = sa.union_all(*(sa.select(source.c.trial_id.label("trial_id"), *(
            sa.cast(sa.bindparam(f"{tag}_{c}_{i}", type_=table.c[c].type), table.c[c].type).label(c)
            for c in cols)) for i in range(n)))
        ins = insert(table).from_select(["trial_id", *cols], rows)
        if keys:
            index = [table.c[k] for k in keys]
            ins = (ins.on_conflict_do_update(index_elements=index, set_={c: ins.excluded[c] for c in update})
                   if update else ins.on_conflict_do_nothing(index_elements=index))
        return ins.cte(f"w_{tag}")

    @staticmethod
    def _rows_args(tag: str, rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
        """The bound values of :meth:`_rows_cte`'s rows."""
        return {f"{tag}_{c}_{i}": v for i, row in enumerate(rows) for c, v in row.items()}

    @staticmethod
    def _attr_rows(attrs: dict[str, Any]) -> list[dict[str, Any]]:
        """Attribute rows as Optuna stores them (the value as JSON)."""
        return [{"key": k, "value_json": json.dumps(v)} for k, v in attrs.items()]

    def _upsert(self, model: Any, keys: Sequence[str], update: Sequence[str]) -> Any:
        """An INSERT that overwrites ``update`` on a clash of ``keys`` (none: leaves the row as it
        is), run with a list of rows (PostgreSQL and SQLite: ``ON CONFLICT``, as Optuna's own
        attribute writes on these databases); one statement object per table, so SQLAlchemy
        compiles it once."""
        def build() -> Any:
            table = model.__table__
            if self.engine.name == "postgresql":
                from sqlalchemy.dialects.postgresql import insert
            else:
                from sqlalchemy.dialects.sqlite import insert
            stmt = insert(table)
            index = [table.c[k] for k in keys]
            return (stmt.on_conflict_do_update(index_elements=index, set_={c: stmt.excluded[c] for c in update})
                    if update else stmt.on_conflict_do_nothing(index_elements=index))
        return self._statement((model.__tablename__, tuple(keys), tuple(update)), build)

    def _reader(self) -> Any:
        """The engine for reads: autocommit (no BEGIN and ROLLBACK round trips around a read;
        under PostgreSQL's default isolation, READ COMMITTED, each statement of a transaction
        takes its own snapshot anyway, so a read of two statements sees what it saw before)."""
        reader = self.__dict__.get("_autocommit")
        if reader is None or reader[0] is not self.engine:
            reader = self.__dict__["_autocommit"] = (self.engine, self.engine.execution_options(isolation_level="AUTOCOMMIT"))
        return reader[1]

    @property
    def _lean(self) -> bool:
        """Core paths only where the upsert dialect is known; other databases use Optuna's code."""
        return self.engine.name in ("postgresql", "sqlite")

    # -- reads -------------------------------------------------------------------------------

    def _read(self, conn: Any, where: Any, limit: int | None = None,
              known: dict[int, FrozenTrial] | None = None) -> list[FrozenTrial]:
        """Every trial of ``trials`` matching ``where`` (the first ``limit`` by id), with its rows,
        as FrozenTrials by id: two statements (the trials; their params, values, attributes and
        intermediate values as one UNION ALL, each row tagged with its table). A trial of
        ``known`` (this process's copies of trials it ended) found in the state its copy holds
        is taken from there, its rows not read; when every trial found is, one statement."""
        import sqlalchemy as sa
        m = self._models()
        t = m.TrialModel.__table__
        rows = conn.execute(sa.select(t.c.trial_id, t.c.number, t.c.state, t.c.datetime_start,
                                      t.c.datetime_complete).where(where).order_by(t.c.trial_id).limit(limit)).all()
        if not rows:
            return []
        mine: dict[int, FrozenTrial] = {}
        if known:
            for r in rows:
                k = known.get(r.trial_id)
                if k is not None and k.state == r.state and k.number == r.number:
                    mine[r.trial_id] = k
        if len(mine) == len(rows):
            return [mine[r.trial_id] for r in rows]
        ids = [r.trial_id for r in rows if r.trial_id not in mine]
        params: dict[int, list[tuple[int, str, float, str]]] = {i: [] for i in ids}
        values: dict[int, dict[int, float]] = {i: {} for i in ids}
        user: dict[int, dict[str, Any]] = {i: {} for i in ids}
        system: dict[int, dict[str, Any]] = {i: {} for i in ids}
        inter: dict[int, dict[int, float]] = {i: {} for i in ids}
        text, num = sa.String, sa.Float

        def part(tag: str, table: Any, pk: str, key: Any, number: Any, extra: Any) -> Any:
            return sa.select(sa.literal(tag).label("tag"), table.c.trial_id, table.c[pk].label("pk"),
                             sa.cast(key, text).label("k"), sa.cast(number, num).label("x"),
                             sa.cast(extra, text).label("e")).where(table.c.trial_id.in_(ids))
        tp, tv = m.TrialParamModel.__table__, m.TrialValueModel.__table__
        tu, ts = m.TrialUserAttributeModel.__table__, m.TrialSystemAttributeModel.__table__
        ti = m.TrialIntermediateValueModel.__table__
        union = sa.union_all(
            part("p", tp, "param_id", tp.c.param_name, tp.c.param_value, tp.c.distribution_json),
            part("v", tv, "trial_value_id", tv.c.objective, tv.c.value, tv.c.value_type),
            part("u", tu, "trial_user_attribute_id", tu.c.key, sa.null(), tu.c.value_json),
            part("s", ts, "trial_system_attribute_id", ts.c.key, sa.null(), ts.c.value_json),
            part("i", ti, "trial_intermediate_value_id", ti.c.step, ti.c.intermediate_value,
                 ti.c.intermediate_value_type)).subquery()
        value_type = m.TrialValueModel.TrialValueType
        inter_type = m.TrialIntermediateValueModel.TrialIntermediateValueType
        for r in conn.execute(sa.select(union).order_by(union.c.pk)):
            tid = r.trial_id
            if r.tag == "p":
                params[tid].append((r.pk, r.k, r.x, r.e))
            elif r.tag == "v":
                values[tid][int(r.k)] = m.TrialValueModel.stored_repr_to_value(r.x, value_type[r.e])
            elif r.tag == "u":
                user[tid][r.k] = json.loads(r.e)
            elif r.tag == "s":
                system[tid][r.k] = json.loads(r.e)
            else:
                inter[tid][int(r.k)] = m.TrialIntermediateValueModel.stored_repr_to_intermediate_value(
                    r.x, inter_type[r.e])
        out_trials = []
        for r in rows:
            if r.trial_id in mine:
                out_trials.append(mine[r.trial_id])
                continue
            ps = sorted(params[r.trial_id])
            vals = values[r.trial_id]
            out_trials.append(FrozenTrial(
                number=r.number, state=r.state, value=None,
                values=[vals[k] for k in range(len(vals))] if vals else None,
                datetime_start=_local_naive(r.datetime_start), datetime_complete=_local_naive(r.datetime_complete),
                params={name: _distribution(dj).to_external_repr(v) for _, name, v, dj in ps},
                distributions={name: _distribution(dj) for _, name, _v, dj in ps},
                user_attrs=user[r.trial_id], system_attrs=system[r.trial_id],
                intermediate_values=inter[r.trial_id], trial_id=r.trial_id))
        return out_trials

    def _get_trials(self, study_id: int, states: Any, included_trial_ids: set[int],
                    trial_id_greater_than: int) -> list[FrozenTrial]:
        if not self._lean:
            return super()._get_trials(study_id, states, included_trial_ids, trial_id_greater_than)
        import sqlalchemy as sa
        t = self._models().TrialModel.__table__
        included = [i for i in included_trial_ids if i <= trial_id_greater_than]
        where = t.c.study_id == study_id
        if states is not None:
            where = sa.and_(where, t.c.state.in_(list(states)))
        if included and trial_id_greater_than > -1:
            where = sa.and_(where, sa.or_(t.c.trial_id.in_(included), t.c.trial_id > trial_id_greater_than))
        elif trial_id_greater_than > -1:
            where = sa.and_(where, t.c.trial_id > trial_id_greater_than)
        with self._reader().connect() as conn:
            trials = self._read(conn, where)
            if not trials:
                self._study_exists(conn, study_id)
        return [self._merged(t) for t in trials]

    def read_trials(self, study_id: int, after_id: int, trial_ids: Iterable[int] = (),
                    limit: int | None = None) -> list[FrozenTrial]:
        """The study's trials with an id above ``after_id`` (the first ``limit`` of them, if
        given) and those of ``trial_ids``, read whole in two statements and not kept anywhere
        (Optuna's cache holds every trial it reads: a worker's index reads through this, so that
        its memory does not grow with the study). By id, not number: the primary key finds the
        newest trials without reading the study's older ones (there is no index on numbers)."""
        import sqlalchemy as sa
        t = self._models().TrialModel.__table__
        which = t.c.trial_id > after_id
        ids = sorted(set(trial_ids))
        if ids:
            which = sa.or_(which, t.c.trial_id.in_(ids))
        with self._pending_lock:
            known = self._ended
            self._ended = {}
        with self._reader().connect() as conn:
            trials = self._read(conn, sa.and_(t.c.study_id == study_id, which), limit, known)
        for x in trials:
            self._see(study_id, compat.trial_id(x), x.number)
        return [self._merged(x) for x in trials]

    def _study_exists(self, conn: Any, study_id: int) -> None:
        import sqlalchemy as sa
        s = self._models().StudyModel.__table__
        if conn.execute(sa.select(s.c.study_id).where(s.c.study_id == study_id)).first() is None:
            raise KeyError(f"No study with study_id {study_id} exists.")

    def get_trial(self, trial_id: int) -> FrozenTrial:
        if not self._lean:
            return super().get_trial(trial_id)
        with self._pending_lock:
            own = self._own.get(trial_id) or self._recent.get(trial_id)
            if own is not None:
                # a deferred trial: only this process writes it while it runs (a reaper that
                # fails it meanwhile is found by the write that ends it, as before)
                return copy.deepcopy(own)
        t = self._models().TrialModel.__table__
        with self._reader().connect() as conn:
            found = self._read(conn, t.c.trial_id == trial_id)
        if not found:
            raise KeyError(f"No trial with trial_id {trial_id} exists.")
        return self._merged(found[0])

    def get_study_user_attrs(self, study_id: int) -> dict[str, Any]:
        if not self._lean:
            return super().get_study_user_attrs(study_id)
        import sqlalchemy as sa
        a = self._models().StudyUserAttributeModel.__table__
        with self._reader().connect() as conn:
            rows = conn.execute(sa.select(a.c.key, a.c.value_json).where(a.c.study_id == study_id)
                                .order_by(a.c.study_user_attribute_id)).all()
            if not rows:
                self._study_exists(conn, study_id)
        return {r.key: json.loads(r.value_json) for r in rows}

    def trial_states(self, study_id: int, after_id: int, trial_ids: Iterable[int],
                     study_attr: str) -> tuple[list[tuple[int, int, TrialState]], Any]:
        """In one statement: ``(trial_id, number, state)`` of the study's trials with an id above
        ``after_id`` and of ``trial_ids``, and the study's user attribute ``study_attr``
        (None if unset). What a worker reads under the budget lock (``TrialIndex.recount``):
        its cost does not grow with the study."""
        import sqlalchemy as sa
        ids = sorted(set(trial_ids))

        def build() -> Any:
            m = self._models()
            t, a = m.TrialModel.__table__, m.StudyUserAttributeModel.__table__
            which = t.c.trial_id > sa.bindparam("after")
            if ids:
                which = sa.or_(which, t.c.trial_id.in_(sa.bindparam("ids", expanding=True)))
            trials = sa.select(t.c.trial_id, t.c.number, sa.cast(t.c.state, sa.String).label("e")).where(
                t.c.study_id == sa.bindparam("sid"), which)
            attr = sa.select(sa.cast(sa.null(), sa.Integer), sa.cast(sa.null(), sa.Integer), a.c.value_json).where(
                a.c.study_id == sa.bindparam("sid"), a.c.key == sa.bindparam("key"))
            return sa.union_all(trials, attr)
        stmt = self._statement(("states", bool(ids)), build)      # the lock's statement: its round trip only
        args = {"after": after_id, "sid": study_id, "key": study_attr, **({"ids": ids} if ids else {})}
        with self._reader().connect() as conn:
            rows = conn.execute(stmt, args).all()
        value, out = None, []
        for tid, number, e in rows:
            if tid is None:
                value = json.loads(e)
            else:
                out.append((tid, number, TrialState[e]))
                self._see(study_id, tid, number)
        return sorted(out, key=lambda r: r[1]), value

    def _get_stale_trial_ids(self, study_id: int) -> list[int]:
        """Optuna's reading (a running trial whose heartbeat is older than the grace period, by
        the database's clock) in one statement."""
        if not self._lean:
            return super()._get_stale_trial_ids(study_id)
        import sqlalchemy as sa
        m = self._models()
        t, h = m.TrialModel.__table__, m.TrialHeartbeatModel.__table__
        grace = self.grace_period if self.grace_period is not None else 2 * self.heartbeat_interval
        with self._reader().connect() as conn:
            rows = conn.execute(sa.select(t.c.trial_id, h.c.heartbeat, sa.func.now().label("now"))
                                .join(h, h.c.trial_id == t.c.trial_id)
                                .where(t.c.study_id == study_id, t.c.state == TrialState.RUNNING)).all()
        return [r.trial_id for r in rows
                if r.now.replace(tzinfo=None) - r.heartbeat.replace(tzinfo=None) > datetime.timedelta(seconds=grace)]

    def get_trial_id_from_study_id_trial_number(self, study_id: int, trial_number: int) -> int:
        if not self._lean:
            return super().get_trial_id_from_study_id_trial_number(study_id, trial_number)
        import sqlalchemy as sa
        t = self._models().TrialModel.__table__
        with self._reader().connect() as conn:
            row = conn.execute(sa.select(t.c.trial_id).where(t.c.number == trial_number,
                                                             t.c.study_id == study_id)).first()
        if row is None:
            raise KeyError(f"No trial with trial number {trial_number} exists in study with study_id {study_id}.")
        return row[0]

    def _merged(self, trial: FrozenTrial) -> FrozenTrial:
        """``trial`` as this process sees it: with its deferred writes."""
        with self._pending_lock:
            p = self._pending.get(compat.trial_id(trial))
            if p is None or p.empty():
                return trial
            for name, (value, dist) in p.params.items():
                if name not in trial.params:
                    trial.params[name] = dist.to_external_repr(value)
                    trial.distributions[name] = dist
            trial.user_attrs.update(p.user_attrs)
            trial.system_attrs.update(p.system_attrs)
        return trial

    # -- creating ----------------------------------------------------------------------------

    def _create_new_trial(self, study_id: int, template_trial: FrozenTrial | None = None) -> FrozenTrial:
        simple = template_trial is None or (
            template_trial.state == TrialState.RUNNING and not template_trial.params
            and template_trial.values is None and not template_trial.intermediate_values)
        if not (self._lean and simple):
            return super()._create_new_trial(study_id, template_trial)
        import sqlalchemy as sa
        m = self._models()
        t, s = m.TrialModel.__table__, m.StudyModel.__table__
        start = datetime.datetime.now()
        user = dict(template_trial.user_attrs) if template_trial else {}
        system = dict(template_trial.system_attrs) if template_trial else {}
        with self.engine.begin() as conn:
            # Optuna's own order (``_create_new_trial``): the study's row locked, so that the
            # number, the count of the study's earlier trials, is not raced by another creator
            lock = self._statement("lock_study", lambda: sa.select(s.c.study_id)
                                   .where(s.c.study_id == sa.bindparam("sid")).with_for_update())
            if conn.execute(lock, {"sid": study_id}).first() is None:
                raise KeyError(f"No study with study_id {study_id} exists.")
            if self.engine.name == "postgresql":
                tid, number = self._insert_running_pg(conn, study_id, _utc_naive(start), user, system)
            else:
                tid = conn.execute(sa.insert(t).values(study_id=study_id, number=None, state=TrialState.RUNNING,
                                                       datetime_start=_utc_naive(start))
                                   .returning(t.c.trial_id)).scalar_one()
                earlier = sa.select(sa.func.count(t.c.trial_id)).where(t.c.study_id == study_id, t.c.trial_id < tid)
                number = conn.execute(sa.update(t).where(t.c.trial_id == tid).values(number=earlier.scalar_subquery())
                                      .returning(t.c.number)).scalar_one()
                self._write_attrs(conn, tid, user, system)
        frozen = FrozenTrial(number=number, state=TrialState.RUNNING, value=None, values=None,
                             datetime_start=_local_naive(_utc_naive(start)), datetime_complete=None,
                             params={}, distributions={}, user_attrs=user, system_attrs=system,
                             intermediate_values={}, trial_id=tid)
        with self._pending_lock:
            self._recent = {tid: copy.deepcopy(frozen)}
        return frozen

    def _insert_running_pg(self, conn: Any, study_id: int, start_utc: datetime.datetime,
                           user: dict[str, Any], system: dict[str, Any]) -> tuple[int, int]:
        """PostgreSQL: the trial and its attributes in one statement (data-modifying CTEs), the
        study's row already locked by the caller. The number is the count of the study's trials
        before this one, as Optuna's ``count_past_trials``: under the row lock every earlier
        trial of the study is committed when this statement takes its snapshot, and its id,
        drawn now, is the study's largest."""
        import sqlalchemy as sa
        anchor = self._anchor.get(study_id)
        rows = {"u": self._attr_rows(user), "s": self._attr_rows(system)}

        def build() -> Any:
            m = self._models()
            t = m.TrialModel.__table__
            sid = sa.bindparam("sid")
            if anchor is None:
                earlier = sa.select(sa.func.count(t.c.trial_id)).where(t.c.study_id == sid).scalar_subquery()
            else:
                # a trial this process saw, numbered k, has k trials before it (Optuna's
                # numbering): the count is k + 1 and the study's trials after it, found by the
                # primary key, so the statement reads the newest trials only, not the whole study
                earlier = (sa.select(sa.func.count(t.c.trial_id) + sa.bindparam("a_next"))
                           .where(t.c.study_id == sid, t.c.trial_id > sa.bindparam("a_id")).scalar_subquery())
            ins = sa.insert(t).values(study_id=sid, number=earlier, state=TrialState.RUNNING,
                                      datetime_start=sa.bindparam("start")).returning(t.c.trial_id, t.c.number)
            ins = ins.cte("new_trial")
            query = sa.select(ins.c.trial_id, ins.c.number)
            for tag, model in (("u", m.TrialUserAttributeModel), ("s", m.TrialSystemAttributeModel)):
                if rows[tag]:
                    query = query.add_cte(self._rows_cte(ins, model, ("key", "value_json"), len(rows[tag]), tag))
            return query
        query = self._statement(("create", anchor is not None, len(user), len(system)), build)
        args: dict[str, Any] = {"sid": study_id, "start": start_utc,
                                **self._rows_args("u", rows["u"]), **self._rows_args("s", rows["s"])}
        if anchor is not None:
            args.update(a_id=anchor[0], a_next=anchor[1] + 1)
        row = conn.execute(query, args).one()
        self._see(study_id, row.trial_id, row.number)
        return row.trial_id, row.number

    def claim(self, trial_id: int, user_attrs: dict[str, Any]) -> bool:
        """Pop a waiting (enqueued) trial for this process: its state RUNNING, its start now and
        ``user_attrs`` (the worker's identity) in one write, so that no reader sees it running
        without its worker. On PostgreSQL one statement (a guard CTE: the trial updated only
        from WAITING; the attributes inserted from it); SQLite: one transaction. False if the
        trial runs already (another process popped it), as Optuna's ``set_trial_state_values``;
        ``UpdateFinishedTrialError`` if it has ended, KeyError if there is no such trial."""
        if not self._lean:
            if not super().set_trial_state_values(trial_id, TrialState.RUNNING):
                return False
            for k, v in user_attrs.items():
                super().set_trial_user_attr(trial_id, k, v)
            return True
        import sqlalchemy as sa
        m = self._models()
        t = m.TrialModel.__table__
        start = _utc_naive(datetime.datetime.now())
        waiting = sa.and_(t.c.trial_id == sa.bindparam("tid"), t.c.state == TrialState.WAITING)
        pop = (sa.update(t).where(waiting).values(state=TrialState.RUNNING, datetime_start=sa.bindparam("start"))
               .returning(t.c.trial_id))
        attrs = self._attr_rows(user_attrs)
        self._forget(trial_id)
        if self.engine.name == "postgresql" and attrs:
            def build() -> Any:
                guard = pop.cte("guard")
                return sa.select(guard.c.trial_id).add_cte(self._rows_cte(
                    guard, m.TrialUserAttributeModel, ("key", "value_json"), len(attrs), "u", ("trial_id", "key"),
                    ("value_json",)))
            query = self._statement(("claim", len(attrs)), build)
            with self._reader().connect() as conn:
                if conn.execute(query, {"tid": trial_id, "start": start, **self._rows_args("u", attrs)}).first() is not None:
                    return True
                return self._not_claimed(conn, trial_id)
        with self.engine.begin() as conn:
            if conn.execute(pop, {"tid": trial_id, "start": start}).first() is None:
                return self._not_claimed(conn, trial_id)
            self._write_attrs(conn, trial_id, user_attrs, {})
        return True

    def _not_claimed(self, conn: Any, trial_id: int) -> bool:
        """:meth:`claim` found ``trial_id`` not waiting: False if it runs, else raises."""
        self._check_running(conn, trial_id)
        return False

    def _see(self, study_id: int, trial_id: int, number: int | None) -> None:
        """Keep the newest trial seen of a study as the anchor of the next number's count."""
        if number is not None and trial_id > self._anchor.get(study_id, (-1, -1))[0]:
            self._anchor[study_id] = (trial_id, number)

    # -- deferred writes ---------------------------------------------------------------------

    def defer(self, trial_id: int) -> None:
        """Buffer ``trial_id``'s parameters and attributes in this process until :meth:`flush` or
        its ``set_trial_state_values`` (a no-op on databases the Core paths do not cover)."""
        if not self._lean:
            return
        with self._pending_lock:
            own = self._recent.pop(trial_id, None)
        if own is None:
            own = self.get_trial(trial_id)
        with self._pending_lock:
            self._pending.setdefault(trial_id, _Pending())
            self._own.setdefault(trial_id, own)

    def flush(self, trial_id: int) -> None:
        """Write ``trial_id``'s buffered writes in one transaction; it stays deferred."""
        with self._pending_lock:
            p = self._pending.get(trial_id)
            if p is None or p.empty():
                return
            self._pending[trial_id] = _Pending()
        try:
            if self.engine.name == "postgresql":
                self._write_one_pg(trial_id, p)
                return
            with self.engine.begin() as conn:
                self._check_running(conn, trial_id)
                self._write_pending(conn, trial_id, p)
        except UpdateFinishedTrialError:
            raise
        except Exception:
            with self._pending_lock:           # not written: kept for the next write
                newer = self._pending.get(trial_id) or _Pending()
                self._pending[trial_id] = _Pending({**newer.params, **p.params},   # a param: the first write
                                                   {**p.user_attrs, **newer.user_attrs},
                                                   {**p.system_attrs, **newer.system_attrs})
            raise

    def _write_one_pg(self, trial_id: int, p: _Pending, change: dict[str, Any] | None = None,
                      values: Sequence[float] | None = None) -> None:
        """PostgreSQL: a deferred trial's writes in one statement (autocommit, so one round trip):
        a guard CTE, the trial locked while it runs (``change`` None: a flush) or its state
        changed from RUNNING (``change``: the new state and end time), and the inserts of the
        parameters, attributes and values selected from the guard, so that nothing is written
        unless the trial was running (otherwise :meth:`_refuse`). Built once per shape."""
        import sqlalchemy as sa
        m = self._models()
        t = m.TrialModel.__table__
        vals = [] if values is None else list(values)
        rows = {"p": [{"param_name": k, "param_value": v, "distribution_json": distributions.distribution_to_json(d)}
                      for k, (v, d) in p.params.items()],
                "u": self._attr_rows(p.user_attrs), "s": self._attr_rows(p.system_attrs),
                "v": [{c: r[c] for c in ("objective", "value", "value_type")} for r in self._value_rows(trial_id, vals)]}

        def build() -> Any:
            running = sa.and_(t.c.trial_id == sa.bindparam("tid"), t.c.state == TrialState.RUNNING)
            if change is None:
                guard = sa.select(t.c.trial_id).where(running).with_for_update().cte("guard")
            else:
                guard = (sa.update(t).where(running)
                         .values(**{c: sa.bindparam(f"c_{c}", type_=t.c[c].type) for c in sorted(change)})
                         .returning(t.c.trial_id).cte("guard"))
            query = sa.select(guard.c.trial_id)
            parts = (("p", m.TrialParamModel, ("param_name", "param_value", "distribution_json"),
                      ("trial_id", "param_name"), ()),                      # a param: the first write wins
                     ("u", m.TrialUserAttributeModel, ("key", "value_json"), ("trial_id", "key"), ("value_json",)),
                     ("s", m.TrialSystemAttributeModel, ("key", "value_json"), ("trial_id", "key"), ("value_json",)),
                     ("v", m.TrialValueModel, ("objective", "value", "value_type"), ("trial_id", "objective"),
                      ("value", "value_type")))
            for tag, model, cols, keys, update in parts:
                if rows[tag]:
                    query = query.add_cte(self._rows_cte(guard, model, cols, len(rows[tag]), tag, keys, update))
            return query
        shape = ("write", tuple(sorted(change)) if change is not None else None, *(len(r) for r in rows.values()))
        query = self._statement(shape, build)
        args: dict[str, Any] = {"tid": trial_id, **{f"c_{c}": v for c, v in (change or {}).items()}}
        for tag, r in rows.items():
            args.update(self._rows_args(tag, r))
        with self._reader().connect() as conn:
            if conn.execute(query, args).first() is None:
                self._refuse(conn, trial_id)

    def _value_rows(self, trial_id: int, values: Sequence[float]) -> list[dict[str, Any]]:
        """``trial_values`` rows as Optuna stores them (an infinity as its type, no value)."""
        rows = []
        for objective, v in enumerate(values):
            stored, kind = self._models().TrialValueModel.value_to_stored_repr(v)
            rows.append({"trial_id": trial_id, "objective": objective, "value": stored, "value_type": kind})
        return rows

    def _refuse(self, conn: Any, trial_id: int) -> None:
        """A write's guard found ``trial_id`` not running: KeyError if there is no such trial,
        else Optuna's ``UpdateFinishedTrialError``; always raises."""
        self._check_running(conn, trial_id)
        raise UpdateFinishedTrialError(f"Trial#{trial_id} is not running.")

    def _check_running(self, conn: Any, trial_id: int) -> TrialState:
        import sqlalchemy as sa
        t = self._models().TrialModel.__table__
        row = conn.execute(sa.select(t.c.state).where(t.c.trial_id == trial_id).with_for_update()).first()
        if row is None:
            raise KeyError(f"No trial with trial_id {trial_id} exists.")
        self.check_trial_is_updatable(trial_id, row.state)
        return row.state

    def _write_pending(self, conn: Any, trial_id: int, p: _Pending) -> None:
        if p.params:
            # a second write of a name is ignored, as Optuna's (its unique key, integrity error ignored)
            conn.execute(self._upsert(self._models().TrialParamModel, ("trial_id", "param_name"), ()),
                         [{"trial_id": trial_id, "param_name": k, "param_value": v,
                           "distribution_json": distributions.distribution_to_json(d)}
                          for k, (v, d) in p.params.items()])
        self._write_attrs(conn, trial_id, p.user_attrs, p.system_attrs)

    def _write_attrs(self, conn: Any, trial_id: int, user: dict[str, Any], system: dict[str, Any]) -> None:
        m = self._models()
        for model, attrs in ((m.TrialUserAttributeModel, user), (m.TrialSystemAttributeModel, system)):
            if attrs:
                conn.execute(self._upsert(model, ("trial_id", "key"), ("value_json",)),
                             [{"trial_id": trial_id, **r} for r in self._attr_rows(attrs)])

    def _set_trial_param(self, trial_id: int, param_name: str, param_value_internal: float,
                         distribution: distributions.BaseDistribution,
                         previous_distribution: distributions.BaseDistribution | None) -> None:
        with self._pending_lock:
            p = self._pending.get(trial_id)
            if p is not None and previous_distribution is not None:
                distributions.check_distribution_compatibility(previous_distribution, distribution)
                p.params.setdefault(param_name, (param_value_internal, distribution))
                self._own_param(trial_id, param_name, param_value_internal, distribution)
                return
        if p is not None:
            self.flush(trial_id)          # the study's first write of this name: Optuna's check, now
        else:
            self._forget(trial_id)
        super()._set_trial_param(trial_id, param_name, param_value_internal, distribution, previous_distribution)
        with self._pending_lock:
            self._own_param(trial_id, param_name, param_value_internal, distribution)

    def _own_param(self, trial_id: int, name: str, value: float, dist: distributions.BaseDistribution) -> None:
        own = self._own.get(trial_id)
        if own is not None and name not in own.params:
            own.params[name] = dist.to_external_repr(value)
            own.distributions[name] = dist

    def set_trial_user_attr(self, trial_id: int, key: str, value: Any) -> None:
        with self._pending_lock:
            p = self._pending.get(trial_id)
            if p is not None:
                value = json.loads(json.dumps(value))   # not JSON: refused now, as Optuna's write would
                p.user_attrs[key] = value
                self._own[trial_id].user_attrs[key] = copy.deepcopy(value)
                return
            self._recent.pop(trial_id, None)
        super().set_trial_user_attr(trial_id, key, value)

    def set_trial_system_attr(self, trial_id: int, key: str, value: Any) -> None:
        with self._pending_lock:
            p = self._pending.get(trial_id)
            if p is not None:
                value = json.loads(json.dumps(value))
                p.system_attrs[key] = value
                self._own[trial_id].system_attrs[key] = copy.deepcopy(value)
                return
            self._recent.pop(trial_id, None)
        super().set_trial_system_attr(trial_id, key, value)

    def set_trial_state_values(self, trial_id: int, state: TrialState,
                               values: Sequence[float] | None = None) -> bool:
        with self._pending_lock:
            p = self._pending.pop(trial_id, None)
            own = self._own.pop(trial_id, None)
        if p is None:
            self._forget(trial_id)
            return super().set_trial_state_values(trial_id, state, values)
        change: dict[str, Any] = {"state": state}
        if state.is_finished():
            change["datetime_complete"] = _utc_naive(datetime.datetime.now())
        try:
            if self.engine.name == "postgresql" and state != TrialState.RUNNING:
                self._write_one_pg(trial_id, p, change, values)
            else:
                self._write_many(trial_id, p, state, change, values)
        except UpdateFinishedTrialError:
            raise
        except Exception:
            with self._pending_lock:           # not written: kept for a retry of the call
                self._pending.setdefault(trial_id, p)
                if own is not None:
                    self._own.setdefault(trial_id, own)
            raise
        if state == TrialState.RUNNING:
            return False
        if own is not None:
            # as the database now holds it (Optuna's tell reads it back at once)
            own.state, own.datetime_complete = state, _local_naive(change.get("datetime_complete"))
            own.values = None if values is None else [float(v) for v in values]
            with self._pending_lock:
                self._recent = {trial_id: own}
                # the worker's next index read takes its own trial from this copy, not the
                # database (a copy, since Optuna's tell may change the one ``_recent`` hands out)
                if len(self._ended) < self.ENDED_KEPT:
                    self._ended[trial_id] = copy.deepcopy(own)
        return True

    def _write_many(self, trial_id: int, p: _Pending, state: TrialState, change: dict[str, Any],
                    values: Sequence[float] | None) -> None:
        """A deferred trial's end in one transaction of several statements (SQLite; and a
        RUNNING state asked of a trial that runs already, Optuna's False)."""
        import sqlalchemy as sa
        m = self._models()
        t = m.TrialModel.__table__
        with self.engine.begin() as conn:
            if state == TrialState.RUNNING:           # a deferred trial runs already: Optuna's False
                self._check_running(conn, trial_id)
                self._write_pending(conn, trial_id, p)
                return
            # the state first, only from RUNNING (the row stays locked to the commit): one
            # statement in place of a locking read and a write
            done = conn.execute(sa.update(t).where(t.c.trial_id == trial_id, t.c.state == TrialState.RUNNING)
                                .values(**change).returning(t.c.trial_id)).first()
            if done is None:
                self._refuse(conn, trial_id)
            self._write_pending(conn, trial_id, p)
            if values is not None:
                conn.execute(self._upsert(m.TrialValueModel, ("trial_id", "objective"), ("value", "value_type")),
                             self._value_rows(trial_id, values))

    def set_trial_intermediate_value(self, trial_id: int, step: int, intermediate_value: float) -> None:
        super().set_trial_intermediate_value(trial_id, step, intermediate_value)
        with self._pending_lock:
            own = self._own.get(trial_id) or self._recent.get(trial_id)
            if own is not None:
                own.intermediate_values[step] = intermediate_value

    def _forget(self, trial_id: int) -> None:
        """A write not deferred: the kept copy of the trial (``_recent``) is no longer what the
        database holds."""
        with self._pending_lock:
            self._recent.pop(trial_id, None)

    def deferred(self) -> Iterable[int]:
        """The trials this process defers (for tests and the worker's checks)."""
        with self._pending_lock:
            return list(self._pending)


def lean(storage: Any) -> LeanRDBStorage | None:
    """The :class:`LeanRDBStorage` behind an Optuna storage object (its cache), or None."""
    base = compat.cached_backend(storage)
    return base if isinstance(base, LeanRDBStorage) else None
