"""Plain walks: the scenario of a study without a scenario section.

Each trial's set walks once per surface of the study (deterministic: no randomisation); each
walk is scored by :func:`tuner.scenarios.base.rollout_score` and the trial's score is the worst
(max) or the mean over surfaces, as the study's ``aggregate`` says. A fall, and covering less
than ``MIN_PROGRESS`` of the planned forward distance, are infeasible (the constraint's value says
how far). Single-objective studies report the running aggregate after each surface, so the
median pruner can stop a trial that is already hopeless on its first surfaces. Optional second
objective: forward speed [m/s] (maximised; 0 on a fall), for a Pareto front.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np
import optuna

from gaits import ParamError, UnreachableTargetError

from ..sim.metrics import MIN_PROGRESS, summarize
from .base import Scenario, TrialResult, invalid_result, register, rollout_score


class Walk(Scenario):
    name = "walk"
    section = None
    prunes = True

    def parse(self, sec: Any, doc: Mapping[str, Any], source: str) -> None:
        return None

    def evaluate(self, settings: Any, drive: Any, world: Any,
                 report: Callable[[float, int], bool] | None = None) -> TrialResult:
        try:
            traj, planned, plan_dist = world.plan(drive)
        except (ParamError, UnreachableTargetError) as exc:
            return invalid_result(str(exc))
        dt = world.control_period
        scores, speeds, walked, per = [], [], [], {}
        shortfall = 0.0
        for i, (name, sim) in enumerate(zip(world.surfaces, world.sims)):
            m = summarize(sim.run(drive.controller(world.robot, dt, table=traj),
                                  **{**drive.run_options(), "duration": world.duration}))
            score, frac, covered = rollout_score(m, planned, plan_dist)
            if covered is not None:
                shortfall = max(shortfall, MIN_PROGRESS - covered)
            scores.append(score)
            speeds.append(0.0 if not m.survived else m.speed_mps)
            walked.append(frac if not m.survived else 1.0 + 1e-9)
            per[name] = m.to_dict()
            if report is not None and report(world.aggregate(scores), i):
                raise optuna.TrialPruned()
        fell_any = any(not v["survived"] for v in per.values())
        constraint = (1.0 - min(walked) + 1e-3) if fell_any else (shortfall if shortfall > 0 else -1.0)
        return TrialResult(score=world.aggregate(scores), speed=float(np.mean(speeds)),
                           fall_constraint=constraint, fell=fell_any, per_surface=per)


register(Walk())
