"""A trial's score: what a study walks for one sampled set, and how the walk is scored.

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

The objective (:func:`objective_for`) turns a sampled trial into a :class:`gaits.Drive` (the set,
its stabiliser, or a controller of the user's own with the sampled values) and asks the
:class:`Evaluator` to walk it on the study's robot and surfaces.
"""

from __future__ import annotations

import math
import queue
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np
import optuna

import gaits
from gaits import ParamError, UnreachableTargetError

from ..sim import cache as sim_cache
from ..sim.metrics import MIN_PROGRESS, planned_forward_distance, summarize
from ..sim.randomisation import TUNE, draw
from ..sim.rollout import Simulator
from . import optuna_compat as compat
from .study import OBJECTIVES, StudySpec

__all__ = ["FALL_PENALTY_DEG", "PROGRESS_PENALTY_DEG", "MIN_PROGRESS", "TrialResult", "Evaluator", "rollout_score",
           "record_constraint", "suggest", "objective_for"]

FALL_PENALTY_DEG = 100.0
PROGRESS_PENALTY_DEG = 50.0     # per unit of the planned distance not covered


@dataclass(frozen=True)
class TrialResult:
    """What the evaluation of one trial found (the objective stores :meth:`stored` with the trial)."""

    score: float                      # the first objective: pitch score [deg], or the speed score
    speed: float                      # [m/s] mean forward speed (speed studies: the forward stair held)
    fall_constraint: float            # <= 0 feasible; > 0 how far from it (a fall, too little progress)
    fell: bool                        # a walk of this trial fell
    per_surface: dict                 # per surface: its metrics (robust: survival, rollouts, median pitch)
    invalid: str | None = None        # why the set could not be walked at all (a rejected set)
    survival: float | None = None     # robust studies: share of the randomised walks that stayed up
    hopeless: bool | None = None      # robust studies: stopped early, survival already below its minimum
    values: tuple | None = None       # speed studies: every objective's value
    by_direction: dict | None = None  # speed studies: the highest stair held per direction
    pitch_rms_deg: float | None = None   # speed studies: the pitch term [deg]

    def stored(self) -> dict[str, Any]:
        """The trial's ``result`` user attribute (JSON in the storage; ``trials.trial_result`` reads it)."""
        return {"fell": self.fell, "fall_constraint": self.fall_constraint, "per_surface": self.per_surface,
                "invalid": self.invalid, "survival": self.survival, "hopeless": self.hopeless}


@dataclass
class Evaluator:
    """Walks trial parameters on the study's robot and surfaces (one Simulator per surface, reused).

    ``threads``: the walks of one surface that a trial makes (a robust trial's randomised walks,
    an engine study's match walks, a speed study's directions) run on this many threads, each
    on its own copy of the surface's simulator (MuJoCo steps without Python's lock, so two
    threads walk ~1.9x as fast on 2 cores while the tick logic is light); the walks are the same
    and are consumed in order, so the result, the early stop included, is the one-at-a-time
    result (tested)."""

    spec: StudySpec
    threads: int = 1

    def __post_init__(self) -> None:
        self.robot = sim_cache.robot(self.spec.robot)
        self.sims = [sim_cache.simulator(self.robot, s) for s in self.spec.surfaces]
        self._copies: dict[int, "queue.SimpleQueue"] = {}
        self._challenge_sims: list[Simulator] | None = None     # the challenge's scenes, built on first use

    def _in_order(self, n: int, walk: Callable[[Any, int], Any],
                  sims: list | None = None) -> Iterator[tuple[str, Any]]:
        """``(surface, walk(simulator, i))`` for every surface of the study in turn and i in
        0..n-1, yielded in that order; on ``self.threads`` threads when more than one (one stream
        over all surfaces, so no thread waits at a surface's end), each walk on a free copy of its
        surface's simulator (of ``sims``, one per surface, when given: the challenge's, with its
        pendulum); what the caller does not consume is cancelled."""
        sims = self.sims if sims is None else sims
        tasks = [(name, sim, i) for name, sim in zip(self.spec.surfaces, sims) for i in range(n)]
        if self.threads <= 1 or len(tasks) <= 1:
            for name, sim, i in tasks:
                yield name, walk(sim, i)
            return
        for sim in sims:
            if id(sim) not in self._copies:
                free = self._copies[id(sim)] = queue.SimpleQueue()
                free.put(sim)
                for _ in range(self.threads - 1):
                    free.put(Simulator(self.robot, sim.surface, pendulum=sim.rope))

        def task(sim: Any, i: int) -> Any:
            free = self._copies[id(sim)]
            s = free.get()
            try:
                return walk(s, i)
            finally:
                free.put(s)
        with ThreadPoolExecutor(self.threads) as pool:
            futures = [(name, pool.submit(task, sim, i)) for name, sim, i in tasks]
            try:
                for name, f in futures:
                    yield name, f.result()
            finally:
                for _, f in futures:
                    f.cancel()

    def evaluate(self, drive: gaits.Drive, report: Callable[[float, int], bool] | None = None) -> TrialResult:
        """Per-surface metrics and the aggregate score of what ``drive`` walks (a trial's set and
        stabiliser)."""
        spec = self.spec
        if spec.challenge is not None:
            return self._evaluate_challenge(drive)
        if spec.speed is not None:
            return self._evaluate_speed(drive.params, drive.stabiliser)
        if spec.scenario is not None:
            return self._evaluate_scenario(drive)
        dt = self.sims[0].control_period
        try:
            if drive.online:                    # no table: its walk lasts the study's duration
                traj, planned, plan_dist = None, float(spec.duration), 0.0
                drive.controller(self.robot, dt)       # a controller that cannot be built: invalid, at once
            else:
                traj = drive.table(self.robot, dt)
                planned = traj.duration - float(traj.t[np.flatnonzero(traj.support != 0)[0]]) \
                    if np.any(traj.support != 0) else traj.duration
                plan_dist = planned_forward_distance(traj)
        except (ParamError, UnreachableTargetError) as exc:
            return TrialResult(score=FALL_PENALTY_DEG * 2, speed=0.0, fall_constraint=1.0, fell=True,
                               per_surface={}, invalid=str(exc))
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
            speeds.append(0.0 if not m.survived else m.speed_mps)
            walked.append(frac if not m.survived else 1.0 + 1e-9)
            per[name] = m.to_dict()
            if report is not None and report(self._aggregate(scores), i):
                raise optuna.TrialPruned()
        fell_any = any(not v["survived"] for v in per.values())
        constraint = (1.0 - min(walked) + 1e-3) if fell_any else (shortfall if shortfall > 0 else -1.0)
        return TrialResult(score=self._aggregate(scores), speed=float(np.mean(speeds)),
                           fall_constraint=constraint, fell=fell_any, per_surface=per)

    def _evaluate_robust(self, drive: gaits.Drive, traj: gaits.GaitTrajectory | None, planned: float,
                         plan_dist: float) -> TrialResult:
        """K randomised rollouts per surface (tuning seeds 0..K-1, common to all trials), scored by
        the study's risk measure; survival below ``min_survival`` is infeasible, and a trial whose
        falls already exceed what that allows stops early (``hopeless``)."""
        rb = self.spec.robust
        total = rb.rollouts * len(self.sims)
        allowed = math.floor((1.0 - rb.min_survival) * total + 1e-9)
        scores, speeds, covered_all, per = [], [], [], {}
        falls = 0
        hopeless = False

        def walk(sim: Any, i: int) -> Any:
            p = draw(rb.randomisation, i, *sim.n_random(), namespace=TUNE)
            return summarize(sim.run(drive.controller(self.robot, sim.control_period, table=traj),
                                     perturb=p, **{**drive.run_options(), "duration": self.spec.duration}))

        rows_of: dict[str, list] = {}
        for name, m in self._in_order(rb.rollouts, walk):
            rows = rows_of.setdefault(name, [])
            score, _, covered = rollout_score(m, planned, plan_dist)
            scores.append(score)
            if not m.survived:
                falls += 1
            else:
                speeds.append(m.speed_mps)
                if covered is not None:
                    covered_all.append(covered)
            rows.append({"fell": not m.survived, "outcome": m.outcome, "pitch_rms_deg": m.pitch_rms_deg,
                         "speed_mps": m.speed_mps,
                         "t_fall_s": m.t_fall_s})
            if falls > allowed:
                hopeless = True
                break
        for name, rows in rows_of.items():
            per[name] = {"survival": float(np.mean([not r["fell"] for r in rows])), "rollouts": len(rows),
                         "fell": any(r["fell"] for r in rows),
                         "pitch_rms_deg": float(np.median([r["pitch_rms_deg"] for r in rows]))}
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
        return TrialResult(score=risk, speed=float(np.mean(speeds)) if speeds else 0.0, fall_constraint=constraint,
                           fell=falls > 0, per_surface=per, survival=survival, hopeless=hopeless)

    def _evaluate_scenario(self, drive: gaits.Drive) -> TrialResult:
        """K match walks per surface (``tuner/sim/scenario.py``; tuning seeds 0..K-1, the same for
        every trial) under the study's randomisation; each walk scored pitch RMS [deg] +
        ``tracking_weight`` x (vx + vy RMSE [m/s] + 0.1 wz RMSE [rad/s]), a fall the full penalty
        times the share of the walk not walked; the trial's score their mean. Survival below
        ``min_survival`` is infeasible, and a trial whose falls already exceed what that allows
        stops at once (``hopeless``)."""
        from ..sim.robustness import walk_scenario
        from ..sim.scenario import draw_scenario
        sc = self.spec.scenario
        total = sc.walks * len(self.sims)
        allowed = math.floor((1.0 - sc.min_survival) * total + 1e-9)
        scores, per, falls, hopeless = [], {}, 0, False
        rmse = []

        def walk(sim: Any, i: int) -> dict:
            stream, pushes = draw_scenario(sc.scenario, i, TUNE)
            p = draw(sc.randomisation, i, *sim.n_random(), namespace=TUNE)
            return walk_scenario(sim, drive, stream, pushes, p)

        rows_of: dict[str, list] = {}
        for name, r in self._in_order(sc.walks, walk):
            tk = r["tracking"] or {}
            err = sum(v for v in (tk.get("vx_rmse_mps"), tk.get("vy_rmse_mps")) if v is not None) \
                + 0.1 * (tk.get("wz_rmse_radps") or 0.0)
            score = (r["pitch_rms_deg"] or 0.0) + sc.tracking_weight * err
            if not r["survived"]:
                falls += 1
                score += FALL_PENALTY_DEG * (1.0 - min(max(r["walked"], 0.0), 1.0))
            else:
                rmse.append(err)
            scores.append(score)
            rows_of.setdefault(name, []).append(r)
            if falls > allowed:
                hopeless = True
                break
        for name, rows in rows_of.items():
            per[name] = {"survival": float(np.mean([r["survived"] for r in rows])), "rollouts": len(rows),
                         "fell": any(not r["survived"] for r in rows)}
        survival = 1.0 - falls / len(scores)
        constraint = (sc.min_survival - (1.0 - falls / total) + 1e-3) if (survival < sc.min_survival or hopeless) else -1.0
        return TrialResult(score=float(np.mean(scores)), speed=0.0, fall_constraint=constraint, fell=falls > 0,
                           per_surface=per, survival=survival, hopeless=hopeless)

    def _evaluate_challenge(self, drive: gaits.Drive) -> TrialResult:
        """The push-recovery challenge (``tuner/sim/challenge.py``) per surface and push seed of the
        study's ``challenge:`` section; the one objective, ``push_distance``, is per surface the mean
        over the seeds of the largest fully successful D [m] (``start - step`` where even ``start``
        fails: worse than any success, and still ordered), then the worst surface's or the mean over
        surfaces, as the study's ``aggregate`` says. Always feasible: a trial that takes no push
        scores low, not infeasible (ours: the sampler then learns from every trial's distance)."""
        from ..sim.challenge import challenge
        ch = self.spec.challenge
        if self._challenge_sims is None:
            self._challenge_sims = [Simulator(self.robot, sim.surface, pendulum=ch.rope) for sim in self.sims]
        floor = ch.start - ch.step

        def walk(sim: Any, i: int) -> dict:
            return challenge(sim, drive, seed=ch.seeds[i], start=ch.start, step=ch.step)

        per: dict[str, dict] = {}
        distances: dict[str, list[float]] = {}
        try:
            for name, r in self._in_order(len(ch.seeds), walk, self._challenge_sims):
                d = r["best_distance_m"]
                distances.setdefault(name, []).append(floor if d is None else float(d))
                row = per.setdefault(name, {"best_distance_m": [], "momentum_Ns": []})
                row["best_distance_m"].append(d)
                row["momentum_Ns"].append(r["momentum_Ns"])
        except (ParamError, UnreachableTargetError) as exc:
            return TrialResult(score=floor, speed=0.0, fall_constraint=1.0, fell=True, per_surface={},
                               invalid=str(exc), values=(floor,))
        means = [float(np.mean(v)) for v in distances.values()]
        score = min(means) if self.spec.aggregate == "worst" else float(np.mean(means))
        return TrialResult(score=score, speed=0.0, fall_constraint=-1.0, fell=False, per_surface=per,
                           values=(score,))

    def _evaluate_speed(self, params: gaits.GaitParams, stabiliser: Any) -> TrialResult:
        """A speed study's trial: every direction's staircase on every surface
        (``tuner/sim/walk_speed.py``); per direction the worst (or mean) surface's highest stair
        held, weighted, less the pitch term. Infeasible unless every direction holds at least
        its first stair on every surface."""
        from ..sim.walk_speed import speed_test
        sp = self.spec.speed
        per: dict[str, dict] = {}
        reached: dict[str, list[float]] = {d: [] for d, _, _ in sp.directions}
        pitches, misses, fell = [], 0, False

        def walk(sim: Any, i: int) -> Any:
            d, top, _ = sp.directions[i]
            return speed_test(sim, params, sp.staircase(d, top), sp.tolerance, stabiliser)

        n = len(sp.directions)
        for k, (name, r) in enumerate(self._in_order(n, walk)):
            d = sp.directions[k % n][0]
            per.setdefault(name, {})[d] = {"reached": r.reached, "measured": r.measured, "fell": r.fell,
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
        return TrialResult(score=score, speed=by_dir.get("forward", 0.0), fall_constraint=constraint, fell=fell,
                           per_surface=per, values=values, by_direction=by_dir, pitch_rms_deg=pitch)

    def _aggregate(self, scores: list[float]) -> float:
        return float(max(scores) if self.spec.aggregate == "worst" else np.mean(scores))

def rollout_score(m: Any, planned: float, plan_dist: float) -> tuple[float, float, float | None]:
    """One rollout's score [deg] (see the module docstring), its walked fraction and, when it
    stayed up and had somewhere to go, the covered fraction of its planned distance."""
    failed = not m.survived                # a fall, and a diverged or impossible walk just the same
    frac = 1.0 if not failed else float(np.clip(m.walk_time_s / max(planned, 1e-9), 0, 1))
    score = m.pitch_rms_deg + (FALL_PENALTY_DEG * (1.0 - frac) if failed else 0.0)
    if failed and frac >= 1.0:
        score += 1.0
    covered = None
    if not failed and abs(plan_dist) > 1e-3:
        covered = float(np.clip(m.distance_m / plan_dist, 0.0, 1.0))
        score += PROGRESS_PENALTY_DEG * (1.0 - covered)
    return score, frac, covered

def record_constraint(trial: optuna.Trial, value: float) -> None:
    """Store the fall constraint (> 0: fell or walked too little) as the list-valued system
    attribute ``constraints``: Optuna 5 reads it as constraint "0" (``FrozenTrial.constraints``,
    feasibility in TPE and ``best_trials``), and optuna-dashboard (0.21) reads only this key,
    not the per-name keys of ``Trial.set_constraint``, so fallen trials show as infeasible there."""
    trial.storage.set_trial_system_attr(compat.trial_id(trial), "constraints", [float(value)])

def suggest(trial: optuna.Trial, spec: StudySpec) -> dict[str, Any]:
    """Sample (or, called again, read back) every parameter of the study's space for ``trial``,
    by field name; the worker calls it outside the budget lock, the objective again."""
    out = {}
    for r in spec.space:
        if r.integer:
            out[r.name] = trial.suggest_int(r.label, int(math.ceil(r.low)), int(math.floor(r.high)), log=r.log)
        else:
            out[r.name] = trial.suggest_float(r.label, r.low, r.high, log=r.log)
    return out

def objective_for(spec: StudySpec, evaluator: Evaluator) -> Callable[[optuna.Trial], Any]:
    def objective(trial: optuna.Trial):
        sampled = suggest(trial, spec)
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

        res = evaluator.evaluate(drive, None if spec.speed is not None or spec.challenge is not None else report)
        # two journal writes per trial (params, result): workers contend for the file lock
        record_constraint(trial, res.fall_constraint)
        walked = {"controller": dict(drive.user.params)} if drive.user is not None else drive.params.to_mapping()
        if drive.stabiliser is not None:
            walked["stabiliser"] = drive.stabiliser.to_mapping()
        if drive.engine is not None:
            walked["engine"] = drive.engine.to_mapping()
        trial.set_user_attr("params", walked)
        trial.set_user_attr("result", res.stored())
        if res.hopeless:
            minimum = (spec.scenario or spec.robust).min_survival
            raise optuna.TrialPruned(f"survival already below {minimum:.0%}")
        if res.values is not None:
            if spec.speed is not None:
                trial.set_user_attr("speed", {"by_direction": res.by_direction, "score": res.score,
                                              "pitch_rms_deg": res.pitch_rms_deg})
            return res.values if len(res.values) > 1 else res.values[0]
        if len(spec.objectives) > 1:
            return res.score, res.speed
        return res.score
    return objective
