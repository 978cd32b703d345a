"""Simulation wing: the one MuJoCo rollout, the surfaces it walks on, randomisation, metrics.

``rollout`` is the only module that steps physics; the others score or perturb what it returns.
"""

from __future__ import annotations

from .metrics import DEFINITIONS, Metrics, summarize
from .randomisation import Perturbation, Randomisation, draw
from .rollout import FallCriteria, Simulator, Trace
from .surfaces import SURFACES, Surface, load_surface

__all__ = [
    "DEFINITIONS",
    "FallCriteria",
    "Metrics",
    "Perturbation",
    "Randomisation",
    "SURFACES",
    "Simulator",
    "Surface",
    "Trace",
    "draw",
    "load_surface",
    "summarize",
]
