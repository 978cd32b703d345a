"""gait-tuner's pure-math half: the three papers' gait generators, leg kinematics and parameters.

Nothing here imports a simulator or an optimiser (``tests/test_import_graph.py``
checks it): functions take and return numpy arrays and dataclasses.
"""

from __future__ import annotations

import numpy as np

from .baselines import list_baselines, load_baseline
from .command_stream import CommandStream
from .cosine_law import CosineLawParams
from .drive import Drive, UserController
from .engine import EngineParams, WalkEngine
from .eros import ErosParams
from .families import (GaitFamily, all_families, command_walk, families, family, family_class, family_of,
                       params_from_mapping)
from .footstep_planner import FootstepPlan, PlanError, StepLimits, plan_footsteps
from .imu_stabiliser import StabiliserParams, stabiliser_corrections
from .leg_kinematics import LegGeometry, UnreachableTargetError, leg_fk, leg_ik
from .limb_kinematics import ArmGeometry, HeadGeometry, arm_fk, head_fk
from .gait_file import GaitFile, gait_file_text, load_gait_file, save_gait_file
from .params import GaitParams, ParamError, did_you_mean
from .tlipfm import TlipfmParams
from .trajectory import JOINT_NAMES, GaitTrajectory
from .walk_command import DIRECTIONS, CommandRamp, SpeedStaircase, WalkCommand, parse_command

__all__ = [
    "ArmGeometry",
    "CommandStream",
    "Drive",
    "EngineParams",
    "WalkEngine",
    "UserController",
    "GaitFamily",
    "all_families",
    "command_walk",
    "family",
    "family_of",
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
    "did_you_mean",
    "families",
    "family_class",
    "generate",
    "head_fk",
    "leg_fk",
    "leg_ik",
    "list_baselines",
    "load_baseline",
    "gait_file_text",
    "load_gait_file",
    "params_from_mapping",
    "save_gait_file",
    "stabiliser_corrections",
    "step_period",
    "step_starts",
    "walks_direction",
]

def walks_direction(family_name: str, direction: str) -> bool:
    """Whether a family walks a speed-test direction (``DIRECTIONS``) on its command axes."""
    return family(family_name).walks_direction(DIRECTIONS[direction])


def step_period(params: GaitParams) -> float:
    """Duration of one step of a family's walk [s]: the T a walk command is planned with."""
    return float(family_of(params).step_period(params))


def step_starts(params: GaitParams, n_steps: int) -> np.ndarray:
    """Start time [s] of each of ``n_steps`` commanded steps and the end of the last, (n_steps + 1,)."""
    return np.asarray(family_of(params).step_starts(params, n_steps), dtype=float)


def generate(params: GaitParams, leg: LegGeometry = LegGeometry(), dt: float = 0.01,
             commands=None, limits: StepLimits | None = None) -> GaitTrajectory:
    """Joint table of any family's parameters, sampled every ``dt`` seconds.

    ``commands`` (n_steps, 3): a walk command per step (vx [m/s], vy [m/s], wz [rad/s]) on the
    family's command axes; a step the family cannot take raises PlanError naming it.
    """
    return family_of(params).generate(params, leg, dt, commands, limits)
