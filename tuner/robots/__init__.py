"""The robots room: the built-in kid-size humanoid, and the one adapter between a user's MJCF and
our simulation (a robot map YAML naming its torso, feet and leg joints)."""

from __future__ import annotations

from .robot import (BUILTIN_ROBOTS, LEG_AXES, RobotModel, RobotSpec, ServoSpec, kidsize_spec,
                    kidsize_xml, leg_geometry_report, load_robot)

__all__ = ["BUILTIN_ROBOTS", "LEG_AXES", "RobotModel", "RobotSpec", "ServoSpec", "kidsize_spec",
           "kidsize_xml", "leg_geometry_report", "load_robot"]
