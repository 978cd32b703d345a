"""The MuJoCo solver options a robot file may set, and which of them differ from MuJoCo's defaults.

The simulated world (``tuner/sim/scene.py``) replaces a file's solver options by MuJoCo's own,
with which the surfaces were calibrated; the robot map notes which ones it replaced.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

__all__ = ["SOLVER_OPTIONS", "solver_differences"]

#: Solver options the surfaces were calibrated with (MuJoCo's defaults); a file's own are replaced.
SOLVER_OPTIONS = ("iterations", "ls_iterations", "tolerance", "ls_tolerance", "noslip_iterations",
                  "noslip_tolerance", "cone", "impratio", "solver", "jacobian", "gravity", "wind", "density",
                  "viscosity", "disableflags", "enableflags")


def solver_differences(option: Any) -> list[str]:
    """The solver options of a file (its compiled ``MjModel.opt`` or its ``MjSpec.option``: the
    fields have the same names) that differ from MuJoCo's defaults (ours), as 'name value'."""
    fresh = mujoco.MjSpec().option
    out = []
    for name in SOLVER_OPTIONS:
        theirs, ours = getattr(option, name), getattr(fresh, name)
        if not np.array_equal(np.asarray(theirs), np.asarray(ours)):
            out.append(f"{name} {np.asarray(theirs).tolist()}")
    return out
