"""The one cache of built simulators in a process: a :class:`Simulator` compiles its model once
(50-200 ms) and serves every rollout of that robot on that surface after it.

Robots are named by their spec (a built-in name or a map path, loaded once) or passed as a
loaded ``RobotModel``; surfaces by name, file or ``Surface`` value. The cache keeps the
:data:`SIZE` most recently used simulators (a worker walks a few robots and surfaces at a time).
"""

from __future__ import annotations

from collections import OrderedDict

from ..robots import RobotModel, load_robot
from .rollout import Simulator
from .surfaces import Surface, load_surface

__all__ = ["simulator", "robot", "SIZE"]

SIZE = 8
_ROBOTS: dict[str, RobotModel] = {}
_SIMS: OrderedDict = OrderedDict()


def robot(spec: str | RobotModel) -> RobotModel:
    """A robot loaded once per process by its spec (built-in name or map path)."""
    if isinstance(spec, RobotModel):
        return spec
    if spec not in _ROBOTS:
        _ROBOTS[spec] = load_robot(spec)
    return _ROBOTS[spec]


def simulator(robot_spec: str | RobotModel, surface: str | Surface) -> Simulator:
    """The simulator of a robot on a surface, built on first use and kept."""
    r = robot(robot_spec)
    s = load_surface(surface) if isinstance(surface, str) else surface
    key = (id(r), s)
    if key in _SIMS:
        _SIMS.move_to_end(key)
        return _SIMS[key][1]
    sim = Simulator(r, s)
    _SIMS[key] = (r, sim)              # the robot is kept with it, so its id is never reused
    while len(_SIMS) > SIZE:
        _SIMS.popitem(last=False)
    return sim
