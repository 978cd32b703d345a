"""Speed staircases (a study's ``speed:`` section): every direction's staircase on every surface
(``tuner/sim/walk_speed.py``), scored by the highest stair held.

Per direction the worst (or mean) surface's highest stair held, weighted, less ``pitch_weight``
times the pitch RMS [deg]: one objective (``mode: weighted``, maximised), or one per direction
and pitch RMS (``mode: pareto``). Infeasible unless every direction holds at least its first stair
on every surface. The CasADi seed of a TLIPFM speed study is planned for half the forward top
stair at a 0.3 s step (ours: the seed's step length is a parameter of the problem, not a
decision variable).

    speed:
      directions:                         # forward, backward, left, right, turn_left, turn_right
        forward: {top: 0.45, weight: 1.0} # top stair [m/s or rad/s], weight in the score
      levels: 8                           # stairs from top / levels up to top
      steps_per_level: 4                  # steps each stair is held (even: whole cycles)
      tolerance: 0.3                      # a stair is held if measured >= (1 - tolerance) x commanded
      pitch_weight: 0.005
      mode: weighted                      # weighted | pareto
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from gaits import DIRECTIONS, family, walks_direction

from ..sim.walk_speed import speed_test
from .base import Scenario, TrialResult, fail, number, register


@dataclass(frozen=True)
class SpeedSpec:
    """A speed study's scoring (see tuner/sim/walk_speed.py): directions with top stair and weight."""

    directions: tuple[tuple[str, float, float], ...]   # (name, top [m/s or rad/s], weight)
    levels: int = 8
    steps_per_level: int = 4
    tolerance: float = 0.3
    pitch_weight: float = 0.005
    mode: str = "weighted"

    def staircase(self, name: str, top: float):
        from gaits import SpeedStaircase
        return SpeedStaircase(name, top, self.levels, self.steps_per_level)


class Speed(Scenario):
    name = "speed"
    section = "speed"
    excludes = {"robust": "list the pedestals under surfaces"}

    def parse(self, sec: Any, doc: Mapping[str, Any], source: str) -> SpeedSpec:
        allowed = ("directions", "levels", "steps_per_level", "tolerance", "pitch_weight", "mode")
        if not isinstance(sec, Mapping):
            fail(source, f"speed must be a mapping of {', '.join(allowed)}")
        for k in sec:
            if k not in allowed:
                fail(source, f"speed: unknown key {k!r} (allowed: {', '.join(allowed)})")
        dirs = sec.get("directions")
        if not isinstance(dirs, Mapping) or not dirs:
            fail(source, f"speed.directions must map at least one of {', '.join(DIRECTIONS)} to {{top, weight}}")
        out = []
        for name, d in dirs.items():
            if name not in DIRECTIONS:
                fail(source, f"speed.directions: unknown direction {name!r} (allowed: {', '.join(DIRECTIONS)})")
            if not isinstance(d, Mapping) or "top" not in d or not set(d) <= {"top", "weight"}:
                fail(source, f"speed.directions.{name} must be {{top: ..., weight: ...}}")
            top, weight = d["top"], d.get("weight", 1.0)
            unit = "rad/s" if name.startswith("turn") else "m/s"
            if isinstance(top, bool) or not isinstance(top, (int, float)) or not 0 < top <= 3.0:
                fail(source, f"speed.directions.{name}.top = {top!r}: expected a number in (0, 3] {unit}")
            if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not 0 <= weight <= 100:
                fail(source, f"speed.directions.{name}.weight = {weight!r}: expected a number in [0, 100]")
            out.append((str(name), float(top), float(weight)))
        levels = number(sec, "levels", 8, 1, 50, source, "speed.levels", integer=True)
        spl = number(sec, "steps_per_level", 4, 2, 40, source, "speed.steps_per_level", integer=True)
        if spl % 2:
            fail(source, f"speed.steps_per_level = {spl}: must be even (whole gait cycles)")
        mode = sec.get("mode", "weighted")
        if mode not in ("weighted", "pareto"):
            fail(source, f"speed.mode = {mode!r}: expected weighted or pareto")
        return SpeedSpec(tuple(out), levels, spl,
                         float(number(sec, "tolerance", 0.3, 0.0, 0.9, source, "speed.tolerance")),
                         float(number(sec, "pitch_weight", 0.005, 0.0, 10.0, source, "speed.pitch_weight")), mode)

    def objectives(self, sp: SpeedSpec, doc: Mapping[str, Any], source: str) -> tuple[str, ...]:
        if "objectives" in doc:
            fail(source, "a speed study takes its objectives from speed.mode: remove 'objectives'")
        return ("speed_score",) if sp.mode == "weighted" else tuple(d[0] for d in sp.directions) + ("pitch_rms",)

    def check(self, sp: SpeedSpec, *, gait: str, engine: Any, controller: Any, source: str) -> None:
        if controller is not None:
            fail(source, "speed studies walk a gait's staircases: not built for a controller of your own")
        for name, _, _ in sp.directions:
            if not walks_direction(gait, name):
                fail(source, f"speed.directions: gait {gait!r} does not walk {name} ({family(gait).commands_text})")
        if engine is not None:
            fail(source, "speed studies walk tables on staircases: give the engine a scenario: section instead")

    def seed_base(self, sp: SpeedSpec, base: Any, gait: str) -> Any:
        top = dict((d, t) for d, t, _ in sp.directions).get("forward", 0.2)
        return family(gait).with_step(base, round(min(0.5 * top * 0.3, 0.06), 4))

    def evaluate(self, sp: SpeedSpec, drive: Any, world: Any,
                 report: Callable[[float, int], bool] | None = None) -> TrialResult:
        params, stabiliser = drive.params, drive.stabiliser
        per: dict[str, dict] = {}
        reached: dict[str, list[float]] = {d: [] for d, _, _ in sp.directions}
        pitches, misses, fell = [], 0, False

        def walk(sim: Any, i: int) -> Any:
            d, top, _ = sp.directions[i]
            return speed_test(sim, params, sp.staircase(d, top), sp.tolerance, stabiliser)

        n = len(sp.directions)
        for k, (name, r) in enumerate(world.in_order(n, walk)):
            d = sp.directions[k % n][0]
            per.setdefault(name, {})[d] = {"reached": r.reached, "measured": r.measured, "fell": r.fell,
                                           "pitch_rms_deg": r.pitch_rms_deg, "reason": r.reason}
            reached[d].append(r.reached)
            if np.isfinite(r.pitch_rms_deg):
                pitches.append(r.pitch_rms_deg)
            misses += r.reached <= 0.0
            fell = fell or r.fell
        worst = world.aggregate_rule == "worst"
        by_dir = {d: float(min(v) if worst else np.mean(v)) for d, v in reached.items()}
        pitch = float(max(pitches) if worst else np.mean(pitches)) if pitches else 90.0
        score = sum(w * by_dir[d] for d, _, w in sp.directions) - sp.pitch_weight * pitch
        total = len(world.sims) * len(sp.directions)
        constraint = misses / total if misses else -1.0
        values = ((score,) if sp.mode == "weighted"
                  else tuple(by_dir[d] for d, _, _ in sp.directions) + (pitch,))
        return TrialResult(score=score, speed=by_dir.get("forward", 0.0), fall_constraint=constraint, fell=fell,
                           per_surface=per, values=values, by_direction=by_dir, pitch_rms_deg=pitch,
                           attrs={"speed": {"by_direction": by_dir, "score": score, "pitch_rms_deg": pitch}})

    def describe_best(self, sp: SpeedSpec, trial: Any, *, fell: bool, falls: int, infeasible: int) -> str:
        got = trial.user_attrs.get("speed") or {}
        dirs = ", ".join(f"{d} {v:.3g} {'rad/s' if d.startswith('turn') else 'm/s'}"
                         for d, v in (got.get("by_direction") or {}).items())
        why = (trial.user_attrs.get("result") or {}).get("invalid")
        return (f"best trial {trial.number}: speed score {got.get('score', trial.values[0]):.3f}"
                + (f"; highest stairs held: {dirs}" if dirs else "")
                + (f"; rejected: {why}" if why else "")
                + f"; infeasible trials (a direction not held on a surface, or rejected): {infeasible}")

    def target_label(self, settings: Any) -> str:
        return "speed score (maximised)"


register(Speed())
