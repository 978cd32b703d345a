"""The search: an Optuna study per (robot, surface(s), gait family), seeded, pruned, resumable.

Objective. For each surface of the study the trial's gait is walked once; its
score is the torso pitch RMS [deg] over the walk, and a fall adds
``FALL_PENALTY_DEG * (1 - walked fraction)`` so that a gait that falls early
scores worse than any that stays up, and falling later is better than falling
sooner (the sampler gets a gradient towards stability). Falls are *also* a
constraint (``fall_constraint`` > 0 when the robot fell anywhere), so Optuna's
TPE sampler treats fallen trials as infeasible and ``best`` is always a gait
that stayed up, if any did. A robust study aggregates the per-surface scores by
their worst (max) or mean, as its file says. A parameter set the generators
reject (e.g. t1 >= t2, an unreachable foot) scores the full penalty.

Walking in place is not walking: a gait that stays up but covers less of its
planned forward distance adds ``PROGRESS_PENALTY_DEG * (1 - covered fraction)``
and is infeasible below ``MIN_PROGRESS`` (feet sliding instead of stepping was
the first thing an unconstrained search found on soft grass).

Single-objective studies report the running aggregate after each surface, so
the median pruner can stop a trial that is already hopeless on its first
surfaces. Optional second objective: forward speed [m/s] (maximised; 0 on a
fall), for a Pareto front.

Robust studies (a ``robust:`` section) walk each trial K times per surface under domain
randomisation (``tuner/sim/randomisation.py``; seeds 0..K-1 of the tuning stream, the same for
every trial, so trials are compared on the same draws), score each walk as above and
aggregate all of them by the study's risk measure (``cvar25``: the mean of the worst quarter;
``worst``; ``mean``). Survival below ``min_survival`` is infeasible, and a trial whose falls
already exceed what that allows stops at once and is recorded as pruned. A study with a
``stabiliser:`` section walks every trial with the IMU stabiliser, its gains in the space as
``stabiliser.NAME``; the trial records them and ``export`` writes them into the gait file.

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
import math
import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import optuna
from optuna.trial import TrialState

import gaits
from gaits import ParamError, UnreachableTargetError

from ..errors import UserError
from ..sim.metrics import summarize
from ..sim import cache as sim_cache
from ..process_pool import mp_context
from ..sim.randomisation import TUNE, draw
from .storage import Heartbeat, StudyStore, process_identity
from .study import CTRL_PREFIX, OBJECTIVES, STAB_PREFIX, StudySpec

__all__ = ["FALL_PENALTY_DEG", "Evaluator", "open_storage", "open_study", "enqueue_starts", "run_study",
           "best_trial", "trial_params", "trial_stabiliser", "trial_result", "rollout_score", "trial_fell", "trial_feasible",
           "DONE_STATES", "record_constraint", "pareto_pick", "PARETO_PICKS", "StudyStore", "WorkerStop", "work", "prepare_study", "run_workers", "load_tuned_study", "trial_distributions"]

FALL_PENALTY_DEG = 100.0
PROGRESS_PENALTY_DEG = 50.0     # per unit of the planned distance not covered
MIN_PROGRESS = 0.5              # a gait covering less than this fraction of its plan is infeasible
DONE_STATES = (TrialState.COMPLETE, TrialState.PRUNED)


def open_storage(spec: StudySpec, storage: str | None, runs_dir: Path) -> Any:
    """The study's Optuna storage: the journal ``runs/<name>.journal`` unless a URL is given."""
    return StudyStore.open(spec.name, storage, runs_dir).optuna_storage()


def _sampler(spec: StudySpec, seed: int) -> optuna.samplers.BaseSampler:
    # the fall constraint is stored on each trial (record_constraint); TPE reads it
    return optuna.samplers.TPESampler(seed=seed, multivariate=True, n_startup_trials=8)


def load_tuned_study(spec: StudySpec, storage: str | None, runs_dir: Path) -> optuna.Study:
    """A study that has been tuned, from its storage; a one-line :class:`UserError` if it has not."""
    journal = Path(runs_dir) / f"{spec.name}.journal"
    if storage is None and not journal.exists():
        raise UserError(f"no runs of study {spec.name!r} in {journal} (run `gait-tuner tune` first)")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        return optuna.load_study(study_name=spec.name, storage=open_storage(spec, storage, runs_dir))
    except KeyError:
        raise UserError(f"storage holds no study named {spec.name!r}") from None


def open_study(spec: StudySpec, storage: Any, seed: int | None = None) -> optuna.Study:
    pruner = (optuna.pruners.MedianPruner(n_startup_trials=6, n_warmup_steps=0)
              if len(spec.objectives) == 1 and len(spec.surfaces) > 1 else optuna.pruners.NopPruner())
    study = optuna.create_study(study_name=spec.name, storage=storage, load_if_exists=True,
                                directions=spec.directions,
                                sampler=_sampler(spec, spec.sampler_seed if seed is None else seed),
                                pruner=pruner)
    if "spec" not in study.user_attrs:
        study.set_user_attr("spec", {"gait": spec.gait, "robot": spec.robot,
                                     "surfaces": list(spec.surfaces), "objectives": list(spec.objectives)})
    return study


@dataclass
class Evaluator:
    """Walks trial parameters on the study's robot and surfaces (one Simulator per surface, reused)."""

    spec: StudySpec

    def __post_init__(self) -> None:
        self.robot = sim_cache.robot(self.spec.robot)
        self.sims = [sim_cache.simulator(self.robot, s) for s in self.spec.surfaces]

    def evaluate(self, drive: gaits.Drive, report: Callable[[float, int], bool] | None = None) -> dict[str, Any]:
        """Per-surface metrics and the aggregate score of what ``drive`` walks (a trial's set and
        stabiliser)."""
        spec = self.spec
        if spec.speed is not None:
            return self._evaluate_speed(drive.params, drive.stabiliser)
        dt = self.sims[0].control_period
        try:
            if drive.user is not None:          # online: no table; its walk lasts the study's duration
                traj, planned, plan_dist = None, float(spec.duration), 0.0
                drive.controller(self.robot, dt)       # a controller that cannot be built: invalid, at once
            else:
                traj = drive.table(self.robot, dt)
                planned = traj.duration - float(traj.t[np.flatnonzero(traj.support != 0)[0]]) \
                    if np.any(traj.support != 0) else traj.duration
                plan_dist = float(traj.p_world_pelvis[-1, 0] - traj.p_world_pelvis[0, 0])
        except (ParamError, UnreachableTargetError) as exc:
            return {"score": FALL_PENALTY_DEG * 2, "speed": 0.0, "fall_constraint": 1.0,
                    "invalid": str(exc), "per_surface": {}}
        if spec.robust is not None:
            return self._evaluate_robust(drive, traj, planned, plan_dist)
        scores, speeds, walked, per = [], [], [], {}
        shortfall = 0.0
        for i, (name, sim) in enumerate(zip(spec.surfaces, self.sims)):
            m = summarize(sim.run(drive.controller(self.robot, dt, table=traj),
                                  **{**drive.run_options(), "duration": spec.duration}))
            score, frac, covered = rollout_score(m, planned, plan_dist)
            if covered is not None:
                shortfall = max(shortfall, MIN_PROGRESS - covered)
            scores.append(score)
            speeds.append(0.0 if m.fell else m.speed_mps)
            walked.append(frac if m.fell else 1.0 + 1e-9)
            per[name] = m.to_dict()
            if report is not None and report(self._aggregate(scores), i):
                raise optuna.TrialPruned()
        fell_any = any(v["fell"] for v in per.values())
        constraint = (1.0 - min(walked) + 1e-3) if fell_any else (shortfall if shortfall > 0 else -1.0)
        return {"score": self._aggregate(scores), "speed": float(np.mean(speeds)),
                "fall_constraint": constraint, "fell": fell_any, "per_surface": per}

    def _evaluate_robust(self, drive: gaits.Drive, traj: gaits.GaitTrajectory | None, planned: float,
                         plan_dist: float) -> dict[str, Any]:
        """K randomised rollouts per surface (tuning seeds 0..K-1, common to all trials), scored by
        the study's risk measure; survival below ``min_survival`` is infeasible, and a trial whose
        falls already exceed what that allows stops early (``hopeless``)."""
        rb = self.spec.robust
        total = rb.rollouts * len(self.sims)
        allowed = math.floor((1.0 - rb.min_survival) * total + 1e-9)
        scores, speeds, covered_all, per = [], [], [], {}
        falls = 0
        hopeless = False
        for name, sim in zip(self.spec.surfaces, self.sims):
            rows = []
            for i in range(rb.rollouts):
                p = draw(rb.randomisation, i, *sim.n_random(), namespace=TUNE)
                m = summarize(sim.run(drive.controller(self.robot, sim.control_period, table=traj),
                                      perturb=p, **{**drive.run_options(), "duration": self.spec.duration}))
                score, _, covered = rollout_score(m, planned, plan_dist)
                scores.append(score)
                if m.fell:
                    falls += 1
                else:
                    speeds.append(m.speed_mps)
                    if covered is not None:
                        covered_all.append(covered)
                rows.append({"fell": m.fell, "pitch_rms_deg": m.pitch_rms_deg, "speed_mps": m.speed_mps,
                             "t_fall_s": m.t_fall_s})
                if falls > allowed:
                    hopeless = True
                    break
            per[name] = {"survival": float(np.mean([not r["fell"] for r in rows])), "rollouts": len(rows),
                         "fell": any(r["fell"] for r in rows),
                         "pitch_rms_deg": float(np.median([r["pitch_rms_deg"] for r in rows]))}
            if hopeless:
                break
        survival = 1.0 - falls / len(scores)            # of the walks run (all of them unless hopeless)
        worst = sorted(scores, reverse=True)
        risk = {"worst": worst[0], "mean": float(np.mean(scores)),
                "cvar25": float(np.mean(worst[:max(1, len(worst) // 4)]))}[rb.risk]
        progress = float(np.median(covered_all)) if covered_all else (0.0 if abs(plan_dist) > 1e-3 else 1.0)
        if survival < rb.min_survival or hopeless:
            constraint = rb.min_survival - (1.0 - falls / total) + 1e-3     # > 0: falls already exceed it
        elif progress < MIN_PROGRESS:
            constraint = MIN_PROGRESS - progress
        else:
            constraint = -1.0
        return {"score": risk, "speed": float(np.mean(speeds)) if speeds else 0.0, "fall_constraint": constraint,
                "fell": falls > 0, "survival": survival, "hopeless": hopeless, "per_surface": per}

    def _evaluate_speed(self, params: gaits.GaitParams, stabiliser: Any) -> dict[str, Any]:
        """A speed study's trial: every direction's staircase on every surface
        (``tuner/sim/walk_speed.py``); per direction the worst (or mean) surface's highest stair
        held, weighted, less the pitch term. Infeasible unless every direction holds at least
        its first stair on every surface."""
        from ..sim.walk_speed import speed_test
        sp = self.spec.speed
        per: dict[str, dict] = {}
        reached: dict[str, list[float]] = {d: [] for d, _, _ in sp.directions}
        pitches, misses, fell = [], 0, False
        for name, sim in zip(self.spec.surfaces, self.sims):
            per[name] = {}
            for d, top, _ in sp.directions:
                r = speed_test(sim, params, sp.staircase(d, top), sp.tolerance, stabiliser)
                per[name][d] = {"reached": r.reached, "measured": r.measured, "fell": r.fell,
                                "pitch_rms_deg": r.pitch_rms_deg, "reason": r.reason}
                reached[d].append(r.reached)
                if np.isfinite(r.pitch_rms_deg):
                    pitches.append(r.pitch_rms_deg)
                misses += r.reached <= 0.0
                fell = fell or r.fell
        agg = (min if self.spec.aggregate == "worst" else (lambda v: float(np.mean(v))))
        by_dir = {d: float(agg(v)) for d, v in reached.items()}
        pitch = float(max(pitches) if self.spec.aggregate == "worst" else np.mean(pitches)) if pitches else 90.0
        score = sum(w * by_dir[d] for d, _, w in sp.directions) - sp.pitch_weight * pitch
        total = len(self.sims) * len(sp.directions)
        constraint = misses / total if misses else -1.0
        values = ((score,) if sp.mode == "weighted"
                  else tuple(by_dir[d] for d, _, _ in sp.directions) + (pitch,))
        return {"values": values, "score": score, "speed": by_dir.get("forward", 0.0),
                "fall_constraint": constraint, "fell": fell, "per_surface": per, "by_direction": by_dir,
                "pitch_rms_deg": pitch}

    def _aggregate(self, scores: list[float]) -> float:
        return float(max(scores) if self.spec.aggregate == "worst" else np.mean(scores))


def rollout_score(m: Any, planned: float, plan_dist: float) -> tuple[float, float, float | None]:
    """One rollout's score [deg] (see the module docstring), its walked fraction and, when it
    stayed up and had somewhere to go, the covered fraction of its planned distance."""
    frac = 1.0 if not m.fell else float(np.clip(m.walk_time_s / max(planned, 1e-9), 0, 1))
    score = m.pitch_rms_deg + (FALL_PENALTY_DEG * (1.0 - frac) if m.fell else 0.0)
    if m.fell and frac >= 1.0:
        score += 1.0
    covered = None
    if not m.fell and abs(plan_dist) > 1e-3:
        covered = float(np.clip(m.distance_m / plan_dist, 0.0, 1.0))
        score += PROGRESS_PENALTY_DEG * (1.0 - covered)
    return score, frac, covered


def record_constraint(trial: optuna.Trial, value: float) -> None:
    """Store the fall constraint (> 0: fell or walked too little) as the list-valued system
    attribute ``constraints``: Optuna 5 reads it as constraint "0" (``FrozenTrial.constraints``,
    feasibility in TPE and ``best_trials``), and optuna-dashboard (0.21) reads only this key,
    not the per-name keys of ``Trial.set_constraint``, so fallen trials show as infeasible there."""
    trial.storage.set_trial_system_attr(trial._trial_id, "constraints", [float(value)])


def _suggest(trial: optuna.Trial, spec: StudySpec) -> dict[str, Any]:
    out = {}
    for r in spec.space:
        if r.integer:
            out[r.name] = trial.suggest_int(r.label, int(math.ceil(r.low)), int(math.floor(r.high)), log=r.log)
        else:
            out[r.name] = trial.suggest_float(r.label, r.low, r.high, log=r.log)
    return out


def objective_for(spec: StudySpec, evaluator: Evaluator) -> Callable[[optuna.Trial], Any]:
    def objective(trial: optuna.Trial):
        sampled = _suggest(trial, spec)
        try:
            drive = spec.drive_for(sampled, source=f"trial {trial.number}")
        except ParamError as exc:
            record_constraint(trial, 1.0)
            trial.set_user_attr("result", {"fell": True, "fall_constraint": 1.0, "invalid": str(exc)})
            worst = tuple(2 * FALL_PENALTY_DEG if OBJECTIVES[o] == "minimize" else (-10.0 if o == "speed_score" else 0.0)
                          for o in spec.objectives)
            return worst if len(worst) > 1 else worst[0]

        def report(value: float, step: int) -> bool:
            if len(spec.objectives) > 1:
                return False
            trial.report(value, step)
            return trial.should_prune()

        res = evaluator.evaluate(drive, None if spec.speed is not None else report)
        # two journal writes per trial (params, result): workers contend for the file lock
        record_constraint(trial, res["fall_constraint"])
        walked = {"controller": dict(drive.user.params)} if drive.user is not None else drive.params.to_mapping()
        trial.set_user_attr("params", walked if drive.stabiliser is None else
                            {**walked, "stabiliser": drive.stabiliser.to_mapping()})
        trial.set_user_attr("result", {"fell": res.get("fell", True),
                                       "fall_constraint": res["fall_constraint"],
                                       "per_surface": res["per_surface"], "invalid": res.get("invalid"),
                                       "survival": res.get("survival"), "hopeless": res.get("hopeless")})
        if res.get("hopeless"):
            raise optuna.TrialPruned(f"survival already below {spec.robust.min_survival:.0%}")
        if "values" in res:
            trial.set_user_attr("speed", {"by_direction": res["by_direction"], "score": res["score"],
                                          "pitch_rms_deg": res["pitch_rms_deg"]})
            return res["values"] if len(res["values"]) > 1 else res["values"][0]
        if len(spec.objectives) > 1:
            return res["score"], res["speed"]
        return res["score"]
    return objective


def _clip_to_space(spec: StudySpec, params: gaits.GaitParams) -> dict[str, Any]:
    out = {}
    for r in spec.space:
        if r.name.startswith(STAB_PREFIX):
            v = getattr(spec.stabiliser, r.name[len(STAB_PREFIX):])
        elif r.name.startswith(CTRL_PREFIX):
            v = spec.controller.params[r.name[len(CTRL_PREFIX):]]
        else:
            v = getattr(params, r.name)
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
            base = spec.base
            if spec.speed is not None and spec.gait == "tlipfm":
                # plan the seed for half the forward top stair at a 0.3 s step (ours: the seed's
                # step length is a parameter of the problem, not a decision variable)
                top = dict((d, t) for d, t, _ in spec.speed.directions).get("forward", 0.2)
                sl = round(min(0.5 * top * 0.3, 0.06), 4)
                base = base.replace(step_length=sl, d1=sl / 2, d2=sl / 2)
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


def _counts(study: optuna.Study) -> tuple[int, int]:
    trials = study.get_trials(deepcopy=False, states=DONE_STATES + (TrialState.RUNNING,))
    done = sum(1 for t in trials if t.state in DONE_STATES)
    return done, len(trials) - done


def _duplicate_of(study: optuna.Study, trial: optuna.Trial) -> optuna.trial.FrozenTrial | None:
    """A finished trial that walked exactly these parameters (a resumed sampler, or TPE on an
    integer axis, can propose a set again); enqueued retries are never duplicates."""
    params = trial.params
    for t in study.get_trials(deepcopy=False, states=DONE_STATES):
        if t.params == params and t.number != trial.number:
            return t
    return None


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


class WorkerStop(UserError):
    """A worker met bad input or a full disk: the whole run stops with this one line."""


def work(spec: StudySpec, store: StudyStore, budget: int, seed: int,
         log: Callable[[str], None] | None = None, poll: float = 1.0) -> int:
    """One process's share of a study: trials until the study holds ``budget`` finished ones.

    Each step runs under the store's budget lock: dead trials are failed and re-enqueued
    (:meth:`StudyStore.reap`), the study's finished and running trials are counted, and a
    trial is asked only while finished + running < budget. So any number of processes, on any
    number of machines, run exactly the budget; a process that finds the rest running waits
    for them (one of them may die and need a retry). Returns the trials this process walked.
    """
    log = log or (lambda msg: print(f"gait-tuner: {msg}", file=sys.stderr, flush=True))
    study = open_study(spec, store.optuna_storage(), seed)
    objective = objective_for(spec, Evaluator(spec))
    space = trial_distributions(spec)
    beat = Heartbeat(store, spec.name).start()
    ran = 0
    try:
        while True:
            with store.budget_lock(spec.name):
                for note in store.reap(study):
                    log(note)
                done, running = _counts(study)
                if done >= budget:
                    return ran
                trial = None
                if done + running < budget:
                    trial = study.ask(space)
                    trial.set_user_attr("worker", process_identity())
            if trial is None:
                time.sleep(poll)
                continue
            beat.trial_id = trial._trial_id
            source = None if trial.user_attrs.get("retry_of") is not None else _duplicate_of(study, trial)
            if source is not None:
                _tell_copy(study, trial, source)
                continue
            try:
                value = objective(trial)
            except optuna.TrialPruned:
                study.tell(trial, state=TrialState.PRUNED)
            except BaseException as exc:
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


def _die_with_parent(parent: int) -> None:
    """Linux: the kernel kills this process when its parent dies (no orphaned workers)."""
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)    # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:
        os._exit(1)


def _worker(spec: StudySpec, store: StudyStore, budget: int, seed: int, parent: int, errors: Any) -> None:
    """A worker process: :func:`work`; bad input or a full disk goes back to the parent as one line."""
    _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)       # the parent decides what Ctrl-C stops
    os.environ.setdefault("MPLBACKEND", "Agg")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    store = StudyStore(journal=store.journal, url=store.url, grace_s=store.grace_s,
                       interval_s=store.interval_s)                   # open afresh after fork
    try:
        work(spec, store, budget, seed)
    except (UserError, ParamError) as exc:
        errors.put(str(exc))
        sys.exit(2)


def _sampler_seed(seed: int, index: int, existing: int) -> int:
    # offset by the trials already stored: a resumed study does not re-draw its first samples
    return (seed + 1000 * index + 7919 * existing) % (2 ** 31)


def prepare_study(spec: StudySpec, store: StudyStore, budget: int | None, seed: int) -> tuple[optuna.Study, int]:
    """Create or join the study; once per study (whoever comes first), enqueue the CasADi seed
    and the baselines; set the shared budget (``budget`` None: keep the stored one, or the
    file's). Returns the study and the budget."""
    study = None
    with store.budget_lock(spec.name):
        study = open_study(spec, store.optuna_storage(), seed)
        enqueue_starts(study, spec)
        stored = study.user_attrs.get("budget")
        if budget is None:
            budget = int(stored) if stored is not None else spec.trials
        if stored != budget:
            study.set_user_attr("budget", budget)
        for note in store.reap(study):
            print(f"gait-tuner: {note}", file=sys.stderr)
    return study, budget


def run_study(spec: StudySpec, store: StudyStore, total: int | None, workers: int,
              seed: int, on_progress: Callable[[optuna.Study], None] | None = None,
              poll: float = 0.5, log: Callable[[str], None] | None = None) -> optuna.Study:
    """Run until the study holds its budget of finished trials, with ``workers`` processes here
    (other machines' ``worker`` processes may share the same budget). A worker that dies is
    replaced (its trial is retried by the others); bad input or a full disk in a worker stops
    all of them and is raised here as one line."""
    study, budget = prepare_study(spec, store, total, seed)
    return run_workers(spec, store, study, budget, workers, seed, on_progress, poll, log)


def run_workers(spec: StudySpec, store: StudyStore, study: optuna.Study, budget: int, workers: int,
                seed: int, on_progress: Callable[[optuna.Study], None] | None = None,
                poll: float = 0.5, log: Callable[[str], None] | None = None) -> optuna.Study:
    """:func:`run_study` after :func:`prepare_study` (which gave ``study`` and ``budget``)."""
    log = log or (lambda msg: print(f"gait-tuner: {msg}", file=sys.stderr, flush=True))
    if _n_done(study) >= budget:
        return study
    ctx = mp_context()
    errors = ctx.Queue()
    existing = len(study.get_trials(deepcopy=False))
    parent = os.getpid()

    def spawn(index: int) -> Any:
        p = ctx.Process(target=_worker, args=(spec, store, budget, _sampler_seed(seed, index, existing),
                                              parent, errors), daemon=False)
        p.start()
        return p

    n = max(1, min(workers, budget - _n_done(study)))
    procs = {i: spawn(i) for i in range(n)}
    respawns = 0
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
                how = f"signal {-p.exitcode}" if p.exitcode < 0 else f"exit code {p.exitcode}"
                if p.exitcode > 0 or respawns >= 2 * n:
                    raise RuntimeError(f"worker {i} failed ({how}); see its message above")
                respawns += 1
                log(f"worker {i} died ({how}); its trial will be retried; starting another")
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


def _n_done(study: optuna.Study) -> int:
    return len(study.get_trials(deepcopy=False, states=DONE_STATES))


def best_trial(study: optuna.Study, number: int | None = None) -> optuna.trial.FrozenTrial:
    """A chosen trial, or the best feasible one (lowest pitch score; the Pareto point with the
    lowest pitch for two objectives)."""
    trials = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    if number is not None:
        for t in trials:
            if t.number == number:
                return t
        raise KeyError(f"study {study.study_name!r} has no completed trial {number}")
    if not trials:
        raise KeyError(f"study {study.study_name!r} has no completed trial yet")
    feasible = [t for t in trials if trial_result(t).get("fall_constraint", 1.0) <= 0] or trials
    if study.directions[0] == optuna.study.StudyDirection.MAXIMIZE:
        return max(feasible, key=lambda t: t.values[0])
    return min(feasible, key=lambda t: t.values[0])


PARETO_PICKS = ("pitch", "speed", "knee")


def pareto_pick(study: optuna.Study, how: str) -> optuna.trial.FrozenTrial:
    """One trial of a (pitch score, speed) study's Pareto front of feasible trials.

    ``pitch``: the lowest pitch score; ``speed``: the fastest; ``knee`` (ours): the point
    nearest the utopia corner (lowest pitch, highest speed) once both objectives are scaled
    to [0, 1] over the front: the best compromise when neither objective is preferred.
    """
    if how not in PARETO_PICKS:
        raise KeyError(f"--pareto-pick {how!r}: choose {', '.join(PARETO_PICKS)}")
    if len(study.directions) != 2:
        raise KeyError(f"--pareto-pick needs a two-objective study (pitch_rms, speed); "
                       f"{study.study_name!r} has {len(study.directions)} objective(s)")
    front = [t for t in study.best_trials if trial_feasible(t)]
    if not front:
        raise KeyError(f"study {study.study_name!r} has no feasible trial on its Pareto front")
    if how == "pitch":
        return min(front, key=lambda t: (t.values[0], -t.values[1]))
    if how == "speed":
        return max(front, key=lambda t: (t.values[1], -t.values[0]))
    p = np.array([t.values[0] for t in front])
    v = np.array([t.values[1] for t in front])
    p_n = (p - p.min()) / max(float(np.ptp(p)), 1e-12)
    v_n = (v.max() - v) / max(float(np.ptp(v)), 1e-12)
    return front[int(np.argmin(p_n ** 2 + v_n ** 2))]


def trial_params(spec_gait: str, trial: optuna.trial.FrozenTrial) -> gaits.GaitParams:
    """The full, validated parameter set a trial walked."""
    data = trial.user_attrs.get("params")
    if data is None:
        raise KeyError(f"trial {trial.number} recorded no parameters (it was rejected: "
                       f"{trial_result(trial).get('invalid') or 'unknown reason'})")
    data = {k: v for k, v in data.items() if k != "stabiliser"}
    return gaits.params_from_mapping(spec_gait, data, f"trial {trial.number}")


def trial_stabiliser(trial: optuna.trial.FrozenTrial) -> gaits.StabiliserParams | None:
    """The IMU stabiliser a trial walked with, or None (open loop)."""
    data = (trial.user_attrs.get("params") or {}).get("stabiliser")
    return None if data is None else gaits.StabiliserParams(**data)


def trial_result(trial: optuna.trial.FrozenTrial) -> dict[str, Any]:
    """What a trial recorded: fell, fall_constraint, per_surface metrics, invalid (reason)."""
    return trial.user_attrs.get("result", {})


def trial_fell(trial: optuna.trial.FrozenTrial) -> bool:
    return bool(trial_result(trial).get("fell", True))


def trial_feasible(trial: optuna.trial.FrozenTrial) -> bool:
    """The search's own notion of a usable gait: it stayed up and walked at least
    ``MIN_PROGRESS`` of its plan on every surface (constraint value <= 0)."""
    constraint = trial_result(trial).get("fall_constraint")
    return trial.state == TrialState.COMPLETE and constraint is not None and constraint <= 0.0
