"""gait-tuner's running half: command line, plots (and, in later issues, simulation and search)."""

from __future__ import annotations

from .errors import UserError
from .params_io import resolve_params

__all__ = ["UserError", "resolve_params"]
