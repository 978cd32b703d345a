"""Train a set's residual (``gaits/engine/residual.py``) in the tool's own closed loop (ours).

The search is Mania, Guy & Recht 2018's augmented random search, their variant V1-t: each iteration
draws ``directions`` random maps delta (standard normal, one number per weight), walks the residual
theta +- ``noise`` delta on the same ``walks`` rollouts (the same command streams, pushes and
randomisation for both signs: the pair's difference is the direction's effect, not the draw's),
keeps the ``top`` directions whose better sign scored best, and moves

    theta += step / (top * sigma_R) * sum over the kept (r+ - r-) delta

(sigma_R the standard deviation of the kept rewards). theta itself is walked on the same rollouts
too and reported (its reward, how many of its walks stood). A random search over a linear map
needs no gradient of the simulator and no network library, and its rollouts are the study's own.

Rewards (ours):

* ``match``: randomised match walks (``tuner/sim/match_walks.py``, the distribution ``versus``
  measures), seeds (seed, iteration, k) of the tuning namespace (never an evaluation walk):
  3 x the share of the walk walked + 1 if it stood to the end - the forward, sideways and 0.2 x the
  turning RMS tracking errors [m/s, rad/s] x the share walked (a walk that falls early has less
  time to track badly: the error counts by the time it walked);
* ``command``: ``command`` (vx, vy, wz) held for 10 s then a stop, under the default randomisation
  (what ``robustness --command`` measures), seeds as above; rewarded as a match walk;
* ``push``: the 2025 push challenge's trial (3 kg bottle, rope 1.5 m), stepping in place as the trial
  walks every set, at a release distance drawn from U(0.8, 1.2) x ``distance`` (the challenge asks
  every D up to the one it reaches, and a map trained at one D alone was seen to lose smaller ones),
  the third push from the front and from behind in turn: the pushes absorbed (0-3) + the share of
  the trial stood.

Several surfaces: rollout k of an evaluation walks surface k mod n (and, pushed, the third push
alternates every n rollouts, so that each surface gets both sides).

Deterministic from ``seed``: the directions come from numpy's generator of it, the rollouts' seeds
from it, and the rewards are gathered in order whatever the workers' timing.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

import gaits
from gaits.drive import ONLINE_DURATION_S
from gaits.engine.residual import ResidualParams

from ..errors import UserError
from ..process_pool import map_in_order
from ..sim.randomisation import TUNE, Randomisation, draw

__all__ = ["TrainSettings", "TrainResult", "ars_update", "train", "OBJECTIVES", "match_reward", "push_reward",
           "save_trained"]

OBJECTIVES = ("match", "command", "push")
_SEED_SPACE = 0x7A1       # the rollouts' own seed namespace within the tuning one (ours)


@dataclass(frozen=True)
class TrainSettings:
    """How ``train`` searches (module docstring); every number a default of ours."""

    iterations: int = 30          # ARS iterations
    directions: int = 8           # N: random directions per iteration
    top: int = 4                  # b: the directions kept
    noise: float = 0.03           # nu [rad per unit feature]: the size of a direction
    step: float = 0.02            # alpha: the step along the kept directions
    walks: int = 3                # rollouts per evaluation (the same for +-delta and theta)
    objective: str = "match"      # match, command or push
    distance: float = 0.5         # [m] push: the bottle's release distance D
    command: tuple[float, float, float] = (0.3, 0.0, 0.0)   # [m/s, m/s, rad/s] command: the one held
    seed: int = 0

    def __post_init__(self) -> None:
        checks = (("iterations", 1, 10_000), ("directions", 1, 256), ("walks", 1, 100))
        for name, lo, hi in checks:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise UserError(f"{name} = {v!r}: expected a whole number in [{lo}, {hi}]")
        if isinstance(self.top, bool) or not isinstance(self.top, int) or not 1 <= self.top <= self.directions:
            raise UserError(f"top = {self.top!r}: expected a whole number in [1, directions = {self.directions}]")
        for name, hi in (("noise", 1.0), ("step", 1.0)):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v <= hi:
                raise UserError(f"{name} = {v!r}: expected a number in (0, {hi:g}]")
        if self.objective not in OBJECTIVES:
            raise UserError(f"objective = {self.objective!r}: one of {', '.join(OBJECTIVES)}")
        if len(self.command) != 3 or not all(isinstance(v, (int, float)) and math.isfinite(v) and abs(v) <= 2.0
                                             for v in self.command):
            raise UserError(f"command = {self.command!r}: expected (vx, vy, wz), each within 2 m/s or rad/s")
        if not isinstance(self.distance, (int, float)) or not math.isfinite(self.distance) \
                or not 0 < self.distance <= 1.125:
            raise UserError(f"distance = {self.distance!r}: expected a release distance in (0, 1.125] m "
                            f"(0.75 x the 1.5 m rope)")


@dataclass
class TrainResult:
    """Where the search ended: the residual, and per iteration theta's mean reward and walks stood."""

    residual: ResidualParams
    rewards: list[float] = field(default_factory=list)
    stood: list[float] = field(default_factory=list)


def ars_update(theta: np.ndarray, deltas: np.ndarray, r_plus: np.ndarray, r_minus: np.ndarray, top: int,
               step: float) -> np.ndarray:
    """One V1-t step (module docstring): ``deltas`` (N, ...) and their rewards (N,) each sign."""
    r_plus, r_minus = np.asarray(r_plus, dtype=float), np.asarray(r_minus, dtype=float)
    order = np.argsort(-np.maximum(r_plus, r_minus), kind="stable")[:top]
    sigma = float(np.std(np.concatenate([r_plus[order], r_minus[order]])))
    if sigma < 1e-12:                       # every kept direction scored the same: nothing to learn
        return np.array(theta, dtype=float)
    move = np.tensordot(r_plus[order] - r_minus[order], deltas[order], axes=1)
    return theta + step / (top * sigma) * move


def match_reward(row: dict[str, Any]) -> float:
    """A match walk's reward (module docstring) from ``walk_scenario``'s row."""
    walked = min(float(row.get("walked") or 0.0), 1.0)
    tk = row.get("tracking") or {}
    err = (tk.get("vx_rmse_mps") or 0.0) + (tk.get("vy_rmse_mps") or 0.0) + 0.2 * (tk.get("wz_rmse_radps") or 0.0)
    return 3.0 * walked + (1.0 if row.get("survived") else 0.0) - err * walked


def push_reward(trial: dict[str, Any], duration: float) -> float:
    """A 2025 push trial's reward (module docstring)."""
    t_fall = trial.get("t_fall_s")
    stood = 1.0 if t_fall is None else min(float(t_fall) / duration, 1.0)
    return float(trial["absorbed"]) + stood


_WORLDS: dict = {}


def _world(robot: str, surfaces: tuple[str, ...]):
    """The robot on each surface (``tuner/scenarios/world.py``: one simulator per surface, and with the
    challenge's pendulum on first use), built once per process; the parent builds it before the
    workers fork, so they inherit it."""
    from ..scenarios.world import World
    key = (robot, surfaces)
    if key not in _WORLDS:
        _WORLDS.clear()
        _WORLDS[key] = World(robot, surfaces)
    return _WORLDS[key]


def _rollout(task: tuple) -> tuple[float, bool]:
    """(reward, stood to the end) of one rollout (a worker process)."""
    robot, surfaces, index, drive, objective, distance, command, third, seed = task
    world = _world(robot, surfaces)
    if objective == "push":
        from ..challenge.rules import TRIAL_S, trial_2025
        from ..sim.scene import BOTTLES
        sim = world.sims_with_pendulum(1.5, BOTTLES[3])[index]
        state = np.random.SeedSequence([_SEED_SPACE, *seed]).generate_state(2)
        d = distance * (0.8 + 0.4 * float(state[1]) / 2.0**32)
        trial = trial_2025(sim, drive, d, int(state[0]), third)
        return push_reward(trial, TRIAL_S), trial.get("t_fall_s") is None
    from ..sim.match_walks import MatchDistribution, draw_scenario
    from ..sim.robustness import walk_scenario
    sim = world.sims[index]
    if objective == "command":
        stream, pushes = gaits.CommandStream.constant(command, ONLINE_DURATION_S), []
    else:
        stream, pushes = draw_scenario(MatchDistribution(), seed, TUNE)
    p = draw(Randomisation(), seed, *sim.n_random(), namespace=TUNE)
    row = walk_scenario(sim, drive, stream, pushes, p)
    return match_reward(row), bool(row.get("survived"))


def save_trained(path: Path, drive: gaits.Drive, residual: ResidualParams, description: str) -> Path:
    """Write ``drive``'s set with ``residual`` to ``path`` (atomically: an interrupted run keeps the
    last whole file)."""
    from gaits.files import write_text_atomic
    return write_text_atomic(Path(path), gaits.gait_file_text(drive.params, description, drive.stabiliser,
                                                             drive.engine, residual))


def train(drive: gaits.Drive, robot: str, surface: str | Sequence[str], settings: TrainSettings = TrainSettings(), *,
          workers: int = 1, limit: float | None = None,
          progress: Callable[[int, float, float], None] | None = None,
          checkpoint: Callable[[ResidualParams, int], None] | None = None) -> TrainResult:
    """Search the residual of ``drive`` (an engine set; its own residual, if any, is the start) on
    ``robot`` and ``surface``, or several surfaces: rollout k of an evaluation walks surface k mod n
    (module docstring). ``checkpoint(residual, iteration)`` with the start (iteration 0) and after each
    iteration, ``progress(iteration, reward, stood)`` after each."""
    if drive.engine is None or gaits.family_of(drive.params).engine != "feedback":
        raise UserError(f"{drive.source or 'the set'}: a residual corrects the online walk engine's targets: "
                        f"train needs a tlipfm set with an engine: section")
    start = drive.residual or ResidualParams()
    clip = start.limit if limit is None else limit
    theta = start.matrix
    base = dataclasses.replace(drive, command=None, stream=None)
    rng = np.random.default_rng(np.random.SeedSequence([_SEED_SPACE, settings.seed]))
    s = settings
    surfaces = (surface,) if isinstance(surface, str) else tuple(surface)
    if not surfaces:
        raise UserError("train: give at least one surface")
    result = TrainResult(ResidualParams.from_matrix(theta, clip))
    if checkpoint is not None:              # the start, before any work: a place it cannot be written is said now
        checkpoint(result.residual, 0)
    world = _world(robot, surfaces)                       # built here: forked workers inherit it
    if s.objective == "push":
        from ..sim.scene import BOTTLES
        world.sims_with_pendulum(1.5, BOTTLES[3])
    for it in range(s.iterations):
        deltas = rng.standard_normal((s.directions,) + theta.shape)
        maps = [theta + s.noise * d for d in deltas] + [theta - s.noise * d for d in deltas] + [theta]
        seeds = [(s.seed, it, k) for k in range(s.walks)]
        n_s = len(surfaces)
        drives = [dataclasses.replace(base, residual=ResidualParams.from_matrix(w, clip)) for w in maps]
        tasks = [(robot, surfaces, seed[-1] % n_s, d, s.objective, s.distance, s.command,
                  "front" if (seed[-1] // n_s) % 2 == 0 else "back", seed) for d in drives for seed in seeds]
        out = map_in_order(_rollout, tasks, workers, chunksize=1)
        rewards = np.array([r for r, _ in out]).reshape(len(maps), s.walks).mean(axis=1)
        stood = float(np.mean([ok for _, ok in out[-s.walks:]]))
        n = s.directions
        # rounded to 1e-6 rad per unit: the set file holds the very numbers trained on (and stays short)
        theta = np.round(ars_update(theta, deltas, rewards[:n], rewards[n:2 * n], s.top, s.step), 6)
        result.residual = ResidualParams.from_matrix(theta, clip)
        result.rewards.append(float(rewards[-1]))
        result.stood.append(stood)
        if checkpoint is not None:
            checkpoint(result.residual, it + 1)
        if progress is not None:
            progress(it + 1, float(rewards[-1]), stood)
    return result
