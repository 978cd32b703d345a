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
from .imu_stabiliser import StabiliserParams, stabiliser_corrections
from .leg_kinematics import LegGeometry, UnreachableTargetError, leg_fk, leg_ik
from .limb_kinematics import ArmGeometry, HeadGeometry, arm_fk, head_fk
from .params import (GaitFile, GaitParams, ParamError, families, family_class, load_gait_file,
                     params_from_mapping, save_gait_file)
from .tlipfm import TlipfmParams
from .trajectory import JOINT_NAMES, GaitTrajectory

__all__ = [
    "ArmGeometry",
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


def generate(params: GaitParams, leg: LegGeometry = LegGeometry(), dt: float = 0.01) -> GaitTrajectory:
    """Joint table of any family's parameters, sampled every ``dt`` seconds."""
    return _GENERATORS[params.FAMILY](params, leg, dt)
