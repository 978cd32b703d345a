"""placo's walk as a controller (the ``placo`` extra; ours, the adapter at that border): Rhoban's
walk pattern generator (``placo.WalkPatternGenerator``: a ZMP preview on footsteps from
``placo.FootstepsPlannerRepetitive``, the whole body by ``placo.KinematicsSolver``'s QP), driven
by the walk command and re-planned at its own period, as placo's own walk example runs it. Open
loop: it plans from its own trajectory, not from the sensors (as the example does).

A placo file names its parameters (every number a study may search, with ``ranges:``)::

    placo:                          # placo.HumanoidParameters' fields, SI units
      single_support_duration: 0.38     # [s]
      single_support_timesteps: 10
      double_support_ratio: 0.0
      startend_double_support_ratio: 1.5
      planned_timesteps: 48
      walk_com_height: 0.32             # [m]
      walk_foot_height: 0.04            # [m]
      walk_trunk_pitch: 0.15            # [rad]
      walk_foot_rise_ratio: 0.2
      feet_spacing: 0.122               # [m]
      zmp_margin: 0.02                  # [m]
      walk_max_dtheta: 1.0              # [rad] a step's largest turn
      walk_max_dy: 0.04                 # [m]
      walk_max_dx_forward: 0.08         # [m]
      walk_max_dx_backward: 0.03        # [m]
      replan_period: 0.1                # [s] ours: how often the footsteps are re-planned
    ranges: {walk_com_height: {low: 0.28, high: 0.34}}

The robot must be given as URDF (its map's ``urdf:``): placo reads the file itself. It needs frames
named ``trunk``, ``left_foot`` and ``right_foot``; where the file has none, the adapter adds them
(fixed links at the torso's origin and at each sole's centre, ours). The sole's size comes from the
robot map. A step's length is the command times the step's period (ours), within the file's limits.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from gaits import JOINT_NAMES, ParamError
from gaits.control import PlanRecord, StartPose

__all__ = ["PlacoFactory", "PlacoWalk", "PLACO_DEFAULTS"]

#: The parameters a placo file may set, and placo's example's values for Sigmaban (the defaults).
PLACO_DEFAULTS = {"single_support_duration": 0.38, "single_support_timesteps": 10, "double_support_ratio": 0.0,
                  "startend_double_support_ratio": 1.5, "planned_timesteps": 48, "walk_com_height": 0.32,
                  "walk_foot_height": 0.04, "walk_trunk_pitch": 0.15, "walk_foot_rise_ratio": 0.2,
                  "feet_spacing": 0.122, "zmp_margin": 0.02, "walk_max_dtheta": 1.0, "walk_max_dy": 0.04,
                  "walk_max_dx_forward": 0.08, "walk_max_dx_backward": 0.03, "replan_period": 0.1}
_INTEGERS = ("single_support_timesteps", "planned_timesteps")


def _rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF's roll, pitch, yaw of a rotation (fixed axes x, y, z), as the URDF reader writes them."""
    from scipy.spatial.transform import Rotation
    return tuple(float(v) for v in Rotation.from_matrix(R).as_euler("xyz"))


def _with_frames(text: str, robot: Any) -> str:
    """The URDF with fixed ``trunk``, ``left_foot`` and ``right_foot`` links added where it has none:
    at the torso's origin and at each foot body's sole centre, turned to the sole's own axes (x
    forward, z up: the robot map's sole frame; a foot body's axes may be turned, as Wolfgang-OP's
    are by 90 and tilted 15 deg), and its ROS packages' paths (``package://NAME/``) made the folders
    the robot's loader found them in (placo reads the file itself, and a team's URDF names its
    meshes so)."""
    for name, folder in (getattr(robot, "package_dirs", None) or {}).items():
        text = text.replace(f"package://{name}/", f"{folder}/")
    links = set(re.findall(r'<link\s+name="([^"]+)"', text))
    extra = []
    if "trunk" not in links:
        extra.append(("trunk", robot.torso, (0.0, 0.0, 0.0), np.eye(3)))
    axes = getattr(robot, "sole_axes", None) or (np.eye(3), np.eye(3))
    for side, name in ((0, "left_foot"), (1, "right_foot")):
        if name not in links:
            # a sole-frame point s sits at soles + s @ R in the foot frame: the sole's rotation is R^T
            extra.append((name, robot.feet[side], tuple(float(v) for v in robot.soles[side]),
                          np.asarray(axes[side], dtype=float).T))
    if not extra:
        return text
    rows = []
    for name, parent, xyz, R in extra:
        r, p, y = _rpy(R)
        rows.append(f'  <link name="{name}"/>\n  <joint name="{name}_placo_frame" type="fixed">\n'
                    f'    <parent link="{parent}"/>\n    <child link="{name}"/>\n'
                    f'    <origin xyz="{xyz[0]:.9g} {xyz[1]:.9g} {xyz[2]:.9g}" rpy="{r:.12g} {p:.12g} {y:.12g}"/>\n'
                    f'  </joint>\n')
    return text.replace("</robot>", "".join(rows) + "</robot>")


class PlacoWalk:
    """placo's walk for one walk (module docstring); the ``gaits.control.Controller`` protocol."""

    senses = frozenset()

    def __init__(self, params: Mapping[str, float], robot: Any, dt: float) -> None:
        try:
            import placo
        except ImportError:
            raise ParamError("placo's walk needs placo: pip install 'gait-tuner[placo]'") from None
        urdf = getattr(robot, "urdf_path", None)
        if not urdf:
            raise ParamError(f"placo's walk reads the robot as URDF: robot {getattr(robot, 'name', '?')} has none (give "
                             f"a robot map with urdf:)")
        self.placo = placo
        self.p = {**PLACO_DEFAULTS, **params}
        self.dt = float(dt)
        self.duration = None
        self.walk_start = 0.0
        self.jmap = dict(robot.joint_map)
        self.held = dict(getattr(robot, "pose", {}) or {})
        self.foot_size = tuple(float(v) for v in robot.foot_size)
        # placo's first solve starts from the robot's walking crouch (its legs bent as ours bends them),
        # not the file's zero pose: from there a leg bent at zero (Wolfgang-OP's) found the solution
        # with its knee bent backwards, into its limit
        from gaits.leg_kinematics import crouch_angles
        self.crouch = crouch_angles(robot.leg, self.jmap)
        text = _with_frames(Path(urdf).read_text(encoding="utf-8"), robot)
        self._urdf = (str(Path(urdf).parent), text)
        self._build()

    def _build(self) -> None:
        placo = self.placo
        self.robot = placo.HumanoidRobot(self._urdf[0], int(placo.Flags.ignore_collisions), self._urdf[1])
        hp = placo.HumanoidParameters()
        for k, v in self.p.items():
            if k == "replan_period":
                continue
            setattr(hp, k, int(round(v)) if k in _INTEGERS else float(v))
        hp.foot_length, hp.foot_width = self.foot_size
        self.hp = hp
        self.solver = placo.KinematicsSolver(self.robot)
        self.solver.enable_velocity_limits(True)
        self.solver.dt = self.dt
        self.tasks = placo.WalkTasks()
        self.tasks.initialize_tasks(self.solver, self.robot)
        legs = {theirs for ours, (theirs, _) in self.jmap.items() if ours[2:] in
                ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")}
        others = {j: float(v) for j, v in self.held.items() if j not in legs}
        if others:
            joints = self.solver.add_joints_task()
            joints.set_joints(others)
            joints.configure("joints", "soft", 1.0)
        self.planner = placo.FootstepsPlannerRepetitive(hp)
        self.pattern = placo.WalkPatternGenerator(self.robot, hp)

    def _ours(self) -> np.ndarray:
        q = np.zeros(len(JOINT_NAMES))
        for i, name in enumerate(JOINT_NAMES):
            if name in self.jmap:
                theirs, sign = self.jmap[name]
                q[i] = sign * float(self.robot.get_joint(theirs))
        return q

    def _configure(self, command: np.ndarray) -> None:
        p = self.p
        T = p["single_support_duration"] * (1.0 + p["double_support_ratio"])    # one step [s]
        dx = float(np.clip(command[0] * T, -p["walk_max_dx_backward"], p["walk_max_dx_forward"]))
        dy = float(np.clip(command[1] * T, -p["walk_max_dy"], p["walk_max_dy"]))
        dth = float(np.clip(command[2] * T, -p["walk_max_dtheta"], p["walk_max_dtheta"]))
        self.planner.configure(dx, dy, dth, 10)

    def start_pose(self) -> StartPose:
        self._build()
        for joint, angle in self.crouch.items():
            self.robot.set_joint(joint, angle)
        self.robot.update_kinematics()
        self.tasks.reach_initial_pose(np.eye(4), self.hp.feet_spacing, self.hp.walk_com_height,
                                      self.hp.walk_trunk_pitch)
        self._plan(np.zeros(3))
        return StartPose(self._ours())

    def _plan(self, command: np.ndarray) -> None:
        placo = self.placo
        self._configure(command)
        left = placo.flatten_on_floor(self.robot.get_T_world_left())
        right = placo.flatten_on_floor(self.robot.get_T_world_right())
        steps = self.planner.plan(placo.HumanoidRobot_Side.left, left, right)
        supports = placo.FootstepsPlanner.make_supports(steps, 0.0, True, self.hp.has_double_support(), True)
        self.trajectory = self.pattern.plan(supports, self.robot.com_world(), 0.0)
        self.t = 0.0
        self.last_replan = 0.0
        self.steps = 0

    def reset(self, m: Any) -> None:
        pass

    def step(self, m: Any, command: np.ndarray | None = None) -> np.ndarray:
        c = np.zeros(3) if command is None else np.asarray(command, dtype=float)
        self.t += self.dt
        t, traj = self.t, self.trajectory
        if t - self.last_replan > self.p["replan_period"] and self.pattern.can_replan_supports(traj, t):
            self._configure(c)
            supports = self.pattern.replan_supports(self.planner, traj, t, self.last_replan)
            self.last_replan = t
            self.trajectory = traj = self.pattern.replan(supports, traj, t)
        self.tasks.update_tasks_from_trajectory(traj, t)
        self.robot.update_kinematics()
        self.solver.solve(True)
        if not traj.support_is_both(t):
            self.robot.update_support_side(str(traj.support_side(t)))
            self.robot.ensure_on_floor()
        q = self._ours()
        if not np.all(np.isfinite(q)):
            raise ParamError("placo's walk returned targets that are not finite")
        return q

    def plan(self, n: int) -> PlanRecord:
        """placo's plan is its own; the metrics get double support at the start stance."""
        W = self.p["feet_spacing"] / 2
        z = np.zeros((n, 2))
        return PlanRecord("placo", np.zeros(n, dtype=int), z, z + np.array([0.0, W]), z - np.array([0.0, W]),
                          walk_start=0.0, cycle_time=2 * self.p["single_support_duration"],
                          meta={"placo": True})


class PlacoFactory:
    """Builds a :class:`PlacoWalk`: ``factory(params, robot, dt)`` (a controller class's signature,
    ``gaits.drive.UserController``); picklable for a study's workers."""

    def __call__(self, params: Mapping[str, float], robot: Any, dt: float) -> PlacoWalk:
        return PlacoWalk(params, robot, dt)


def placo_params(doc: Any, source: str) -> dict[str, float]:
    """A placo file's ``placo:`` section, checked: known names, finite numbers (positive where a
    duration, a height or a size), the defaults for the rest."""
    if not isinstance(doc, Mapping):
        raise ParamError(f"{source}: placo: expected a mapping of placo.HumanoidParameters fields")
    out = dict(PLACO_DEFAULTS)
    for k, v in doc.items():
        if k not in PLACO_DEFAULTS:
            raise ParamError(f"{source}: placo: unknown parameter {k!r} (known: {', '.join(PLACO_DEFAULTS)})")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise ParamError(f"{source}: placo.{k} = {v!r}: expected a finite number >= 0")
        out[k] = float(v)
    for k in ("single_support_duration", "walk_com_height", "replan_period", "single_support_timesteps",
              "planned_timesteps"):
        if out[k] <= 0:
            raise ParamError(f"{source}: placo.{k} = {out[k]:g}: expected a positive number")
    return out
