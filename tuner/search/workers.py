"""The workers: processes that share one study's budget, here and on other machines.

Storage (``storage.py``): a journal file under ``runs/`` by default (no server), or a
SQLite / PostgreSQL URL. Re-running a study resumes it; any number of processes, here
(``--workers``) or on other machines (``gait-tuner worker``), share one budget stored with the
study, each asking for a trial under the store's budget lock (:func:`work`). A trial whose
worker died is failed and retried once with the same parameters; a parameter set already
walked is never walked again (its result is copied, ``duplicate_of``). Every trial records
its full parameter set (SI), so it is reproducible: the simulation is deterministic.

"""

from __future__ import annotations

import contextlib
import gc
import math
import os
import signal
import sys
import time
import warnings
from pathlib import Path
from typing import Any, Callable

import optuna
from optuna.trial import TrialState

import gaits
from gaits import ParamError

from ..errors import UserError
from ..process_pool import die_with_parent, forking_without_ctrl_c, ignore_ctrl_c, mp_context
from ..store import optuna_compat as compat
from ..store.liveness import Heartbeat, process_identity
from ..store.history import IndexedMedianPruner, TrialIndex, WindowedTPESampler
from .objective import Evaluator, objective_for, record_constraint, suggest
from ..store.journal import StorageFull
from ..store.rdb import lean
from ..store.storage import StudyStore, disk_full, storage_full
from .study import CTRL_PREFIX, ENGINE_PREFIX, STAB_PREFIX, StudySpec
from .trials import n_done, trial_result

__all__ = ["open_storage", "open_study", "load_tuned_study", "enqueue_starts", "trial_distributions",
           "WorkerStop", "WorkersDying", "work", "prepare_study", "run_study", "run_workers"]


def open_storage(spec: StudySpec, storage: str | None, runs_dir: Path) -> Any:
    """The study's Optuna storage: the journal ``runs/<name>.journal`` unless a URL is given."""
    return StudyStore.open(spec.name, storage, runs_dir).optuna_storage()

def _sampler(spec: StudySpec, seed: int, index: TrialIndex | None = None) -> optuna.samplers.BaseSampler:
    # the fall constraint is stored on each trial (record_constraint); TPE reads it. The constant
    # liar: trials running in other workers count as bad ones, so workers that sample at the same
    # time do not all propose the same set (sampling is outside the budget lock)
    return WindowedTPESampler(trial_distributions(spec), index, seed=seed, n_startup_trials=8,
                              constant_liar=True)

def load_tuned_study(spec: StudySpec, storage: str | None, runs_dir: Path) -> optuna.Study:
    """A study that has been tuned, from its storage; a one-line :class:`UserError` if it has not."""
    journal = Path(runs_dir) / f"{spec.name}.journal"
    if storage is None and not os.path.lexists(journal):
        raise UserError(f"no runs of study {spec.name!r} in {journal} (run `gait-tuner tune` first)")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        return optuna.load_study(study_name=spec.name, storage=open_storage(spec, storage, runs_dir))
    except KeyError:
        raise UserError(f"storage holds no study named {spec.name!r}") from None

def open_study(spec: StudySpec, storage: Any, seed: int | None = None,
               index: TrialIndex | None = None) -> optuna.Study:
    pruner: optuna.pruners.BasePruner = optuna.pruners.NopPruner()
    if len(spec.objectives) == 1 and len(spec.surfaces) > 1:
        pruner = (optuna.pruners.MedianPruner(n_startup_trials=6, n_warmup_steps=0) if index is None
                  else IndexedMedianPruner(index, n_startup_trials=6, n_warmup_steps=0))
    study = optuna.create_study(study_name=spec.name, storage=storage, load_if_exists=True,
                                directions=spec.directions,
                                sampler=_sampler(spec, spec.sampler_seed if seed is None else seed, index),
                                pruner=pruner)
    if "spec" not in study.user_attrs:
        study.set_user_attr("spec", {"gait": spec.gait, "robot": spec.robot,
                                     "surfaces": list(spec.surfaces), "objectives": list(spec.objectives)})
    if study.metric_names is None:              # optuna-dashboard and Optuna's plots show these names
        import warnings
        with warnings.catch_warnings():         # "experimental since 3.2": expected, not the user's concern
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            study.set_metric_names([OBJECTIVE_NAMES.get(o, o) for o in spec.objectives])
    return study


#: The objectives as a reader of the dashboard should see them
OBJECTIVE_NAMES = {"pitch_rms": "pitch score [deg]", "speed": "forward speed [m/s]",
                   "speed_score": "speed score", "forward": "forward stair [m/s]", "backward": "backward stair [m/s]",
                   "left": "left stair [m/s]", "right": "right stair [m/s]", "turn_left": "turn-left stair [rad/s]",
                   "turn_right": "turn-right stair [rad/s]", "push_distance": "push distance D [m]"}


def _clip_to_space(spec: StudySpec, params: gaits.GaitParams) -> dict[str, Any]:
    out = {}
    for r in spec.space:
        if r.name.startswith(STAB_PREFIX):
            v = getattr(spec.stabiliser, r.name[len(STAB_PREFIX):])
        elif r.name.startswith(CTRL_PREFIX):
            v = spec.controller.params[r.name[len(CTRL_PREFIX):]]
        elif r.name.startswith(ENGINE_PREFIX):
            v = getattr(spec.engine, r.name[len(ENGINE_PREFIX):])
        else:
            v = getattr(params, r.name)
            if r.of is not None:                # searched as a share of another parameter
                v = v / getattr(params, r.of)
        v = min(max(v, r.low), r.high)
        out[r.label] = int(round(v)) if r.integer else float(v)
    return out

def enqueue_starts(study: optuna.Study, spec: StudySpec) -> list[str]:
    """Enqueue the CasADi seed and the baselines as the first trials (once per study)."""
    if study.user_attrs.get("starts_enqueued"):
        return []
    done = []
    if "casadi" in spec.enqueue:
        from .seed import SeedInfeasible, seed_for
        try:
            from ..sim.surfaces import load_surface
            layer = max(load_surface(name).layer_height for name in spec.surfaces)
            base = spec.scenario_room.seed_base(spec.settings, spec.base, spec.gait)
            seeded = seed_for(spec.gait, base, layer_height=layer)
            study.enqueue_trial(_clip_to_space(spec, seeded), user_attrs={"start": "casadi seed"})
            done.append("casadi seed")
        except (SeedInfeasible, ParamError) as exc:
            done.append(f"casadi seed skipped: {exc}")
    if "baselines" in spec.enqueue and spec.controller is not None:
        study.enqueue_trial(_clip_to_space(spec, None), user_attrs={"start": "the controller file's values"})
        done.append("the controller file's values")
    elif "baselines" in spec.enqueue:
        for i, b in enumerate((spec.base,) + spec.baselines):
            study.enqueue_trial(_clip_to_space(spec, b), user_attrs={"start": f"baseline {i}"})
            done.append(f"baseline {i}")
    study.set_user_attr("starts_enqueued", True)
    return done

def trial_distributions(spec: StudySpec) -> dict[str, Any]:
    """The study's space as Optuna distributions (all parameters are sampled at ``ask``)."""
    from optuna.distributions import FloatDistribution, IntDistribution
    out: dict[str, Any] = {}
    for r in spec.space:
        if r.integer:
            out[r.label] = IntDistribution(int(math.ceil(r.low)), int(math.floor(r.high)), log=r.log)
        else:
            out[r.label] = FloatDistribution(r.low, r.high, log=r.log)
    return out

def _tell_copy(study: optuna.Study, trial: optuna.Trial, source: optuna.trial.FrozenTrial) -> None:
    """Record ``source``'s result for ``trial`` without walking it again."""
    for key, value in source.user_attrs.items():
        if key not in ("worker", "start", "retry_of"):
            trial.set_user_attr(key, value)
    trial.set_user_attr("duplicate_of", source.number)
    constraint = trial_result(source).get("fall_constraint")
    if constraint is not None:
        record_constraint(trial, float(constraint))
    if source.state == TrialState.PRUNED:
        study.tell(trial, state=TrialState.PRUNED)
    else:
        study.tell(trial, source.values if len(source.values) > 1 else source.values[0])

#: A worker that dies by a signal is replaced as often as the study needs; only this many deaths
#: per worker with no trial finishing in between stop the run (a crash loop, not bad luck).
MAX_DEATHS_IN_A_ROW = 3


class WorkersDying(RuntimeError):
    """Workers keep dying with no trial finishing: the run stops with this one line (exit 1)."""


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


class WorkerStop(UserError):
    """A worker met bad input or a full disk: the whole run stops with this one line."""

#: How many finished trials a worker reads between two freezes of its memory (:func:`_freeze_history`).
FREEZE_EVERY = 1000


def _freeze_history(n_done: int, frozen_at: int) -> int:
    """Python's garbage collector walks every object it tracks in its oldest generation, and a
    worker holds the whole study Optuna replayed (10k trials: a full collection took ~50 ms, falling
    on whichever trial allocated at that moment, and the overhead per trial grew with the study).
    Ours: once the study is read, and again every :data:`FREEZE_EVERY` trials read since, collect
    and then freeze what is left (``gc.freeze``: those objects are never walked again; they live as
    long as the study's replay holds them anyway). Returns the count it froze at."""
    if n_done - frozen_at < FREEZE_EVERY:
        return frozen_at
    gc.collect()
    gc.freeze()
    return n_done


def work(spec: StudySpec, store: StudyStore, budget: int, seed: int,
         log: Callable[[str], None] | None = None, poll: float = 1.0, threads: int = 1) -> int:
    """One process's share of a study: trials until the study holds ``budget`` finished ones.

    Under the store's budget lock, per trial: dead trials are failed and re-enqueued
    (:meth:`StudyStore.reap`), the study's finished and running trials are counted (the
    :class:`TrialIndex`, read incrementally before the lock and recounted under it: on a
    database one statement), and a trial is reserved (created, or popped from the queue, with
    the worker's identity in the same write; on the journal a popped trial gets it in a second
    record) only while finished + running < budget. So any number of processes, on any number
    of machines, run exactly the budget; a process that finds the rest running waits
    for them (one of them may die and need a retry). The parameters are sampled after the lock
    is released, so the lock is held for constant work whatever the study's size. A set walked
    before (a resumed sampler, or TPE on an integer axis, can propose one again) is not walked
    again: its result is copied; enqueued retries are never such copies. ``threads``: a robust
    trial's randomised walks run on this many threads (:class:`Evaluator`). Returns the trials
    this process walked.
    """
    log = log or (lambda msg: print(f"gait-tuner: {msg}", file=sys.stderr, flush=True))
    index = TrialIndex()
    study = open_study(spec, store.optuna_storage(), seed, index)
    index.refresh(study)                            # the whole study, once, outside the lock
    frozen = _freeze_history(index.n_done, -FREEZE_EVERY)
    objective = objective_for(spec, Evaluator(spec, threads=threads))
    rdb = lean(compat.study_storage(study))
    me = process_identity()                         # host, pid, start time: this process's, once
    beat = Heartbeat(store, spec.name).start()
    ran = 0
    try:
        while True:
            frozen = _freeze_history(index.n_done, frozen)
            index.refresh(study)                    # the new trials read whole, outside the lock
            with store.budget_lock(spec.name):
                stored = index.recount(study, "budget")      # exact counts: constant work
                notes = store.reap(study, index.running_read, index.failed)
                for note in notes:
                    log(note)
                if notes:
                    index.refresh(study)             # the trials reap failed or enqueued
                    stored = study.user_attrs.get("budget")
                budget = int(stored if stored is not None else budget)   # as another `tune --trials` set it
                if index.n_done_now >= budget:
                    return ran
                trial = None
                if index.n_done_now + index.n_running < budget:
                    with warnings.catch_warnings():
                        # ours: heartbeats with ask/tell, on purpose (StudyStore.beat); not for users
                        warnings.filterwarnings("ignore", message="Heartbeat of storage is supposed")
                        trial = index.reserve(study, {"worker": me})
            if trial is None:
                time.sleep(poll)
                continue
            beat.trial_id = compat.trial_id(trial)
            if isinstance(study.sampler, WindowedTPESampler):
                study.sampler.mark_fresh(trial.number)
            if rdb is not None:
                # a database: the trial's writes in two transactions, not one per write (rdb.py)
                rdb.defer(compat.trial_id(trial))
            suggest(trial, spec)
            if rdb is not None:
                rdb.flush(compat.trial_id(trial))       # its parameters, for the other workers' liar
            source = None if trial.user_attrs.get("retry_of") is not None else index.duplicate_of(trial)
            if source is not None:
                _tell_copy(study, trial, source)
                continue
            try:
                value = objective(trial)
            except optuna.TrialPruned:
                study.tell(trial, state=TrialState.PRUNED)
            except BaseException as exc:
                if isinstance(exc, StorageFull):
                    raise                       # left running, as below
                full = storage_full(exc)
                if full is not None:
                    # left running: the next open finds its worker dead and retries it
                    raise disk_full(store.where, full) from None
                with contextlib.suppress(Exception):
                    trial.set_user_attr("failed", f"{type(exc).__name__}: {exc}")
                    study.tell(trial, state=TrialState.FAIL)
                raise
            else:
                study.tell(trial, value)
            beat.trial_id = None
            ran += 1
    finally:
        beat.stop()

def _worker(spec: StudySpec, store: StudyStore, budget: int, seed: int, parent: int, errors: Any,
            threads: int = 1) -> None:
    """A worker process: :func:`work`; bad input or a full disk goes back to the parent as one line."""
    die_with_parent(parent)
    ignore_ctrl_c()                                    # the parent decides what Ctrl-C stops
    os.environ.setdefault("MPLBACKEND", "Agg")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    store = StudyStore(journal=store.journal, url=store.url, grace_s=store.grace_s,
                       interval_s=store.interval_s)                   # open afresh after fork
    try:
        work(spec, store, budget, seed, threads=threads)
    except StorageFull as exc:
        errors.put(str(exc))
        sys.exit(3)
    except (UserError, ParamError) as exc:
        errors.put(str(exc))
        sys.exit(2)
    except Exception as exc:  # noqa: BLE001 - a database's full disk, outside a trial
        full = storage_full(exc)
        if full is None:
            raise
        errors.put(str(disk_full(store.where, full)))
        sys.exit(3)

def cores() -> int:
    """The cores this process may run on (its affinity, not the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1

def _sampler_seed(seed: int, index: int, run: int) -> int:
    """Worker ``index`` of the study's ``run``-th start (counted in the storage under the budget
    lock): two commands started on one study at once, or a resumed one, never share a sampler
    seed, so they do not walk the same sets; a fresh study's first run is reproducible."""
    return (seed + 1000 * index + 7919 * run) % (2 ** 31)

def scoring_parts(spec: StudySpec) -> dict[str, str]:
    """What a trial's score stands on, part by part, each as a short digest: the robot (its model
    file, servos, sensors, joints), the surfaces, the scenario and its settings, the objectives and
    how surfaces are aggregated, the walk's length, what is held fixed of the set, the engine, the
    stabiliser and a controller. Not the space (a study may be widened and resumed), not the
    budget, not the start."""
    import hashlib
    from ..robots import load_robot
    from ..sim.surfaces import load_surface

    def digest(*parts: Any) -> str:
        h = hashlib.sha256()
        for part in parts:
            h.update(part if isinstance(part, bytes) else repr(part).encode())
        return h.hexdigest()[:16]
    robot = load_robot(spec.robot)
    model_file = robot.urdf_path or robot.mjcf_path
    searched = {r.name for r in spec.space}
    held = {} if spec.base is None else {k: v for k, v in spec.base.to_mapping().items() if k not in searched}
    # the robot's own file where it has one (its converted MJCF holds absolute paths: a study moved
    # with its robot would read as another robot), the generated MJCF of a built-in one
    return {"robot": digest(Path(model_file).read_bytes() if model_file else robot.xml,
                            sorted((k, repr(v)) for k, v in robot.servos.items()), robot.foot_sensors,
                            sorted(robot.joint_map.items()), sorted(robot.pose.items())),
            "surfaces": digest([repr(load_surface(n)) for n in spec.surfaces]),
            "scenario": digest(spec.kind, spec.settings),
            "objectives": digest(spec.objectives, spec.aggregate),
            "duration": digest(spec.duration),
            "fixed": digest(spec.gait, sorted(held.items())),
            "engine": digest(spec.engine), "stabiliser": digest(spec.stabiliser),
            "controller": digest(None if spec.controller is None else _file_or_name(spec.controller.source))}


def _file_or_name(source: str) -> Any:
    """A controller's file's bytes (where the study moved, the same file), else its name."""
    path = Path(source.split(":", 1)[0]) if not Path(source).is_file() else Path(source)
    return path.read_bytes() if path.is_file() else source


def _same_scoring(spec: StudySpec, study: optuna.Study, log: Callable[[str], None]) -> None:
    """A study stored with other scoring parts than its file gives now is refused in one line: its
    trials were scored by another robot, scenario or objective, and a resume would mix them (an
    init re-run into the same folder did so silently). A study stored before its parts were kept
    takes them now."""
    parts = scoring_parts(spec)
    stored = study.user_attrs.get("scoring")
    if stored is None:
        study.set_user_attr("scoring", parts)
        return
    changed = [k for k in parts if stored.get(k) != parts[k]]
    if changed:
        done = len(study.get_trials(deepcopy=False))
        raise UserError(f"study {spec.name}: its storage holds {done} trial(s) scored with another "
                        f"{', '.join(changed)} than {spec.source or 'its file'} gives now; resuming would mix "
                        f"them: give the study a new name:, or move its journal away (the space may be "
                        f"widened and resumed, not the scoring)")


def prepare_study(spec: StudySpec, store: StudyStore, budget: int | None, seed: int,
                  log: Callable[[str], None] | None = None) -> tuple[optuna.Study, int, int]:
    """Create or join the study; once per study (whoever comes first), enqueue the CasADi seed
    and the baselines; set the shared budget (``budget`` None: keep the stored one, or the
    file's; a given budget that changes the stored one is said in one line: workers already
    running read it before each trial, so every process stops at the same budget); count this
    start. Returns the study, the budget and this start's number (for the sampler seeds)."""
    log = log or (lambda msg: print(f"gait-tuner: {msg}", file=sys.stderr, flush=True))
    study = None
    with store.budget_lock(spec.name):
        study = open_study(spec, store.optuna_storage(), seed)
        _same_scoring(spec, study, log)
        enqueue_starts(study, spec)
        attrs = study.user_attrs
        stored = attrs.get("budget")
        if budget is None:
            budget = int(stored) if stored is not None else spec.trials
        if stored != budget:
            study.set_user_attr("budget", budget)
            if stored is not None:
                log(f"budget of study {spec.name} {'raised' if budget > stored else 'lowered'} from "
                    f"{stored} to {budget} trials (--trials); every process on it stops at {budget}")
        run = int(attrs.get("starts", 0))
        study.set_user_attr("starts", run + 1)
        for note in store.reap(study):
            log(note)
    return study, budget, run

def run_study(spec: StudySpec, store: StudyStore, total: int | None, workers: int,
              seed: int, on_progress: Callable[[optuna.Study], None] | None = None,
              poll: float = 0.5, log: Callable[[str], None] | None = None) -> optuna.Study:
    """Run until the study holds its budget of finished trials, with ``workers`` processes here
    (other machines' ``worker`` processes may share the same budget). A worker that dies is
    replaced (its trial is retried by the others); bad input or a full disk in a worker stops
    all of them and is raised here as one line."""
    study, budget, run = prepare_study(spec, store, total, seed, log)
    return run_workers(spec, store, study, budget, workers, seed, on_progress, poll, log, run)

def run_workers(spec: StudySpec, store: StudyStore, study: optuna.Study, budget: int, workers: int,
                seed: int, on_progress: Callable[[optuna.Study], None] | None = None,
                poll: float = 0.5, log: Callable[[str], None] | None = None, run: int = 0) -> optuna.Study:
    """:func:`run_study` after :func:`prepare_study` (which gave ``study`` and ``budget``)."""
    log = log or (lambda msg: print(f"gait-tuner: {msg}", file=sys.stderr, flush=True))
    if n_done(study) >= budget:
        return study
    ctx = mp_context()
    errors = ctx.Queue()
    parent = os.getpid()

    n = max(1, min(workers, budget - n_done(study)))
    threads = max(1, cores() // n)           # cores the other workers leave to a robust trial's walks

    def spawn(index: int) -> Any:
        p = ctx.Process(target=_worker, args=(spec, store, budget, _sampler_seed(seed, index, run),
                                              parent, errors, threads), daemon=False)
        with forking_without_ctrl_c():
            p.start()
        return p

    procs = {i: spawn(i) for i in range(n)}
    respawns, in_a_row, last_done = 0, 0, n_done(study)
    try:
        while procs:
            if on_progress is not None:
                on_progress(study)
            for i, p in list(procs.items()):
                p.join(timeout=poll / len(procs))
                if p.exitcode is None:
                    continue
                del procs[i]
                if p.exitcode == 0:
                    continue
                if p.exitcode == 2:
                    msg = errors.get(timeout=5) if not errors.empty() else "a worker stopped on bad input"
                    raise WorkerStop(msg)
                if p.exitcode == 3:
                    raise StorageFull(errors.get(timeout=5) if not errors.empty() else
                                      f"disk full writing the study's storage {store.where}")
                if p.exitcode > 0:
                    raise RuntimeError(f"worker {i} (pid {p.pid}) failed with exit code {p.exitcode}; "
                                       f"see its message above")
                how = _signal_name(-p.exitcode)
                with store.budget_lock(spec.name):
                    store.mark_death(study, p.pid, how)
                    for note in store.reap(study):
                        log(note)
                done_now = n_done(study)
                in_a_row = 0 if done_now > last_done else in_a_row
                last_done = done_now
                in_a_row += 1
                if in_a_row > MAX_DEATHS_IN_A_ROW * n:
                    raise WorkersDying(f"workers of study {spec.name} died {in_a_row} times without a trial "
                                       f"finishing in between (the last, worker {i}, by {how}): stopped; "
                                       f"finished trials are kept, run the command again to resume")
                respawns += 1
                log(f"worker {i} (pid {p.pid}) was killed by {how}; starting another")
                procs[i] = spawn(i + 100 * respawns)
    except BaseException:
        for p in procs.values():
            p.terminate()
        for p in procs.values():
            p.join(timeout=10)
        raise
    if on_progress is not None:
        on_progress(study)
    return study


def runs_of(spec: StudySpec, runs_dir: Path | None) -> Path:
    """The folder of a study's journal: ``--runs`` when given, else the study file's ``runs:``, else
    ./runs."""
    return Path(runs_dir) if runs_dir is not None else spec.runs if spec.runs is not None else Path("runs")


def tuned_study(study_file: str, storage: str | None, runs_dir: Path | None):
    """(spec, optuna study) of a study that has been tuned; a one-line error if it has not."""
    from .study import load_study
    spec = load_study(study_file)
    return spec, load_tuned_study(spec, storage, runs_of(spec, runs_dir))
