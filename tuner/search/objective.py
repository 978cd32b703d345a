"""A trial of a study: what it walks for one sampled set, and what the study stores of it.

The objective (:func:`objective_for`) turns a sampled trial into a :class:`gaits.Drive` (the set,
its stabiliser and engine, or a controller of the user's own with the sampled values) and asks the
:class:`Evaluator` to walk it in the study's scenario (``tuner/scenarios``: plain walks, randomised
walks, match walks, the push-recovery challenge, speed staircases; each file there says how it
scores). What every study shares lives here: the fall constraint stored where Optuna and the
dashboard read it (> 0: infeasible: a fall, too little progress, survival below the study's
minimum), the trial's parameters and result as user attributes, a set the generators reject
scoring the worst value of each objective, a hopeless randomised trial recorded as pruned, and
the median pruner's reports for scenarios that prune (plain walks of one objective).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import optuna

import gaits
from gaits import ParamError

from ..scenarios import World
from ..scenarios.base import FALL_PENALTY_DEG, PROGRESS_PENALTY_DEG, TrialResult, rollout_score
from ..sim.metrics import MIN_PROGRESS
from ..store import optuna_compat as compat
from .study import OBJECTIVES, StudySpec

__all__ = ["FALL_PENALTY_DEG", "PROGRESS_PENALTY_DEG", "MIN_PROGRESS", "TrialResult", "Evaluator", "rollout_score",
           "record_constraint", "suggest", "objective_for"]


@dataclass
class Evaluator:
    """Walks trial parameters in the study's scenario, on its robot and surfaces (a
    :class:`tuner.scenarios.World`, one simulator per surface, reused). ``threads``: how many
    threads a trial's walks of one surface share (see :class:`World`)."""

    spec: StudySpec
    threads: int = 1

    def __post_init__(self) -> None:
        spec = self.spec
        # a controller of the user's own walks on the main thread only: its time limits are signals
        threads = 1 if spec.controller is not None else self.threads
        self.world = World(spec.robot, spec.surfaces, aggregate=spec.aggregate, duration=spec.duration,
                           threads=threads)
        self.robot, self.sims = self.world.robot, self.world.sims

    def evaluate(self, drive: gaits.Drive, report: Callable[[float, int], bool] | None = None) -> TrialResult:
        """Per-surface metrics and the aggregate score of what ``drive`` walks (a trial's set and
        stabiliser); ``report(value, step)`` for scenarios that prune."""
        room = self.spec.scenario_room
        return room.evaluate(self.spec.settings, drive, self.world, report if room.prunes else None)


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

        res = evaluator.evaluate(drive, report)
        # two journal writes per trial (params, result): workers contend for the file lock
        record_constraint(trial, res.fall_constraint)
        walked = {"controller": dict(drive.user.params)} if drive.user is not None else drive.params.to_mapping()
        if drive.stabiliser is not None:
            walked["stabiliser"] = drive.stabiliser.to_mapping()
        if drive.engine is not None:
            walked["engine"] = drive.engine.to_mapping()
        trial.set_user_attr("params", walked)
        trial.set_user_attr("result", res.stored())
        for key, value in (res.attrs or {}).items():
            trial.set_user_attr(key, value)
        if res.hopeless:
            minimum = spec.scenario_room.min_survival(spec.settings)
            raise optuna.TrialPruned(f"survival already below {minimum:.0%}")
        if res.values is not None:
            return res.values if len(res.values) > 1 else res.values[0]
        if len(spec.objectives) > 1:
            return res.score, res.speed
        return res.score
    return objective
