"""Randomised walks (a study's ``robust:`` section): K rollouts per surface per trial under domain
randomisation (``tuner/sim/randomisation.py``).

Seeds 0..K-1 of the tuning stream, the same for every trial, so trials are compared on the same
draws. Each walk is scored as a plain walk (:func:`tuner.scenarios.base.rollout_score`); all of
them are aggregated by the study's risk measure (``cvar25``: the mean of the worst quarter;
``worst``; ``mean``). Survival below ``min_survival`` is infeasible, and a trial whose falls
already exceed what that allows stops at once (``hopeless``, recorded as pruned). A table that
stays up but covers less than ``MIN_PROGRESS`` of its plan (median over the walks) is infeasible
too.

    robust:
      rollouts: 8          # K per surface per trial
      risk: cvar25         # cvar25 (mean of the worst quarter), worst, or mean of the scores
      min_survival: 0.95   # below this fraction of rollouts standing: infeasible (stopped early)
      randomisation: {}    # overrides of tuner/sim/randomisation.py's defaults, or none
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from gaits import ParamError, UnreachableTargetError

from ..errors import UserError
from ..sim.metrics import MIN_PROGRESS, summarize
from ..sim.randomisation import draw, randomisation_from_mapping
from .base import (Scenario, TrialResult, check_section, fail, invalid_result, register, rollout_score,
                   survival_constraint, describe_randomised)

RISKS = ("cvar25", "worst", "mean")


@dataclass(frozen=True)
class RobustSpec:
    """A robust study's evaluation: K randomised rollouts per surface (see tuner/sim/randomisation.py)."""

    rollouts: int = 8                 # K per surface per trial
    risk: str = "cvar25"              # cvar25 | worst | mean over all rollouts' scores
    min_survival: float = 0.95        # [-] fraction of rollouts that must stay up
    randomisation: Any = None         # tuner.randomisation.Randomisation


class Robust(Scenario):
    name = "robust"
    section = "robust"

    def parse(self, sec: Any, doc: Mapping[str, Any], source: str) -> RobustSpec:
        check_section(sec, "robust", ("rollouts", "risk", "min_survival", "randomisation"), source)
        k = sec.get("rollouts", 8)
        if not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= 1000:
            fail(source, f"robust.rollouts = {k!r}: expected a whole number in [1, 1000]")
        risk = sec.get("risk", "cvar25")
        if risk not in RISKS:
            fail(source, f"robust.risk = {risk!r}: expected one of {', '.join(RISKS)}")
        ms = sec.get("min_survival", 0.95)
        if not isinstance(ms, (int, float)) or isinstance(ms, bool) or not 0.0 <= ms <= 1.0:
            fail(source, f"robust.min_survival = {ms!r}: expected a fraction in [0, 1]")
        try:
            rnd = randomisation_from_mapping(sec.get("randomisation"), "robust.randomisation")
        except UserError as exc:
            fail(source, str(exc))
        return RobustSpec(k, risk, float(ms), rnd)

    def evaluate(self, rb: RobustSpec, drive: Any, world: Any,
                 report: Callable[[float, int], bool] | None = None) -> TrialResult:
        try:
            traj, planned, plan_dist = world.plan(drive)
        except (ParamError, UnreachableTargetError) as exc:
            return invalid_result(str(exc))
        total = rb.rollouts * len(world.sims)
        allowed = math.floor((1.0 - rb.min_survival) * total + 1e-9)
        scores, speeds, covered_all, per = [], [], [], {}
        falls = 0
        stood = 0.0                     # the walks run, each by the share of it walked
        hopeless = False

        def walk(sim: Any, i: int) -> Any:
            p = draw(rb.randomisation, i, *sim.n_random(), namespace=world.namespace)
            return summarize(sim.run(drive.controller(world.robot, sim.control_period, table=traj),
                                     perturb=p, **{**drive.run_options(), "duration": world.duration}))

        rows_of: dict[str, list] = {}
        for name, m in world.in_order(rb.rollouts, walk):
            rows = rows_of.setdefault(name, [])
            score, frac, covered = rollout_score(m, planned, plan_dist)
            scores.append(score)
            stood += frac
            if not m.survived:
                falls += 1
            else:
                speeds.append(m.speed_mps)
                if covered is not None:
                    covered_all.append(covered)
            rows.append({"fell": not m.survived, "pitch_rms_deg": m.pitch_rms_deg})
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
        constraint = survival_constraint(rb.min_survival, falls, total, len(scores), hopeless, stood)
        if constraint is not None:
            pass
        elif progress < MIN_PROGRESS:
            constraint = MIN_PROGRESS - progress
        else:
            constraint = -1.0
        return TrialResult(score=risk, speed=float(np.mean(speeds)) if speeds else 0.0, fall_constraint=constraint,
                           fell=falls > 0, per_surface=per, survival=survival, hopeless=hopeless)


    def describe_best(self, rb: RobustSpec, trial: Any, *, fell: bool, falls: int, infeasible: int) -> str:
        return describe_randomised(trial, rb.min_survival, infeasible, f"randomised walks ({rb.rollouts} a surface)")


register(Robust())
