"""What a scenario is, and the registry of them.

A study walks each trial's set (a :class:`gaits.Drive`) in one *scenario*: plain walks, randomised
walks, match walks, the push-recovery challenge, speed staircases. A scenario is one room (the
pattern of dm_control's Task and mujoco_playground's registry): one file that holds its YAML
section, how that section is read and checked, which objectives it scores and how it walks and
scores a trial. ``tuner/search`` keeps only what every study shares (the space, the sampler, the
storage) and asks the study's scenario for the rest.

To add one: write a file in this folder with a subclass of :class:`Scenario` (its ``name``, its
``section``, and :meth:`Scenario.parse` and :meth:`Scenario.evaluate`) and add its module to
``BUILT_IN`` in ``tuner/scenarios/__init__.py`` (or call :func:`register` from your own code).

Scoring shared by the walking scenarios (from ``tuner/search/objective.py``, unchanged): a walk's
score is its torso pitch RMS [deg]; a fall adds ``FALL_PENALTY_DEG`` times the share of the walk
not walked; a walk that stayed up but covered less of its planned forward distance adds
``PROGRESS_PENALTY_DEG`` times the uncovered share (:func:`rollout_score`).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Mapping

import numpy as np

from ..errors import UserError

__all__ = ["Scenario", "TrialResult", "describe_randomised", "register", "SCENARIOS", "scenario_named", "scenario_for_doc",
           "rollout_score", "invalid_result", "survival_constraint", "FALL_PENALTY_DEG", "PROGRESS_PENALTY_DEG",
           "OBJECTIVES", "MAX_SEED", "fail", "check_section", "number"]

FALL_PENALTY_DEG = 100.0
PROGRESS_PENALTY_DEG = 50.0     # per unit of the planned distance not covered
MAX_SEED = 2 ** 31 - 1
#: every objective a study may have, and its direction
OBJECTIVES = {"pitch_rms": "minimize", "speed": "maximize", "speed_score": "maximize",
              **{d: "maximize" for d in ("forward", "backward", "left", "right", "turn_left", "turn_right")},
              "push_distance": "maximize"}


def fail(source: str, msg: str) -> None:
    """A study file's mistake: one line naming the file."""
    raise UserError(f"{source}: {msg}")


def check_section(sec: Any, name: str, allowed: tuple[str, ...], source: str) -> None:
    """A study's section must be a mapping of the allowed keys (one line naming the first stranger)."""
    if not isinstance(sec, Mapping):
        fail(source, f"{name} must be a mapping of {', '.join(allowed)}")
    for k in sec:
        if k not in allowed:
            fail(source, f"{name}: unknown key {k!r} (allowed: {', '.join(allowed)})")


def number(sec: Mapping[str, Any], key: str, default: float, lo: float, hi: float, source: str, what: str,
           integer: bool = False, unit: str = "") -> Any:
    """``sec[key]`` (or ``default``), a finite number (a whole one when ``integer``) in [lo, hi]."""
    v = sec.get(key, default)
    ok = isinstance(v, int) if integer else isinstance(v, (int, float))
    if isinstance(v, bool) or not ok or not math.isfinite(v) or not lo <= v <= hi:
        fail(source, f"{what} = {v!r}: expected {'a whole number' if integer else 'a number'} in "
                     f"[{lo:g}, {hi:g}]{' ' + unit if unit else ''}")
    return v


@dataclass(frozen=True)
class TrialResult:
    """What the evaluation of one trial found (the objective stores :meth:`stored` with the trial)."""

    score: float                      # the first objective: pitch score [deg], or the speed score
    speed: float                      # [m/s] mean forward speed (speed studies: the forward stair held)
    fall_constraint: float            # <= 0 feasible; > 0 how far from it (a fall, too little progress)
    fell: bool                        # a walk of this trial fell
    per_surface: dict                 # per surface: its metrics (robust: survival, rollouts, median pitch)
    invalid: str | None = None        # why the set could not be walked at all (a rejected set)
    survival: float | None = None     # randomised studies: share of the randomised walks that stayed up
    hopeless: bool | None = None      # randomised studies: stopped early, survival already below its minimum
    values: tuple | None = None       # every objective's value, where the scenario sets them itself
    by_direction: dict | None = None  # speed studies: the highest stair held per direction
    pitch_rms_deg: float | None = None   # speed studies: the pitch term [deg]
    attrs: dict | None = None         # more user attributes the trial stores (name: JSON value)

    def stored(self) -> dict[str, Any]:
        """The trial's ``result`` user attribute (JSON in the storage; ``trials.trial_result`` reads it)."""
        return {"fell": self.fell, "fall_constraint": self.fall_constraint, "per_surface": self.per_surface,
                "invalid": self.invalid, "survival": self.survival, "hopeless": self.hopeless}


def invalid_result(why: str, score: float = FALL_PENALTY_DEG * 2, values: tuple | None = None) -> TrialResult:
    """A set that cannot be walked at all (the generators or the IK refused it)."""
    return TrialResult(score=score, speed=0.0, fall_constraint=1.0, fell=True, per_surface={}, invalid=why,
                       values=values)


def survival_constraint(min_survival: float, falls: int, total: int, walked: int, hopeless: bool,
                        stood: float | None = None) -> float | None:
    """A randomised study's constraint from its falls: > 0 when survival over the walks run is below
    ``min_survival`` (or the trial stopped as hopeless), by how far the falls exceed what the
    study's ``total`` walks allow; None when survival holds.

    ``stood``: the walks run, each counted by the share of it walked before it fell (1 for one that
    stayed up). A trial the falls made infeasible is then further by the share of the study's
    walking it did not stand, over ``total + 1`` (ours): among trials with as many falls the one
    that stood longer is nearer, and a whole fall more (1 / ``total``) still weighs more than any
    share not stood. Without it a study whose every trial falls (a robot's soft servos, a first
    start that cannot walk) gave the sampler one value for all of them, and TPE, which ranks the
    infeasible by how far they are, searched blind; with it, it climbs toward the sets that stand
    longest."""
    survival = 1.0 - falls / walked
    if survival < min_survival or hopeless:
        unstood = 0.0 if stood is None else min(max(1.0 - stood / total, 0.0), 1.0)
        return min_survival - (1.0 - falls / total) + 1e-3 + unstood / (total + 1)
    return None


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


class Scenario(ABC):
    """One way a study walks and scores a trial (subclass it; one instance is registered).

    ``name``: the registry's name; ``section``: the study file's key that chooses it (None: the
    scenario of a study with none of the registered sections, the plain walk); ``excludes``: other
    keys of a study file it does not go with, and why. ``prunes``: the median pruner may stop a
    trial between surfaces (one objective)."""

    name: ClassVar[str]
    section: ClassVar[str | None]
    excludes: ClassVar[dict[str, str]] = {}
    prunes: ClassVar[bool] = False
    #: the objectives a study of this scenario has when its file names none
    default_objectives: ClassVar[tuple[str, ...]] = ("pitch_rms",)

    @abstractmethod
    def parse(self, sec: Any, doc: Mapping[str, Any], source: str) -> Any:
        """The section's settings (a frozen dataclass), checked; a mistake is :func:`fail`."""

    def objectives(self, settings: Any, doc: Mapping[str, Any], source: str) -> tuple[str, ...]:
        """The study's objectives: by default the file's ``objectives``, [pitch_rms] or [pitch_rms, speed]."""
        objectives = doc.get("objectives", list(self.default_objectives))
        if not isinstance(objectives, list) or not objectives or any(o not in OBJECTIVES for o in objectives) \
                or objectives[0] != "pitch_rms" or len(set(objectives)) != len(objectives) \
                or not set(objectives) <= {"pitch_rms", "speed"}:
            fail(source, f"objectives must be [pitch_rms] or [pitch_rms, speed], got {objectives!r}")
        return tuple(objectives)

    def check(self, settings: Any, *, gait: str, engine: Any, controller: Any, source: str) -> None:
        """Checks against the rest of the study (its gait family, its engine section, a controller
        of the user's own); default none."""

    @abstractmethod
    def evaluate(self, settings: Any, drive: Any, world: Any,
                 report: Callable[[float, int], bool] | None = None) -> TrialResult:
        """Walk ``drive`` in ``world`` (:class:`tuner.scenarios.world.World`: the robot, one simulator
        per surface, the study's aggregate and duration) and score it. ``report(value, step)``
        (scenarios that prune): the running aggregate after each surface; True stops the trial."""

    def min_survival(self, settings: Any) -> float | None:
        """The survival below which a trial is infeasible and stops early (None: no such rule)."""
        return getattr(settings, "min_survival", None)

    def seed_base(self, settings: Any, base: Any, gait: str) -> Any:
        """The parameter set the CasADi seed is planned from (default: the study's base)."""
        return base

    def describe_best(self, settings: Any, trial: Any, *, fell: bool, falls: int, infeasible: int) -> str:
        """One line on a study's best trial (``trial``: Optuna's FrozenTrial, read duck-typed; ``fell``:
        it fell; ``falls`` and ``infeasible``: the study's finished trials that fell, that are infeasible)."""
        return (f"best trial {trial.number}: pitch score {trial.values[0]:.3f} deg"
                + (f", speed {trial.values[1]:.4f} m/s" if len(trial.values) > 1 else "")
                + f"; {'fell' if fell else 'stayed up'}"
                + f"; falls in study: {falls}")

    def target_label(self, settings: Any) -> str:
        """What the first objective is, for plots."""
        return "pitch score [deg] (minimised)"


def describe_randomised(trial: Any, min_survival: float, infeasible: int, walks: str) -> str:
    """The best trial of a randomised study (robust, match): its survival over its walks, not
    whether one of them fell (a 90 % survivor did fall, in one walk of ten)."""
    result = trial.user_attrs.get("result") or {}
    survival = result.get("survival")
    shown = "not recorded" if survival is None else f"{survival:.0%}"
    return (f"best trial {trial.number}: score {trial.values[0]:.3f}; survival {shown} of its {walks} "
            f"(minimum {min_survival:.0%}); trials below the minimum or rejected in study: {infeasible}")


#: name -> the registered scenario, in registration order
SCENARIOS: dict[str, Scenario] = {}


def register(scenario: Scenario) -> Scenario:
    """Register ``scenario`` under its name (a second one of the same name or section is refused)."""
    for other in SCENARIOS.values():
        if other.name == scenario.name or other.section == scenario.section:
            raise ValueError(f"scenario {scenario.name!r}: its name or section {scenario.section!r} "
                             f"is taken by {other.name!r}")
    SCENARIOS[scenario.name] = scenario
    return scenario


def scenario_named(name: str) -> Scenario:
    try:
        return SCENARIOS[name]
    except KeyError:
        raise UserError(f"unknown scenario {name!r} (registered: {', '.join(SCENARIOS)})") from None


def scenario_for_doc(doc: Mapping[str, Any], source: str) -> Scenario:
    """The scenario a study file chooses: the one whose section it has (at most one), else the
    scenario without a section; a section that does not go with another key is one line."""
    chosen = [s for s in SCENARIOS.values() if s.section is not None and doc.get(s.section) is not None]
    if len(chosen) > 1:
        a, b = chosen[0], chosen[1]            # named later one first: "challenge does not go with robust"
        why = b.excludes.get(a.section) or a.excludes.get(b.section) or "each is a study of its own"
        fail(source, f"{b.section} does not go with {a.section}: {why}")
    if chosen:
        s = chosen[0]
        for key, why in s.excludes.items():
            if doc.get(key) is not None and key not in {c.section for c in SCENARIOS.values()}:
                fail(source, f"{s.section} does not go with {key}: {why}")
        return s
    plain = [s for s in SCENARIOS.values() if s.section is None]
    return plain[0]
