"""The robots room: the built-in kid-size humanoid, and the one adapter between a user's MJCF and
our simulation (a robot map YAML naming its torso, feet and leg joints).

* ``kidsize.py``: the built-in robot; ``robot_map.py``: reading and checking a map; ``urdf.py``: a
  map's URDF read into MJCF (fixed-joint links kept, the torso given the free joint);
  ``mjcf_geometry.py``: what is derived from a model (axis lines, sole hull, CoM);
  ``solver.py``: the solver options a file may set. The servos (laws and presets) are their own
  room, ``tuner/servos/``.
  The robot on a surface (our servos, sensors and drag) is built by ``tuner/sim/scene.py``; the
  ``robot check`` report is ``tuner/report/robot_check.py``.
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path
from typing import Callable

from gaits import did_you_mean

from ..errors import UserError
from .kidsize import RobotSpec, kidsize_model, kidsize_spec, kidsize_xml
from .robot_map import LEG_AXES, load_map
from .robot_model import RobotModel, SimOptions
from ..servos import MotorServo, preset

__all__ = ["BUILTIN_ROBOTS", "LEG_AXES", "RobotModel", "RobotSpec", "SimOptions", "kidsize_spec", "kidsize_xml",
           "load_robot"]

BUILTIN_ROBOTS: dict[str, Callable[[], RobotModel]] = {
    "kidsize": kidsize_model,
    # round one to four's servos (the pd law, tuner/servos/pd.py): the papers' figures and the sets tuned then
    "kidsize-pd": lambda: kidsize_model(RobotSpec(name="kidsize-pd", leg_servo=preset("MX-64-pd"),
                                                  arm_servo=preset("MX-28-pd"))),
}
#: a built-in robot's battery at another voltage: ``kidsize@13.5V`` (its dc-motor servos only)
_AT_VOLTAGE = re.compile(r"^(?P<robot>[a-z0-9-]+)@(?P<volts>[0-9]+(?:\.[0-9]+)?)V$")
VOLTAGE_RANGE = (6.0, 20.0)      # [V] what a kid-size robot's battery gives (2S to a full 4S LiPo and a margin)


def load_robot(name_or_path: str | Path, *, relative_to: Path | None = None) -> RobotModel:
    """The built-in robot by name (``kidsize``; ``kidsize@13.5V`` for its battery at another voltage;
    ``kidsize-pd`` on round one's servos) or a robot map YAML (see ``robot_map.py``). A relative map
    path resolves against ``relative_to`` (a study file's folder) when given."""
    name = str(name_or_path)
    if name in BUILTIN_ROBOTS:
        return BUILTIN_ROBOTS[name]()
    at = _AT_VOLTAGE.match(name)
    if at is not None and at["robot"] in BUILTIN_ROBOTS:
        return _at_voltage(BUILTIN_ROBOTS[at["robot"]](), float(at["volts"]), name)
    path = Path(name)
    if relative_to is not None and not path.is_absolute():
        path = relative_to / path
    if not os.path.lexists(path):
        raise UserError(f"robot {name!r}: not a built-in robot{did_you_mean(name, BUILTIN_ROBOTS)} "
                        f"({', '.join(BUILTIN_ROBOTS)}) and no such file"
                        + (f" (looked in {relative_to})" if relative_to is not None else ""))
    return load_map(path)


def _at_voltage(robot: RobotModel, volts: float, name: str) -> RobotModel:
    lo, hi = VOLTAGE_RANGE
    if not lo <= volts <= hi:
        raise UserError(f"robot {name!r}: {volts:g} V is outside [{lo:g}, {hi:g}] V (a kid-size robot's battery)")
    if not any(isinstance(s, MotorServo) for s in robot.servos.values()):
        raise UserError(f"robot {name!r}: its servos are not driven by a voltage (the pd law); drop @{volts:g}V")
    servos = {j: (s.replace(voltage=volts) if isinstance(s, MotorServo) else s) for j, s in robot.servos.items()}
    return dataclasses.replace(robot, name=name, servos=servos)
