"""A gait's joint table in a robot's own joint names and signs, ready for its controller.

Columns: every joint the map names, as the MJCF names it, with the map's sign applied and
non-leg joints moved about their held pose (``RobotModel.pose``), then every held joint the
map does not name, constant at its pose. Angles in radians, as the MJCF's joints measure them.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from gaits import JOINT_NAMES, GaitTrajectory

from .robot_model import RobotModel

__all__ = ["robot_joint_table", "joint_table_file"]


def robot_joint_table(traj: GaitTrajectory, robot: RobotModel) -> GaitTrajectory:
    """``traj`` with its q_ref columns in ``robot``'s joint names and signs (N, n_joints)."""
    ours = [n for n in JOINT_NAMES if n in robot.joint_map]
    cols, names = [], []
    for n in ours:
        theirs, sign = robot.joint_map[n]
        cols.append(sign * traj.q_ref[:, traj.joint_names.index(n)] + robot.pose.get(theirs, 0.0))
        names.append(theirs)
    # the extra joints (a gait drives the 20 roles) and the held ones stand at their pose
    for theirs in [robot.joint_map[n][0] for n in robot.extra_joints] + list(robot.held_joints):
        cols.append(np.full(len(traj.t), robot.pose.get(theirs, 0.0)))
        names.append(theirs)
    return dataclasses.replace(traj, q_ref=np.column_stack(cols), joint_names=tuple(names),
                               meta={**traj.meta, "robot": robot.name, "joint_names": "robot"})


def joint_table_file(traj: GaitTrajectory, robot: RobotModel, path: Path, joint_names: str, comment: str,
                     table_format: str = "csv", clip: bool = False) -> tuple[Path, str, list[str]]:
    """(path, text, notes) of the joint table of ``traj`` for ``robot`` as CSV, headed by a comment
    naming what it is for; ``table_format`` servo: in the map's servo units instead
    (``<name>.servo.csv``, checked). ``notes``: what the caller should say (a table clipped, a
    servo asked for more than its speed). The caller writes it with the files it belongs with
    (``write_files_atomic``)."""
    from ..errors import UserError
    from .servo_table import check_positions, check_table, servo_columns, to_units, too_fast
    said: list[str] = []
    if clip and joint_names != "robot":
        raise UserError("--clip writes the robot's own joints: leave out --joint-names ours")
    if table_format == "servo" and joint_names != "robot":
        raise UserError("--format servo writes the robot's own joints: leave out --joint-names ours")
    table = robot_joint_table(traj, robot)
    names = tuple(table.joint_names)
    speed = np.array([robot.servos[n].speed for n in names])
    if table_format == "csv":
        if clip:                             # the table the servos play, as the simulator's servo does
            lo, hi = robot.joint_ranges(names)
            q, notes = check_table(table.q_ref, table.t, names, speed, lo, hi, True)
            said += notes
            table = dataclasses.replace(table, q_ref=q)
            comment += "; joint targets clipped to the servos' speed and range (the references are the plan's)" if notes else ""
        else:
            rate, over = too_fast(table.q_ref, table.t, speed)
        if not clip and over.any():          # said, as the simulator's servo limits it (never silently)
            j = int(np.argmax((rate / speed).max(axis=0)))
            said.append(f"the table asks {names[j]} for up to {rate[:, j].max():.2f} rad/s where its servo "
                        f"gives {speed[j]:g} rad/s (the simulated servo moves at most that fast; "
                        f"{int(over.any(axis=1).sum())} row(s) ask more of some servo): --clip writes what the "
                        f"servos can play")
        if joint_names == "robot":
            traj = table
        return path, traj.csv_text(comment=f"gait-tuner joint table for robot {robot.name} "
                                           f"({joint_names} joint names and signs; angles in rad); {comment}"), said
    units = servo_columns(robot.servo_units, names)
    lo, hi = robot.joint_ranges(names)
    q, notes = check_table(table.q_ref, table.t, names, speed, lo, hi, clip)
    said += notes
    ticks = np.column_stack([to_units(q[:, j], u) for j, u in enumerate(units)])
    check_positions(ticks, table.t, names, units)
    dt = float(np.median(np.diff(table.t)))
    out = path.with_name(path.name.replace("joints.csv", "servo.csv")) if path.name.endswith("joints.csv") \
        else path.with_suffix(".servo.csv")
    rows = [f"# gait-tuner servo table for robot {robot.name}; {comment}; every {dt * 1000:g} ms "
            f"({1 / dt:g} Hz); positions in the servos' units (robot map servos:)" +
            ("; clipped to the servos' speed and range" if notes else ""),
            "# " + ", ".join(f"id{u.id} = {n} ({u.units_per_rad * 2 * np.pi:g} per turn, centre {u.centre:g}, "
                             f"direction {u.direction:+d}, offset {u.offset:g} rad)" for n, u in zip(names, units)),
            "# the servos it was tuned with (write these into them): " + servo_settings(robot, names),
            "t_s," + ",".join(f"id{u.id}" for u in units)]
    rows += [f"{t:.4f}," + ",".join(str(int(v)) for v in r) for t, r in zip(table.t, ticks)]
    return out, "\n".join(rows) + "\n", said


def servo_settings(robot: RobotModel, names) -> str:
    """What the simulated servos of ``names`` (the robot's joints) were, as a team sets its own: a
    motor's P register and supply voltage, a pd servo's gain and torque; ids grouped by setting."""
    from ..servos import MotorServo
    groups: dict[str, list[str]] = {}
    for n in names:
        s = robot.servos[n]
        if isinstance(s, MotorServo):
            key = f"{s.preset or 'motor'} P {s.p_gain:.4g} at {s.voltage:g} V ({s.friction_model})"
        else:
            key = f"pd kp {s.kp:g} N m/rad, kv {s.kv + 0.0:g}, {s.torque:g} N m"
        groups.setdefault(key, []).append(n)
    return "; ".join(f"{k}: {', '.join(v)}" for k, v in groups.items())
