"""The robots room: the built-in kid-size humanoid, and the one adapter between a user's MJCF and
our simulation (a robot map YAML naming its torso, feet and leg joints).

* ``kidsize.py``: the built-in robot; ``robot_map.py``: reading and checking a map; ``urdf.py``: a
  map's URDF read into MJCF (fixed-joint links kept, the torso given the free joint);
  ``mjcf_geometry.py``: what is derived from a model (axis lines, sole hull, CoM);
  ``servo.py``: the servo model and presets; ``solver.py``: the solver options a file may set.
  The robot on a surface (our servos, sensors and drag) is built by ``tuner/sim/scene.py``; the
  ``robot check`` report is ``tuner/report/robot_check.py``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

from gaits import did_you_mean

from ..errors import UserError
from .kidsize import RobotSpec, kidsize_model, kidsize_spec, kidsize_xml
from .robot_map import LEG_AXES, load_map
from .robot_model import RobotModel, SimOptions
from .servo import SERVO_PRESETS, ServoSpec

__all__ = ["BUILTIN_ROBOTS", "LEG_AXES", "RobotModel", "RobotSpec", "SERVO_PRESETS",
           "ServoSpec", "SimOptions", "kidsize_spec", "kidsize_xml", "load_robot"]

BUILTIN_ROBOTS: dict[str, Callable[[], RobotModel]] = {"kidsize": kidsize_model}


def load_robot(name_or_path: str | Path, *, relative_to: Path | None = None) -> RobotModel:
    """The built-in robot by name (``kidsize``) or a robot map YAML (see ``robot_map.py``).
    A relative map path resolves against ``relative_to`` (a study file's folder) when given."""
    name = str(name_or_path)
    if name in BUILTIN_ROBOTS:
        return BUILTIN_ROBOTS[name]()
    path = Path(name)
    if relative_to is not None and not path.is_absolute():
        path = relative_to / path
    if not os.path.lexists(path):
        raise UserError(f"robot {name!r}: not a built-in robot{did_you_mean(name, BUILTIN_ROBOTS)} "
                        f"({', '.join(BUILTIN_ROBOTS)}) and no such file"
                        + (f" (looked in {relative_to})" if relative_to is not None else ""))
    return load_map(path)
