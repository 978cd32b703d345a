"""gait-tuner's pure-math half: the three papers' gait generators, leg kinematics and parameters.

Nothing here imports a simulator or an optimiser (``tests/test_import_graph.py``
checks it): functions take and return numpy arrays and dataclasses.
"""

from __future__ import annotations

from typing import Callable

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
]

_GENERATORS: dict[str, Callable[..., GaitTrajectory]] = {
    "eros": eros.generate,
    "tlipfm": tlipfm.generate,
    "cosine": cosine_law.generate,
}


#: What each family does with a walk command (``gaits/walk_command.py``), as ``params`` says it.
COMMANDS: dict[str, str] = {
    "tlipfm": "any (vx, vy, wz): the footstep planner's steps, hip yaw turns the feet",
    "eros": "none: its quarter-circle steps walk straight ahead only (lateral and turning via "
            "points are not built)",
    "cosine": "none: the 5-DoF leg has no hip yaw, so forward and backward only in principle, "
              "and per-step commands are not built",
}


def generate(params: GaitParams, leg: LegGeometry = LegGeometry(), dt: float = 0.01,
             commands=None, limits: StepLimits | None = None) -> GaitTrajectory:
    """Joint table of any family's parameters, sampled every ``dt`` seconds.

    ``commands`` (n_steps, 3): a walk command per step (vx [m/s], vy [m/s], wz [rad/s]); only
    the families whose :data:`COMMANDS` entry allows it take one, others raise ParamError.
    """
    if commands is None:
        return _GENERATORS[params.FAMILY](params, leg, dt)
    if params.FAMILY != "tlipfm":
        raise ParamError(f"gait {params.FAMILY!r} takes no walk command: {COMMANDS[params.FAMILY]}")
    return tlipfm.generate(params, leg, dt, commands=commands, limits=limits or StepLimits())
