"""gait-tuner's pure-math half: the three papers' gait generators, leg kinematics and parameters.

Nothing here imports a simulator or an optimiser (``tests/test_import_graph.py``
checks it): functions take and return numpy arrays and dataclasses.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from . import cosine_law, eros, tlipfm
from .baselines import list_baselines, load_baseline
from .cosine_law import CosineLawParams
from .eros import ErosParams
from .footstep_planner import FootstepPlan, PlanError, StepLimits, plan_footsteps
from .imu_stabiliser import StabiliserParams, stabiliser_corrections
from .leg_kinematics import LegGeometry, UnreachableTargetError, leg_fk, leg_ik
from .limb_kinematics import ArmGeometry, HeadGeometry, arm_fk, head_fk
from .params import (GaitFile, GaitParams, ParamError, families, family_class, load_gait_file,
                     params_from_mapping, save_gait_file)
from .tlipfm import TlipfmParams
from .trajectory import JOINT_NAMES, GaitTrajectory
from .walk_command import DIRECTIONS, CommandRamp, SpeedStaircase, WalkCommand, parse_command

__all__ = [
    "ArmGeometry",
    "COMMANDS",
    "COMMAND_AXES",
    "CommandRamp",
    "DIRECTIONS",
    "FootstepPlan",
    "PlanError",
    "SpeedStaircase",
    "StepLimits",
    "WalkCommand",
    "parse_command",
    "plan_footsteps",
    "CosineLawParams",
    "ErosParams",
    "GaitFile",
    "GaitParams",
    "GaitTrajectory",
    "HeadGeometry",
    "JOINT_NAMES",
    "LegGeometry",
    "ParamError",
    "StabiliserParams",
    "TlipfmParams",
    "UnreachableTargetError",
    "arm_fk",
    "families",
    "family_class",
    "generate",
    "head_fk",
    "leg_fk",
    "leg_ik",
    "list_baselines",
    "load_baseline",
    "load_gait_file",
    "params_from_mapping",
    "save_gait_file",
    "stabiliser_corrections",
    "step_period",
    "step_starts",
    "walks_direction",
]

_GENERATORS: dict[str, Callable[..., GaitTrajectory]] = {
    "eros": eros.generate,
    "tlipfm": tlipfm.generate,
    "cosine": cosine_law.generate,
}


#: What each family does with a walk command (``gaits/walk_command.py``), as ``params`` says it.
COMMANDS: dict[str, str] = {
    "tlipfm": "any (vx, vy, wz): the footstep planner's steps, hip yaw turns the feet",
    "eros": "any (vx, vy, wz): the footstep planner's steps walked with the paper's quarter-circle "
            "via points (side steps and turns follow eq 37's X profile, ours), hip yaw turns the feet",
    "cosine": "forward and backward (vx) only: one motion per step, S = vx t_f; the 5-DoF leg has "
              "no hip yaw and the paper keeps the roll static, so no side steps or turns",
}

#: Which command axes (vx, vy, wz) each family walks.
COMMAND_AXES: dict[str, tuple[bool, bool, bool]] = {
    "tlipfm": (True, True, True),
    "eros": (True, True, True),
    "cosine": (True, False, False),
}

_STEP_PERIODS: dict[str, Callable[..., float]] = {
    "eros": eros.step_period,
    "tlipfm": lambda p: p.period,
    "cosine": cosine_law.step_period,
}

_STEP_STARTS: dict[str, Callable[..., np.ndarray]] = {
    "eros": eros.step_starts,
    "tlipfm": lambda p, n: p.t_start + np.arange(n + 1) * p.period,
    "cosine": cosine_law.step_starts,
}


def walks_direction(family: str, direction: str) -> bool:
    """Whether a family walks a speed-test direction (``DIRECTIONS``) on its command axes."""
    return all(ok or u == 0 for ok, u in zip(COMMAND_AXES[family], DIRECTIONS[direction]))


def step_period(params: GaitParams) -> float:
    """Duration of one step of a family's walk [s]: the T a walk command is planned with."""
    return float(_STEP_PERIODS[params.FAMILY](params))


def step_starts(params: GaitParams, n_steps: int) -> np.ndarray:
    """Start time [s] of each of ``n_steps`` commanded steps and the end of the last, (n_steps + 1,)."""
    return np.asarray(_STEP_STARTS[params.FAMILY](params, n_steps), dtype=float)


def generate(params: GaitParams, leg: LegGeometry = LegGeometry(), dt: float = 0.01,
             commands=None, limits: StepLimits | None = None) -> GaitTrajectory:
    """Joint table of any family's parameters, sampled every ``dt`` seconds.

    ``commands`` (n_steps, 3): a walk command per step (vx [m/s], vy [m/s], wz [rad/s]) on the
    axes :data:`COMMAND_AXES` allows; a step the family cannot take raises PlanError naming it.
    """
    if commands is None:
        return _GENERATORS[params.FAMILY](params, leg, dt)
    return _GENERATORS[params.FAMILY](params, leg, dt, commands=commands, limits=limits or StepLimits())
