"""Match walks (a study's ``scenario:`` section): K command streams with pushes per surface per
trial, drawn from a stated distribution (``tuner/sim/match_walks.py``), under the randomisation.

Seeds 0..K-1 of the tuning stream, the same for every trial. Each walk is scored pitch RMS [deg]
+ ``tracking_weight`` x (vx + vy RMSE [m/s] + 0.1 wz RMSE [rad/s]), a fall the full penalty times
the share of the walk not walked; the trial's score is their mean. Survival below
``min_survival`` is infeasible, and a trial whose falls already exceed what that allows stops at
once (``hopeless``).

    scenario:
      walks: 6              # scenario seeds 0..K-1 of the tuning stream, the same every trial
      min_survival: 0.9     # below this share of walks standing: infeasible (stops early)
      tracking_weight: 10.0 # [deg per m/s]
      randomisation: {}     # overrides of tuner/sim/randomisation.py's defaults, or none
      servo_share: 0.95     # optional: a walk whose targets ask any servo for more than this share of
                            #   its speed makes the trial infeasible (so its export's servo table plays)
      forward: 0.3          # the distribution: any field of tuner/sim/match_walks.py
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from ..errors import UserError
from ..sim.randomisation import draw, randomisation_from_mapping
from ..sim.robustness import walk_scenario
from ..sim.match_walks import SCENARIO_FIELDS, draw_scenario, scenario_from_mapping
from .base import (FALL_PENALTY_DEG, Scenario, TrialResult, check_section, describe_randomised, fail, register,
                   survival_constraint)


@dataclass(frozen=True)
class ScenarioSpec:
    """A scenario study's walks: K match walks per surface (``tuner/sim/match_walks.py``)."""

    walks: int = 6
    min_survival: float = 0.9
    tracking_weight: float = 10.0      # [deg per m/s]
    randomisation: Any = None          # tuner.sim.randomisation.Randomisation
    scenario: Any = None               # tuner.sim.match_walks.MatchDistribution
    servo_share: float | None = None   # the most of a servo's speed a walk may ask (None: not checked)


class Match(Scenario):
    name = "match"
    section = "scenario"
    excludes = {"robust": "a scenario study has its own randomised walks",
                "speed": "a scenario study has its own randomised walks"}

    def parse(self, sec: Any, doc: Mapping[str, Any], source: str) -> ScenarioSpec:
        check_section(sec, "scenario", ("walks", "min_survival", "tracking_weight", "randomisation", "servo_share")
                      + SCENARIO_FIELDS, source)
        k = sec.get("walks", 6)
        if not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= 1000:
            fail(source, f"scenario: walks = {k!r}: expected a whole number in [1, 1000]")
        ms = sec.get("min_survival", 0.9)
        if not isinstance(ms, (int, float)) or isinstance(ms, bool) or not 0.0 <= ms <= 1.0:
            fail(source, f"scenario: min_survival = {ms!r}: expected a fraction in [0, 1]")
        tw = sec.get("tracking_weight", 10.0)
        if not isinstance(tw, (int, float)) or isinstance(tw, bool) or not 0.0 <= tw <= 1000.0:
            fail(source, f"scenario: tracking_weight = {tw!r}: expected a number in [0, 1000] deg per m/s")
        share = sec.get("servo_share")
        if share is not None and (not isinstance(share, (int, float)) or isinstance(share, bool)
                                  or not 0.1 <= share <= 10.0):
            fail(source, f"scenario: servo_share = {share!r}: expected a share of the servos' speed in [0.1, 10]")
        try:
            rnd = randomisation_from_mapping(sec.get("randomisation"), "scenario.randomisation")
            scen = scenario_from_mapping({kk: v for kk, v in sec.items() if kk in SCENARIO_FIELDS}, "scenario")
        except UserError as exc:
            fail(source, str(exc))
        return ScenarioSpec(k, float(ms), float(tw), rnd, scen, None if share is None else float(share))

    def evaluate(self, sc: ScenarioSpec, drive: Any, world: Any,
                 report: Callable[[float, int], bool] | None = None) -> TrialResult:
        total = sc.walks * len(world.sims)
        allowed = math.floor((1.0 - sc.min_survival) * total + 1e-9)
        scores, per, falls, hopeless = [], {}, 0, False
        asked = 0.0                        # the largest share of a servo's speed any walk asked

        def walk(sim: Any, i: int) -> dict:
            stream, pushes = draw_scenario(sc.scenario, i, world.namespace)
            p = draw(sc.randomisation, i, *sim.n_random(), namespace=world.namespace)
            return walk_scenario(sim, drive, stream, pushes, p)

        rows_of: dict[str, list] = {}
        for name, r in world.in_order(sc.walks, walk):
            tk = r["tracking"] or {}
            err = sum(v for v in (tk.get("vx_rmse_mps"), tk.get("vy_rmse_mps")) if v is not None) \
                + 0.1 * (tk.get("wz_rmse_radps") or 0.0)
            score = (r["pitch_rms_deg"] or 0.0) + sc.tracking_weight * err
            if not r["survived"]:
                falls += 1
                score += FALL_PENALTY_DEG * (1.0 - min(max(r["walked"], 0.0), 1.0))
            scores.append(score)
            asked = max(asked, float(r.get("servo_share") or 0.0))
            rows_of.setdefault(name, []).append(r)
            if falls > allowed:
                hopeless = True
                break
        for name, rows in rows_of.items():
            per[name] = {"survival": float(np.mean([r["survived"] for r in rows])), "rollouts": len(rows),
                         "fell": any(not r["survived"] for r in rows)}
        stood = sum(1.0 if r["survived"] else min(max(r["walked"], 0.0), 1.0)
                    for rows in rows_of.values() for r in rows)
        constraint = survival_constraint(sc.min_survival, falls, total, len(scores), hopeless, stood)
        if sc.servo_share is not None and asked > sc.servo_share:
            # too fast for the servos: infeasible by how far (beside any shortfall of survival)
            constraint = max(constraint or 0.0, asked - sc.servo_share)
        return TrialResult(score=float(np.mean(scores)), speed=0.0,
                           fall_constraint=-1.0 if constraint is None else constraint, fell=falls > 0,
                           per_surface=per, survival=1.0 - falls / len(scores), hopeless=hopeless,
                           attrs={"servo_share": round(asked, 4)})


    def describe_best(self, sc: ScenarioSpec, trial: Any, *, fell: bool, falls: int, infeasible: int) -> str:
        return describe_randomised(trial, sc.min_survival, infeasible, f"match walks ({sc.walks} a surface)")


register(Match())
