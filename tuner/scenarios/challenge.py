"""The push-recovery challenge as a study (a study's ``challenge:`` section, ours): the challenge
(``tuner/challenge/rules.py``) on each surface for each push seed.

The one objective, ``push_distance`` (maximised), is per surface the mean over the seeds of the
largest fully successful D [m] (by the rules the section names; 2025 by default) (``start - step`` where even ``start`` fails: worse than any
success, and still ordered), then the worst surface's or the mean over surfaces, as the study's
``aggregate`` says. Always feasible: a trial that takes no push scores low, not infeasible (ours:
the sampler then learns from every trial's distance).

    challenge:
      rules: 2025        # 2025: the current rules (a bottle of 3, 5 or 10 kg; front, back, either;
                         #   the largest fully successful D); 2019: the old trial (1 kg, random directions)
      bottle: 3          # [kg] 2025 rules: 3, 5 or 10
      third: both        # 2025 rules: the third push from the front, the back, or both tried (the worse)
      seeds: [0, 1, 2]   # push seeds
      rope: 1.5          # [m] the 2025 rules allow 1.5-2 m, 2019's 1-2 m
      start: 0.05        # [m] the first D tried
      step: 0.05         # [m] D raised by this until a trial fails
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from gaits import ParamError, UnreachableTargetError

from ..challenge.rules import challenge, challenge_2025
from ..sim.scene import BOTTLE_2019, BOTTLES
from .base import MAX_SEED, Scenario, TrialResult, check_section, fail, invalid_result, number, register


@dataclass(frozen=True)
class ChallengeSpec:
    """A challenge study's trials: the push-recovery challenge on each surface for each push seed."""

    seeds: tuple[int, ...] = (0, 1, 2)
    rope: float = 1.5                  # [m] the rules allow 1-2 m
    start: float = 0.05                # [m] the first D tried
    step: float = 0.05                 # [m] D raised by this until a trial fails
    rules: str = "2025"                # the rules' year: 2025 (current) or 2019
    bottle: int = 3                    # [kg] the 2025 rules' bottle
    third: str = "both"                # the 2025 rules' third push: front, back or both


class Challenge(Scenario):
    name = "challenge"
    section = "challenge"
    excludes = {other: "a challenge study walks the challenge's own trials" for other in ("robust", "scenario", "speed")}
    default_objectives = ("push_distance",)

    def parse(self, sec: Any, doc: Mapping[str, Any], source: str) -> ChallengeSpec:
        check_section(sec, "challenge", ("rules", "bottle", "third", "seeds", "rope", "start", "step"), source)
        rules = str(sec.get("rules", "2025"))
        if rules not in ("2025", "2019"):
            fail(source, f"challenge: rules = {sec.get('rules')!r}: expected 2025 (the current rules) or 2019")
        bottle = sec.get("bottle", 3)
        if rules == "2019" and ("bottle" in sec or "third" in sec):
            fail(source, "challenge: bottle and third are the 2025 rules' (the 2019 trial has a 1 kg bottle)")
        if bottle not in (3, 5, 10) or isinstance(bottle, bool):
            fail(source, f"challenge: bottle = {bottle!r}: expected 3, 5 or 10 [kg]")
        third = sec.get("third", "both")
        if third not in ("both", "front", "back"):
            fail(source, f"challenge: third = {third!r}: expected both, front or back")
        if doc.get("duration") is not None and doc.get("controller") is None:
            fail(source, "challenge: the challenge's trials last 14 s each: remove 'duration'")
        seeds = sec.get("seeds", [0, 1, 2])
        if not isinstance(seeds, list) or not seeds or len(seeds) > 100 or any(
                not isinstance(k, int) or isinstance(k, bool) or not 0 <= k <= MAX_SEED for k in seeds) \
                or len(set(seeds)) != len(seeds):
            fail(source, f"challenge: seeds = {seeds!r}: expected a list of 1 to 100 different whole numbers "
                         f"in [0, {MAX_SEED}]")
        vals = {k: float(number(sec, k, default, lo, hi, source, f"challenge: {k}", unit="m"))
                for k, default, lo, hi in (("rope", 1.5, 1.0, 2.0), ("start", 0.05, 0.01, 1.9),
                                           ("step", 0.05, 0.01, 1.0))}
        top = 0.75 if rules == "2025" else 0.95
        if vals["start"] >= top * vals["rope"]:
            fail(source, f"challenge: start = {vals['start']:g} m: the bottle is released from below {top:g} of the "
                         f"rope ({top * vals['rope']:g} m): start lower")
        if rules == "2025" and vals["rope"] < 1.5:
            fail(source, f"challenge: rope = {vals['rope']:g} m: the 2025 rules' rope is 1.5 to 2 m")
        return ChallengeSpec(tuple(int(k) for k in seeds), vals["rope"], vals["start"], vals["step"], rules,
                             int(bottle), str(third))

    def objectives(self, settings: Any, doc: Mapping[str, Any], source: str) -> tuple[str, ...]:
        if "objectives" in doc:
            fail(source, "a challenge study's one objective is push_distance: remove 'objectives'")
        return self.default_objectives

    def evaluate(self, ch: ChallengeSpec, drive: Any, world: Any,
                 report: Callable[[float, int], bool] | None = None) -> TrialResult:
        floor = ch.start - ch.step

        def walk(sim: Any, i: int) -> dict:
            if ch.rules == "2025":
                r = challenge_2025(sim, drive, seed=ch.seeds[i], start=ch.start, step=ch.step, third=ch.third)
                return {"best_distance_m": r["full"]["distance_m"], "momentum_Ns": r["full"]["momentum_Ns"]}
            return challenge(sim, drive, seed=ch.seeds[i], start=ch.start, step=ch.step)

        bottle = BOTTLE_2019 if ch.rules == "2019" else BOTTLES[ch.bottle]
        per: dict[str, dict] = {}
        distances: dict[str, list[float]] = {}
        try:
            for name, r in world.in_order(len(ch.seeds), walk, world.sims_with_pendulum(ch.rope, bottle)):
                d = r["best_distance_m"]
                distances.setdefault(name, []).append(floor if d is None else float(d))
                row = per.setdefault(name, {"best_distance_m": [], "momentum_Ns": []})
                row["best_distance_m"].append(d)
                row["momentum_Ns"].append(r["momentum_Ns"])
        except (ParamError, UnreachableTargetError) as exc:
            return invalid_result(str(exc), score=floor, values=(floor,))
        means = [float(np.mean(v)) for v in distances.values()]
        score = min(means) if world.aggregate_rule == "worst" else float(np.mean(means))
        return TrialResult(score=score, speed=0.0, fall_constraint=-1.0, fell=False, per_surface=per,
                           values=(score,))

    def describe_best(self, ch: ChallengeSpec, trial: Any, *, fell: bool, falls: int, infeasible: int) -> str:
        per = (trial.user_attrs.get("result") or {}).get("per_surface") or {}
        cells = "; ".join(f"{name} " + ", ".join("-" if d is None else f"{d:.2f}" for d in row["best_distance_m"])
                          for name, row in per.items())
        return (f"best trial {trial.number}: push distance {trial.values[0]:.3f} m (mean largest D over the push "
                f"seeds {', '.join(str(k) for k in ch.seeds)}" + (f": {cells}" if cells else "") + ")")

    def target_label(self, settings: Any) -> str:
        return "push distance D [m] (maximised)"


register(Challenge())
