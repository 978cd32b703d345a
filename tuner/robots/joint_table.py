"""A gait's joint table in a robot's own joint names and signs, ready for its controller.

Columns: every joint the map names, as the MJCF names it, with the map's sign applied and
non-leg joints moved about their held pose (``RobotModel.pose``), then every held joint the
map does not name, constant at its pose. Angles in radians, as the MJCF's joints measure them.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gaits import JOINT_NAMES, GaitTrajectory

from .robot_model import RobotModel

__all__ = ["robot_joint_table"]


def robot_joint_table(traj: GaitTrajectory, robot: RobotModel) -> GaitTrajectory:
    """``traj`` with its q_ref columns in ``robot``'s joint names and signs (N, n_joints)."""
    ours = [n for n in JOINT_NAMES if n in robot.joint_map]
    cols, names = [], []
    for n in ours:
        theirs, sign = robot.joint_map[n]
        cols.append(sign * traj.q_ref[:, traj.joint_names.index(n)] + robot.pose.get(theirs, 0.0))
        names.append(theirs)
    for theirs in robot.held_joints:
        cols.append(np.full(len(traj.t), robot.pose.get(theirs, 0.0)))
        names.append(theirs)
    return dataclasses.replace(traj, q_ref=np.column_stack(cols), joint_names=tuple(names),
                               meta={**traj.meta, "robot": robot.name, "joint_names": "robot"})
