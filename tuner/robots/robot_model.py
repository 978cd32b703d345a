"""A robot ready for the simulator: its MJCF, joint map, key bodies, leg geometry, servos, held pose."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

import mujoco
import numpy as np

from gaits import JOINT_NAMES, LegGeometry
from gaits.leg_kinematics import LEG_JOINTS
from gaits.robot.robot_file import SENSING_GAP, ImuBoard

from ..errors import UserError
from ..servos import ServoLaw

if TYPE_CHECKING:
    from gaits.robot.robot_file import RobotFile

__all__ = ["RobotModel", "SimOptions", "joint_group", "GROUPS"]

#: Servo groups a map can configure (``servo: {legs: ..., arms: ..., head: ..., other: ...}``).
GROUPS = ("legs", "arms", "head", "other")


#: Finer servo groups a map can configure over the legs (an identification fits these): a
#: joint's ``servo:`` entry is its group's, then its finer group's, then its own (our joint name).
FINE_GROUPS = ("hips", "knees", "ankles")


def fine_group(ours: str) -> str | None:
    """The finer servo group of one of our leg joint names (None for arms, head, others)."""
    tail = ours[2:]
    if ours[:2] in ("l_", "r_") and tail in LEG_JOINTS:
        return "hips" if tail.startswith("hip_") else "knees" if tail == "knee" else "ankles"
    return None


def joint_group(ours: str | None) -> str:
    """The servo group of one of our joint names (None: a joint the map does not name)."""
    if ours is None:
        return "other"
    if ours[2:] in LEG_JOINTS:
        return "legs"
    if ours.startswith("head_"):
        return "head"
    return "arms"


@dataclass(frozen=True)
class SimOptions:
    """Per-robot simulation options (a map's ``sim:``); defaults are the built-in robot's."""

    control_period: float = 0.01      # [s] servo target update period
    timestep: float = 0.002           # [s] physics step
    max_tilt_deg: float = 50.0        # [deg] torso tilt from upright that counts as a fall
    min_height_ratio: float = 0.6     # [-] torso below this fraction of its start height: a fall

    def __post_init__(self) -> None:
        ranges = {"control_period": (0.001, 0.1, "s"), "timestep": (0.0001, 0.01, "s"),
                  "max_tilt_deg": (5.0, 90.0, "deg"), "min_height_ratio": (0.1, 0.95, "")}
        for name, (lo, hi, unit) in ranges.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo <= v <= hi) or not math.isfinite(v):
                raise UserError(f"sim.{name} = {v!r} {unit} is out of range [{lo:g}, {hi:g}] {unit}".replace("  ", " "))
            object.__setattr__(self, name, float(v))
        n = self.control_period / self.timestep
        if abs(n - round(n)) > 1e-6:
            raise UserError(f"sim.control_period = {self.control_period:g} s must be a whole multiple of "
                            f"sim.timestep = {self.timestep:g} s")


@dataclass(frozen=True)
class RobotModel:
    """A robot ready for the simulator.

    ``joint_map`` maps each of our joint names (:data:`gaits.JOINT_NAMES`) the robot has to
    (MJCF joint name, sign): legs required, head and arms optional; a joint beyond the 20 roles
    goes under a name of the map's own (``extra_joints``, :attr:`extra_joints`). ``servos`` gives every
    hinge joint we actuate (mapped or held) its servo, keyed by MJCF joint name; ``pose``
    holds the angle [rad, the file's convention] at which every non-leg joint is held.
    ``feet`` names the foot bodies, ``soles`` their sole centres in the foot frame,
    ``sole_hulls`` their sole polygons (M, 2) in the sole frame (foot origin, torso axes at the
    zero pose) and ``sole_axes`` the rotation from each foot frame into its sole frame. ``sources`` says where each
    derived number came from, ``notes`` what the adapter changed (both for ``robot check``).
    """

    name: str
    xml: str
    joint_map: Mapping[str, tuple[str, int]]
    torso: str
    feet: tuple[str, str]
    soles: tuple[tuple[float, float, float], tuple[float, float, float]]
    foot_size: tuple[float, float]               # [m] length, width of the sole's bounding box
    leg: LegGeometry
    servos: Mapping[str, ServoLaw]
    pose: Mapping[str, float] = field(default_factory=dict)
    sole_hulls: tuple[np.ndarray, ...] = ()
    sources: Mapping[str, str] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    sim: SimOptions = SimOptions()
    mjcf_path: str | None = None                  # set for user robots: meshes resolve beside it
    map_path: str | None = None
    sole_axes: tuple[np.ndarray, ...] = (np.eye(3), np.eye(3))
    #: per foot, the bodies that carry its sole geoms (the foot and bodies welded to it, e.g.
    #: cleats) with their pose in the foot frame (name, R_foot_body (3, 3), p_foot_body (3,));
    #: empty: the foot body alone. Touch sensors are per body, so each gets its own sites.
    sole_bodies: tuple[tuple[tuple[str, np.ndarray, np.ndarray], ...], ...] = ()
    urdf_path: str | None = None                  # a URDF robot's file (``xml`` is its MJCF, meshes absolute)
    #: a URDF robot's ROS packages (``package://NAME/``) -> their folders, as the URDF reader found them
    package_dirs: Mapping[str, str] = field(default_factory=dict)
    servo_units: Mapping[str, Any] = field(default_factory=dict)   # file joint -> servo_table.ServoUnit
    #: each foot's own sole bounding box (length, width) [m], left then right; empty: both ``foot_size``
    #: (which, for unequal feet, is the larger of the two in each direction: what the planners keep apart)
    foot_sizes: tuple[tuple[float, float], ...] = ()
    #: an MJCF robot file read with MuJoCo's ``balanceinertia`` (a map's ``balance_inertia: true``;
    #: a URDF robot's ``xml`` carries the compiler option itself)
    balance_inertia: bool = False
    #: body pairs that do not collide with each other (their shapes interpenetrate at the zero pose
    #: or the walking crouch: ``mjcf_geometry.self_overlaps``), added to the file's own exclusions
    exclude: tuple[tuple[str, str], ...] = ()
    #: joint groups (``GROUPS``) whose gains (kp, kv) are a preset's because neither the file nor the
    #: map states any (a URDF's servos): ``gait-tuner init`` sizes the legs' to the robot's weight
    preset_gains: tuple[str, ...] = ()
    #: the soles measure force (the map's ``foot_sensors``; a controller of a robot without gets none)
    foot_sensors: bool = True
    #: the boards on the robot's buses besides the servos (the map's ``bus:``; gaits.robot.robot_file): the
    #: IMU (``ImuBoard``; None: none on the bus) and the sole boards (left, right ``SoleBoard``)
    imu_board: Any = ImuBoard()
    sole_boards: Any = None
    sole_protocol: str = "bitfoot"

    def foot_size_of(self, side: int) -> tuple[float, float]:
        """The sole bounding box (length, width) [m] of foot ``side`` (0 left, 1 right)."""
        return tuple(self.foot_sizes[side]) if self.foot_sizes else tuple(self.foot_size)

    def joint_ranges(self, names) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) [rad] of the file's joints ``names``; +-inf where a joint is not limited."""
        model = self.model()
        lo, hi = [], []
        for n in names:
            j = model.joint(n).id
            limited = bool(model.jnt_limited[j])
            lo.append(float(model.jnt_range[j, 0]) if limited else -np.inf)
            hi.append(float(model.jnt_range[j, 1]) if limited else np.inf)
        return np.array(lo), np.array(hi)

    def touch_bodies(self, side: int) -> tuple[tuple[str, np.ndarray, np.ndarray], ...]:
        if self.sole_bodies:
            return self.sole_bodies[side]
        return ((self.feet[side], np.eye(3), np.zeros(3)),)

    def sole_points(self, side: int, points_sole: np.ndarray) -> np.ndarray:
        """Offsets from a sole centre given in sole-frame axes (K, 3) -> points in the foot frame
        (K, 3); side 0 left, 1 right."""
        R = np.asarray(self.sole_axes[side])
        return np.asarray(self.soles[side]) + np.asarray(points_sole, dtype=float) @ R

    def spec(self) -> mujoco.MjSpec:
        """A fresh, editable MjSpec of the robot as its file gives it."""
        try:
            if self.mjcf_path is not None:
                spec = mujoco.MjSpec.from_file(self.mjcf_path)
                if self.balance_inertia:
                    spec.compiler.balanceinertia = True
            else:
                spec = mujoco.MjSpec.from_string(self.xml)
        except Exception as exc:  # mujoco raises ValueError with the parser's message
            raise UserError(f"robot {self.name!r}: MJCF does not load: {str(exc).splitlines()[0]}") from None
        for a, b in self.exclude:
            ex = spec.add_exclude()
            ex.bodyname1, ex.bodyname2 = a, b
        return spec

    def model(self) -> mujoco.MjModel:
        """The robot alone, compiled as its file gives it (no scene, no servos of ours)."""
        if self.mjcf_path is not None and not self.balance_inertia and not self.exclude:
            return mujoco.MjModel.from_xml_path(self.mjcf_path)
        return self.spec().compile()

    def servo_of(self, ours: str) -> ServoLaw:
        """The servo of one of our (mapped) joint names."""
        return self.servos[self.joint_map[ours][0]]

    def robot_file(self) -> "RobotFile":
        """The robot side's robot file (``gaits.robot.robot_file.RobotFile``) of this robot: leg geometry,
        soles, mass, joint order, signs and ranges (an unbounded joint: +-pi), each servo's speed
        [rad/s] and torque [N m] (a joint without a servo: the MX-64's 6.5 and 6.0, ours), units and
        the joints held at ``pose``."""
        from gaits.robot.robot_file import JointSpec, RobotFile
        # the robot side drives the 20 roles; an extra joint is held at its pose there as an unmapped
        # one is (no controller of the robot side drives one)
        roles = {ours: v for ours, v in self.joint_map.items() if ours in JOINT_NAMES}
        names = [theirs for theirs, _ in roles.values()]
        lo, hi = self.joint_ranges(names)
        joints = {}
        for (ours, (theirs, sign)), low, high in zip(roles.items(), lo, hi):
            servo = self.servos.get(theirs)
            pieces = servo.pieces() if servo else None
            joints[ours] = JointSpec(theirs, int(sign), float(low) if np.isfinite(low) else -np.pi,
                                     float(high) if np.isfinite(high) else np.pi,
                                     float(servo.speed) if servo else 6.5, float(servo.torque) if servo else 6.0,
                                     self.servo_units.get(theirs),
                                     float(pieces.kp) if pieces else 0.0,
                                     float(pieces.kv + pieces.back_emf + pieces.damping) if pieces else 0.0)
        held = {j: float(v) for j, v in self.pose.items() if j not in names}
        return RobotFile(self.name, self.leg, tuple(float(v) for v in self.foot_size), joints,
                         self.sim.control_period, float(np.sum(self.model().body_mass)), held,
                         bool(self.foot_sensors), self.imu_board, self.sole_boards, self.sole_protocol)

    def require_robot_side_reads(self) -> None:
        """One :class:`UserError` where a walk made for this robot would read what its robot side
        cannot (:meth:`sensing_gap`): what ``init``, a study, ``robot export`` and ``bus serve`` ask."""
        gap = self.sensing_gap()
        if gap is not None:
            raise UserError(gap)

    def sensing_gap(self) -> str | None:
        """Why the robot side could not read what a walk of this robot is made with, or None: a
        robot wired for it (servo ids) whose soles sense force and whose map names no sole boards.
        A robot with no servo ids is not wired yet (its robot file would drive nothing)."""
        if not self.servo_units or not self.foot_sensors or self.sole_boards is not None:
            return None
        return f"{self.map_path or self.name}: {SENSING_GAP}"

    @property
    def extra_joints(self) -> tuple[str, ...]:
        """Our names of the joints the map names beyond the 20 roles (its ``extra_joints:``), in its
        order: the engines hold them at ``pose``, a policy may drive them."""
        return tuple(j for j in self.joint_map if j not in JOINT_NAMES)

    def with_extras(self, q: np.ndarray) -> np.ndarray:
        """Targets of our 20 roles (..., 20) -> (..., 20 + extras): the extra joints at their pose (0);
        targets that have them already (a controller that drives them), as they are."""
        q = np.asarray(q, dtype=float)
        n = len(self.extra_joints)
        if n and q.shape[-1] == len(JOINT_NAMES):
            q = np.concatenate([q, np.zeros(q.shape[:-1] + (n,))], axis=-1)
        return q

    @property
    def servo_joints(self) -> tuple[str, ...]:
        """Our names of every joint a controller drives: the mapped roles in ``JOINT_NAMES`` order,
        then the extra joints (a controller's targets are in this order, the extras last)."""
        return tuple(j for j in JOINT_NAMES if j in self.joint_map) + self.extra_joints

    @property
    def held_joints(self) -> tuple[str, ...]:
        """MJCF names of the actuated joints the map does not name (held at ``pose``)."""
        mapped = {theirs for theirs, _ in self.joint_map.values()}
        return tuple(j for j in self.servos if j not in mapped)
