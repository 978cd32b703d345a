"""gait-tuner's running half: robots, surfaces, simulation, metrics, the CasADi seed and the search.

``gaits`` holds the pure math; everything that steps physics or optimises lives here.
"""

from __future__ import annotations

from .errors import UserError
from .sim.metrics import DEFINITIONS, Metrics, summarize
from .params_io import resolve_params
from .sim.randomisation import Randomisation
from .robots import RobotModel, RobotSpec, ServoSpec, load_robot
from .sim.rollout import FallCriteria, Simulator, Trace
from .sim.surfaces import SURFACES, Surface, load_surface

__all__ = [
    "DEFINITIONS",
    "FallCriteria",
    "Metrics",
    "Randomisation",
    "RobotModel",
    "RobotSpec",
    "SURFACES",
    "ServoSpec",
    "Simulator",
    "Surface",
    "Trace",
    "UserError",
    "load_robot",
    "load_surface",
    "resolve_params",
    "summarize",
]
