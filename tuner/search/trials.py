"""Reading a study's trials: the best one, a Pareto pick, and what a trial walked and scored.

Every trial records its full parameter set (SI, user attribute ``params``; a controller of the
user's own under ``controller``, the stabiliser's gains under ``stabiliser``) and its result
(``result``: fell, the fall constraint, per surface), so it is reproducible: the simulation is
deterministic.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import optuna
from optuna.trial import TrialState

import gaits

from ..store.history import DONE_STATES

__all__ = ["DONE_STATES", "NothingWalked", "best_trial", "progress_note", "PARETO_PICKS", "pareto_pick", "trial_params", "trial_stabiliser",
           "trial_result", "trial_fell", "trial_feasible", "n_done", "trial_engine"]


def n_done(study: optuna.Study) -> int:
    return len(study.get_trials(deepcopy=False, states=DONE_STATES))


class NothingWalked(KeyError):
    """A study whose completed trials were all rejected before they walked: no best trial.
    ``fell``: how many other trials walked and were stopped at their falls (pruned)."""

    def __init__(self, message: str, fell: int = 0) -> None:
        super().__init__(message)
        self.fell = fell

    def __str__(self) -> str:
        return str(self.args[0])


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
    # a rejected trial (its draw could not be walked: ``invalid``) scores a penalty, not a walk: never
    # the best, even in a study where every walk fell
    walked = [t for t in trials if not trial_result(t).get("invalid")]
    if not walked:
        fell = sum(1 for t in study.get_trials(deepcopy=False, states=(TrialState.PRUNED,))
                   if trial_result(t) and not trial_result(t).get("invalid"))
        first = trial_result(trials[0]).get("invalid")
        if fell:
            raise NothingWalked(f"study {study.study_name!r}: {fell} trial(s) walked and fell below the minimum survival "
                                f"(stopped at their falls); every one that completed was rejected before it walked "
                                f"(the first: {first})", fell)
        raise NothingWalked(f"study {study.study_name!r}: every completed trial was rejected before it walked (the first: "
                            f"{first})")
    feasible = [t for t in walked if trial_result(t).get("fall_constraint", 1.0) <= 0] or walked
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
    data = {k: v for k, v in data.items() if k not in ("stabiliser", "engine")}
    return gaits.params_from_mapping(spec_gait, data, f"trial {trial.number}")

def trial_stabiliser(trial: optuna.trial.FrozenTrial) -> gaits.StabiliserParams | None:
    """The IMU stabiliser a trial walked with, or None (open loop)."""
    data = (trial.user_attrs.get("params") or {}).get("stabiliser")
    return None if data is None else gaits.StabiliserParams(**data)

def trial_engine(trial: optuna.trial.FrozenTrial) -> Any:
    """The walk engine's numbers a trial walked with, or None (a joint table)."""
    from gaits.engine import EngineParams
    data = (trial.user_attrs.get("params") or {}).get("engine")
    return None if data is None else EngineParams(**data)


def progress_note(done: list) -> str:
    """What a study's progress bar says of its finished trials: how many kept their walks (feasible)
    and how many had a walk fall ("falls N" alone read as falls counted, not trials)."""
    feasible = sum(1 for t in done if trial_feasible(t))
    fell = sum(1 for t in done if trial_fell(t))
    return f"{feasible} feasible, {fell} with a fall"


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
