"""Robots the simulator can walk: the built-in kid-size humanoid, or your own MJCF plus a joint map.

Built-in robot (``kidsize``): 20 DoF laid out as the EROS robot (Pristovani et
al., Table 1: 2 head, 3 per arm, 6 per leg), 52 cm tall like EROS. Where each
number comes from:

* masses: the TKU-X mass distribution (Wong et al. 2020, Table 1): head 0.36 kg,
  trunk 1.85 kg, arms 0.84 kg (0.42 each), thigh 0.2 kg, calf 0.5 kg, sole
  0.25 kg per leg; 4.95 kg in all. Per leg, 0.05 kg of the thigh budget sits
  in the hip-yaw/roll servo bodies.
* height: 52 cm (EROS): sole to hip 25.5 cm (ankle 3.5 + shank 11 + thigh 11),
  trunk 17 cm, neck and head 8.5 cm (head top at 0.52 m).
* feet: 10 cm x 6 cm soles, a typical kid-size foot (RoboCup kid-size rules
  cap the foot area by the robot's height).
* servos: Dynamixel MX-64-class in the legs (stall torque ~6 N m, no-load speed
  ~6.6 rad/s), MX-28-class in arms and head (2.5 N m, 5.8 rad/s); proportional
  gain 40 N m/rad with 0.5 N m s/rad damping; reflected rotor inertia
  (armature) 0.008 kg m^2; gearbox friction 0.03 N m.
* joint limits: typical kid-size ranges (knee 0..150 deg, hip pitch -110..60 deg).

Bring your own robot: ``load_robot(path)`` reads a YAML map (see
:class:`RobotMap`) naming the MJCF file, the torso body, the foot bodies and
which joint is each leg's hip yaw/roll/pitch, knee, ankle pitch/roll. The leg
dimensions the IK needs are derived from the model at its zero pose unless the
map gives them. Every mistake is a :class:`tuner.errors.UserError` naming what
is wrong.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import mujoco
import numpy as np
import yaml

from gaits import JOINT_NAMES, LegGeometry
from gaits.leg_kinematics import LEG_JOINTS

from ..errors import UserError

__all__ = ["ServoSpec", "RobotSpec", "RobotModel", "kidsize_spec", "kidsize_xml", "load_robot",
           "BUILTIN_ROBOTS", "LEG_AXES", "leg_geometry_report"]

#: Expected joint axis of each leg joint in the torso frame at the zero pose.
LEG_AXES = {"hip_yaw": (0, 0, 1), "hip_roll": (1, 0, 0), "hip_pitch": (0, 1, 0),
            "knee": (0, 1, 0), "ankle_pitch": (0, 1, 0), "ankle_roll": (1, 0, 0)}


@dataclass(frozen=True)
class ServoSpec:
    """A position-controlled hobby servo."""

    kp: float = 40.0            # [N m/rad] proportional gain
    kv: float = 0.5             # [N m s/rad] velocity feedback
    torque: float = 6.0         # [N m] torque limit (stall)
    speed: float = 6.5          # [rad/s] speed limit of the commanded target
    armature: float = 0.008     # [kg m^2] reflected rotor inertia
    damping: float = 0.2        # [N m s/rad] gearbox viscous friction
    frictionloss: float = 0.03  # [N m] gearbox dry friction


LEG_SERVO = ServoSpec()
ARM_SERVO = ServoSpec(kp=15.0, kv=0.2, torque=2.5, speed=5.8, armature=0.004)


@dataclass(frozen=True)
class RobotSpec:
    """Typed description of the built-in humanoid (SI units); see the module docstring for sources."""

    name: str = "kidsize"
    leg: LegGeometry = LegGeometry()
    foot_length: float = 0.10        # [m]
    foot_width: float = 0.06         # [m]
    sole_thickness: float = 0.01     # [m]
    trunk_size: tuple[float, float, float] = (0.09, 0.13, 0.17)   # [m] box x, y, z
    trunk_mass: float = 1.85         # [kg]
    head_mass: float = 0.36          # [kg]
    head_size: float = 0.065         # [m] cube edge
    neck_length: float = 0.02        # [m] trunk top to head-pitch axis
    arm_mass: float = 0.42           # [kg] each arm
    upper_arm: float = 0.08          # [m]
    forearm: float = 0.10            # [m]
    shoulder_y: float = 0.08         # [m] shoulder lateral offset
    hip_servo_mass: float = 0.05     # [kg] per leg, hip yaw + roll bodies
    thigh_mass: float = 0.15         # [kg] (0.2 kg thigh budget less the hip servos)
    calf_mass: float = 0.50          # [kg]
    foot_mass: float = 0.25          # [kg]
    leg_servo: ServoSpec = LEG_SERVO
    arm_servo: ServoSpec = ARM_SERVO
    limits: Mapping[str, tuple[float, float]] = field(default_factory=lambda: {
        "hip_yaw": (-0.8, 0.8), "hip_roll": (-0.6, 0.6), "hip_pitch": (-1.9, 1.0),
        "knee": (0.0, 2.6), "ankle_pitch": (-1.3, 1.3), "ankle_roll": (-0.6, 0.6),
        "head_yaw": (-1.6, 1.6), "head_pitch": (-0.8, 0.8), "shoulder_pitch": (-3.0, 3.0),
        "shoulder_roll": (-0.2, 3.0), "elbow": (-2.5, 0.2)})

    @property
    def total_mass(self) -> float:
        legs = 2 * (self.hip_servo_mass + self.thigh_mass + self.calf_mass + self.foot_mass)
        return self.trunk_mass + self.head_mass + 2 * self.arm_mass + legs

    @property
    def height(self) -> float:
        return (self.leg.max_hip_height + self.leg.hip_offset_z + self.trunk_size[2] + 0.01
                + self.neck_length + self.head_size)


def kidsize_spec() -> RobotSpec:
    return RobotSpec()


def _box_inertia(m: float, sx: float, sy: float, sz: float) -> str:
    return (f'mass="{m:.6g}" diaginertia="{m * (sy * sy + sz * sz) / 12:.6g} '
            f'{m * (sx * sx + sz * sz) / 12:.6g} {m * (sx * sx + sy * sy) / 12:.6g}"')


def kidsize_xml(spec: RobotSpec = RobotSpec()) -> str:
    """MJCF of the built-in robot (robot only: no floor, actuators or sensors; see RobotModel)."""
    L = spec.leg
    lim = spec.limits
    tx, ty, tz = spec.trunk_size

    def rng(name: str) -> str:
        lo, hi = lim[name]
        return f'range="{lo:.6g} {hi:.6g}"'

    def leg(prefix: str, side: int) -> str:
        y = side * L.hip_offset_y
        fl, fw, st = spec.foot_length, spec.foot_width, spec.sole_thickness
        hs = spec.hip_servo_mass / 2
        return f"""
      <body name="{prefix}hip_yaw_link" pos="0 {y:.6g} {-L.hip_offset_z:.6g}">
        <joint name="{prefix}hip_yaw" axis="0 0 1" {rng('hip_yaw')}/>
        <inertial pos="0 0 0" {_box_inertia(hs, 0.03, 0.03, 0.03)}/>
        <body name="{prefix}hip_roll_link">
          <joint name="{prefix}hip_roll" axis="1 0 0" {rng('hip_roll')}/>
          <inertial pos="0 0 0" {_box_inertia(hs, 0.03, 0.03, 0.03)}/>
          <body name="{prefix}thigh">
            <joint name="{prefix}hip_pitch" axis="0 1 0" {rng('hip_pitch')}/>
            <inertial pos="0 0 {-L.thigh / 2:.6g}" {_box_inertia(spec.thigh_mass, 0.04, 0.05, L.thigh)}/>
            <geom type="capsule" fromto="0 0 -0.015 0 0 {-L.thigh + 0.015:.6g}" size="0.018"/>
            <body name="{prefix}shank" pos="0 0 {-L.thigh:.6g}">
              <joint name="{prefix}knee" axis="0 1 0" {rng('knee')}/>
              <inertial pos="0 0 {-L.shank / 2:.6g}" {_box_inertia(spec.calf_mass, 0.04, 0.05, L.shank)}/>
              <geom type="capsule" fromto="0 0 -0.015 0 0 {-L.shank + 0.015:.6g}" size="0.018"/>
              <body name="{prefix}ankle" pos="0 0 {-L.shank:.6g}">
                <joint name="{prefix}ankle_pitch" axis="0 1 0" {rng('ankle_pitch')}/>
                <inertial pos="0 0 0" mass="0.01" diaginertia="1e-6 1e-6 1e-6"/>
                <body name="{prefix}foot">
                  <joint name="{prefix}ankle_roll" axis="1 0 0" {rng('ankle_roll')}/>
                  <inertial pos="0 0 {-L.ankle_height + st:.6g}" {_box_inertia(spec.foot_mass - 0.01, fl, fw, 2 * st)}/>
                  <geom name="{prefix}sole" type="box" pos="0 0 {-L.ankle_height + st / 2:.6g}"
                        size="{fl / 2:.6g} {fw / 2:.6g} {st / 2:.6g}"/>
                </body>
              </body>
            </body>
          </body>
        </body>
      </body>"""

    def arm(prefix: str, side: int) -> str:
        m_up = spec.arm_mass * 0.45
        m_fo = spec.arm_mass - m_up
        return f"""
      <body name="{prefix}shoulder" pos="0 {side * spec.shoulder_y:.6g} {tz - 0.02:.6g}">
        <joint name="{prefix}shoulder_pitch" axis="0 1 0" {rng('shoulder_pitch')}/>
        <inertial pos="0 0 0" mass="0.01" diaginertia="1e-6 1e-6 1e-6"/>
        <body name="{prefix}upper_arm">
          <joint name="{prefix}shoulder_roll" axis="{side} 0 0" {rng('shoulder_roll')}/>
          <inertial pos="0 0 {-spec.upper_arm / 2:.6g}" {_box_inertia(m_up - 0.01, 0.03, 0.03, spec.upper_arm)}/>
          <geom type="capsule" fromto="0 0 -0.01 0 0 {-spec.upper_arm:.6g}" size="0.015"/>
          <body name="{prefix}forearm" pos="0 0 {-spec.upper_arm:.6g}">
            <joint name="{prefix}elbow" axis="0 1 0" {rng('elbow')}/>
            <inertial pos="0 0 {-spec.forearm / 2:.6g}" {_box_inertia(m_fo, 0.03, 0.03, spec.forearm)}/>
            <geom type="capsule" fromto="0 0 -0.01 0 0 {-spec.forearm:.6g}" size="0.014"/>
          </body>
        </body>
      </body>"""

    z0 = L.max_hip_height + L.hip_offset_z + 0.01
    return f"""<mujoco model="{spec.name}">
  <compiler angle="radian"/>
  <default>
    <geom contype="1" conaffinity="0" rgba="0.75 0.75 0.8 1"/>
  </default>
  <worldbody>
    <body name="torso" pos="0 0 {z0:.6g}">
      <freejoint name="root"/>
      <inertial pos="0 0 {tz / 2 + 0.01:.6g}" {_box_inertia(spec.trunk_mass, tx, ty, tz)}/>
      <geom name="trunk" type="box" pos="0 0 {tz / 2 + 0.01:.6g}" size="{tx / 2:.6g} {ty / 2:.6g} {tz / 2:.6g}"/>
      <body name="neck" pos="0 0 {tz + 0.01:.6g}">
        <joint name="head_yaw" axis="0 0 1" {rng('head_yaw')}/>
        <inertial pos="0 0 0" mass="0.01" diaginertia="1e-6 1e-6 1e-6"/>
        <body name="head" pos="0 0 {spec.neck_length:.6g}">
          <joint name="head_pitch" axis="0 1 0" {rng('head_pitch')}/>
          <inertial pos="0 0 {spec.head_size / 2:.6g}" {_box_inertia(spec.head_mass - 0.01, spec.head_size, spec.head_size, spec.head_size)}/>
          <geom type="box" pos="0 0 {spec.head_size / 2:.6g}" size="{spec.head_size / 2:.6g} {spec.head_size / 2:.6g} {spec.head_size / 2:.6g}"/>
        </body>
      </body>{arm('l_', 1)}{arm('r_', -1)}{leg('l_', 1)}{leg('r_', -1)}
    </body>
  </worldbody>
</mujoco>
"""


@dataclass(frozen=True)
class RobotModel:
    """A robot ready for the simulator: MJCF, joint map, key bodies, leg geometry and servos.

    ``joint_map`` maps every name of :data:`gaits.JOINT_NAMES` that the robot has
    to (MJCF joint name, sign); legs are required, head and arm joints optional
    (held at zero). ``feet`` names the left and right foot bodies and ``soles``
    their sole centres in the foot body frame.
    """

    name: str
    xml: str
    joint_map: Mapping[str, tuple[str, int]]
    torso: str
    feet: tuple[str, str]
    soles: tuple[tuple[float, float, float], tuple[float, float, float]]
    foot_size: tuple[float, float]               # [m] length, width of the sole
    leg: LegGeometry
    leg_servo: ServoSpec = LEG_SERVO
    arm_servo: ServoSpec = ARM_SERVO
    mjcf_path: str | None = None                  # set for user robots: meshes resolve beside it

    def spec(self) -> mujoco.MjSpec:
        """A fresh, editable MjSpec of the robot."""
        try:
            if self.mjcf_path is not None:
                return mujoco.MjSpec.from_file(self.mjcf_path)
            return mujoco.MjSpec.from_string(self.xml)
        except Exception as exc:  # mujoco raises ValueError with the parser's message
            raise UserError(f"robot {self.name!r}: MJCF does not load: {str(exc).splitlines()[0]}") from None


def _kidsize_model(spec: RobotSpec = RobotSpec()) -> RobotModel:
    L = spec.leg
    jmap = {name: (name, 1) for name in JOINT_NAMES}
    sole = (0.0, 0.0, -L.ankle_height)
    com = _com_above_pelvis(mujoco.MjModel.from_xml_string(kidsize_xml(spec)), "torso", L, jmap)
    leg = dataclasses.replace(L, com_above_pelvis=com)
    return RobotModel(spec.name, kidsize_xml(spec), jmap, "torso", ("l_foot", "r_foot"),
                      (sole, sole), (spec.foot_length, spec.foot_width), leg,
                      spec.leg_servo, spec.arm_servo)


def _com_above_pelvis(model: mujoco.MjModel, torso: str, leg: LegGeometry,
                      joint_map: Mapping[str, tuple[str, int]], crouch: float = 0.85) -> float:
    """Whole-body CoM height above the torso frame [m], legs bent by the IK to ``crouch`` x the
    straight hip height (a typical walking posture; the legs' CoM rises as the knees bend).
    One definition for the built-in robot and for user robots (through their joint map)."""
    from gaits import leg_ik
    d = mujoco.MjData(model)
    for side, prefix in ((1, "l_"), (-1, "r_")):
        target = leg.hip_in_pelvis(side) + np.array([0.0, 0.0, -crouch * leg.max_hip_height])
        q = leg_ik(target, 0.0, leg, side)
        for name, value in zip(LEG_JOINTS, q):
            theirs, sign = joint_map[prefix + name]
            d.qpos[model.jnt_qposadr[model.joint(theirs).id]] = sign * value
    mujoco.mj_kinematics(model, d)
    mujoco.mj_comPos(model, d)
    b = model.body(torso).id
    return float(d.subtree_com[b][2] - d.xpos[b][2])


BUILTIN_ROBOTS = {"kidsize": _kidsize_model}


# --- bring your own robot ------------------------------------------------------------

_MAP_KEYS = ("mjcf", "torso", "feet", "joints", "leg", "servo")


def _require(cond: bool, source: str, msg: str) -> None:
    if not cond:
        raise UserError(f"{source}: {msg}")


def load_robot(name_or_path: str) -> RobotModel:
    """The built-in robot by name (``kidsize``) or a robot map YAML (see :func:`_load_map`)."""
    if name_or_path in BUILTIN_ROBOTS:
        return BUILTIN_ROBOTS[name_or_path]()
    path = Path(name_or_path)
    if not path.exists():
        raise UserError(f"--robot {name_or_path!r}: not a built-in robot "
                        f"({', '.join(BUILTIN_ROBOTS)}) and no such file")
    return _load_map(path)


def _load_map(path: Path) -> RobotModel:
    """Read a robot map YAML.

    Format::

        mjcf: my_robot.xml            # relative to this file
        torso: base_link              # the floating body; its frame is the IK's pelvis frame
        feet: {left: l_foot, right: r_foot}
        joints:                       # our name: MJCF joint name, or {name: ..., sign: -1}
          l_hip_yaw: LHipYaw
          l_knee: {name: LKnee, sign: -1}
          ...                         # all 12 leg joints; head/arm joints optional
        leg: {thigh: 0.11, ...}       # optional: LegGeometry fields; derived from the model otherwise
        servo: {kp: 40, torque: 6}    # optional: ServoSpec fields for the legs
    """
    source = str(path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError:
        raise UserError(f"{source}: not valid YAML") from None
    _require(isinstance(doc, Mapping), source, f"expected a mapping with keys {', '.join(_MAP_KEYS)}")
    for key in doc:
        _require(key in _MAP_KEYS, source, f"unknown key {key!r} (allowed: {', '.join(_MAP_KEYS)})")
    for key in ("mjcf", "torso", "feet", "joints"):
        _require(key in doc, source, f"missing {key!r}")
    mjcf = (path.parent / str(doc["mjcf"])).resolve()
    _require(mjcf.is_file(), source, f"mjcf file {str(mjcf)!r} not found")
    xml = mjcf.read_text(encoding="utf-8")
    try:
        model = mujoco.MjModel.from_xml_path(str(mjcf))
    except Exception as exc:
        raise UserError(f"{source}: {mjcf.name} does not load in MuJoCo: "
                        f"{str(exc).splitlines()[0]}") from None
    torso = doc["torso"]
    _require(isinstance(torso, str) and _has(model, mujoco.mjtObj.mjOBJ_BODY, torso), source,
             f"torso body {torso!r} not in {mjcf.name}")
    tb = model.body(torso).id
    _require(model.body_jntnum[tb] >= 1 and model.jnt_type[model.body_jntadr[tb]] == mujoco.mjtJoint.mjJNT_FREE,
             source, f"torso body {torso!r} must carry the model's free joint")
    feet = doc["feet"]
    _require(isinstance(feet, Mapping) and set(feet) == {"left", "right"}, source,
             "feet must be {left: BODY, right: BODY}")
    for side in ("left", "right"):
        _require(_has(model, mujoco.mjtObj.mjOBJ_BODY, str(feet[side])), source,
                 f"{side} foot body {feet[side]!r} not in {mjcf.name}")
    joints = doc["joints"]
    _require(isinstance(joints, Mapping), source, "joints must be a mapping of our name: MJCF joint")
    jmap: dict[str, tuple[str, int | None]] = {}
    for ours, theirs in joints.items():
        _require(ours in JOINT_NAMES, source,
                 f"unknown joint {ours!r} (ours are: {', '.join(JOINT_NAMES)})")
        sign = None
        if isinstance(theirs, Mapping):
            _require(set(theirs) <= {"name", "sign"} and "name" in theirs, source,
                     f"joint {ours}: expected {{name: ..., sign: 1 or -1}}")
            sign = theirs.get("sign")
            _require(sign in (None, 1, -1), source, f"joint {ours}: sign must be 1 or -1, got {sign!r}")
            theirs = theirs["name"]
        _require(isinstance(theirs, str) and _has(model, mujoco.mjtObj.mjOBJ_JOINT, theirs), source,
                 f"joint {ours}: {theirs!r} is not a joint of {mjcf.name}")
        jmap[ours] = (theirs, sign)
    missing = [j for j in JOINT_NAMES if j[2:] in LEG_JOINTS and j not in jmap]
    _require(not missing, source, f"leg joints missing from the map: {', '.join(missing)}")
    used = [v[0] for v in jmap.values()]
    dup = sorted({u for u in used if used.count(u) > 1})
    _require(not dup, source, f"MJCF joint(s) mapped twice: {', '.join(dup)}")
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    R_torso = d.xmat[tb].reshape(3, 3)
    final: dict[str, tuple[str, int]] = {}
    for ours, (theirs, sign) in jmap.items():
        j = model.joint(theirs).id
        _require(model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE, source,
                 f"joint {ours}: {theirs!r} is not a hinge joint")
        kind = ours[2:] if ours[:2] in ("l_", "r_") else ours
        if kind in LEG_AXES:
            axis = R_torso.T @ d.xaxis[j]
            expected = np.array(LEG_AXES[kind], dtype=float)
            dot = float(axis @ expected)
            _require(abs(dot) > 0.95, source,
                     f"joint {ours}: {theirs!r} turns about {np.round(axis, 3).tolist()} in the torso "
                     f"frame; a {kind} joint must turn about +-{list(LEG_AXES[kind])}")
            natural = 1 if dot > 0 else -1
            _require(sign is None or sign == natural, source,
                     f"joint {ours}: sign {sign} contradicts the axis of {theirs!r} "
                     f"({np.round(axis, 3).tolist()}); use sign {natural} or leave it out")
            sign = natural
        final[ours] = (theirs, 1 if sign is None else int(sign))
    # leg geometry at the zero pose, from joint anchors and the foot geoms
    anchors = {ours: R_torso.T @ (d.xanchor[model.joint(n).id] - d.xpos[tb]) for ours, (n, _) in final.items()}
    soles = []
    for side in ("left", "right"):
        fb = model.body(str(feet[side])).id
        lowest = _lowest_geom_point(model, d, fb)
        _require(lowest is not None, source, f"{side} foot body {feet[side]!r} has no collision geom")
        soles.append(tuple(float(v) for v in (d.xmat[fb].reshape(3, 3).T @ (lowest - d.xpos[fb]))))
    derived = _derive_leg(anchors, model, d, tb, soles, feet, source)
    leg_over = doc.get("leg") or {}
    _require(isinstance(leg_over, Mapping), source, "leg must be a mapping of LegGeometry fields")
    try:
        leg = LegGeometry(**{**derived, **dict(leg_over)})
    except TypeError as exc:
        raise UserError(f"{source}: leg: {exc}") from None
    except ValueError as exc:
        raise UserError(f"{source}: {exc}") from None
    if "com_above_pelvis" not in leg_over:
        try:
            com = _com_above_pelvis(model, torso, leg, final)
        except ValueError as exc:          # the crouched pose is out of the derived legs' reach
            raise UserError(f"{source}: leg: {exc}") from None
        leg = dataclasses.replace(leg, com_above_pelvis=com)
    servo_over = doc.get("servo") or {}
    try:
        servo = ServoSpec(**dict(servo_over))
    except TypeError as exc:
        raise UserError(f"{source}: servo: {exc}") from None
    fsize = _foot_size(model, d, model.body(str(feet["left"])).id)
    return RobotModel(path.stem, xml, final, torso, (str(feet["left"]), str(feet["right"])),
                      (soles[0], soles[1]), fsize, leg, servo, ARM_SERVO, str(mjcf))


def _has(model: mujoco.MjModel, obj: Any, name: str) -> bool:
    return mujoco.mj_name2id(model, obj, name) >= 0


def _foot_geoms(model: mujoco.MjModel, body: int) -> list[int]:
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] == body
            and (model.geom_contype[g] or model.geom_conaffinity[g])]


def _lowest_geom_point(model: mujoco.MjModel, d: mujoco.MjData, body: int) -> np.ndarray | None:
    geoms = _foot_geoms(model, body)
    if not geoms:
        return None
    best = None
    for g in geoms:
        c = d.geom_xpos[g]
        R = d.geom_xmat[g].reshape(3, 3)
        half = model.geom_aabb[g][3:]
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
        pts = c + (corners + model.geom_aabb[g][:3]) @ R.T
        low = pts[np.argmin(pts[:, 2])]
        centre = np.array([c[0], c[1], low[2]])
        if best is None or centre[2] < best[2]:
            best = centre
    return best


def _foot_size(model: mujoco.MjModel, d: mujoco.MjData, body: int) -> tuple[float, float]:
    g = _foot_geoms(model, body)[0]
    half = model.geom_aabb[g][3:]
    return float(2 * half[0]), float(2 * half[1])


def _derive_leg(anchors: Mapping[str, np.ndarray], model: mujoco.MjModel, d: mujoco.MjData, tb: int,
                soles: list[tuple[float, ...]], feet: Mapping[str, str], source: str) -> dict[str, float]:
    hip = anchors["l_hip_pitch"]
    knee = anchors["l_knee"]
    ankle = anchors["l_ankle_pitch"]
    fb = model.body(str(feet["left"])).id
    R_t = d.xmat[tb].reshape(3, 3)
    sole_world = d.xpos[fb] + d.xmat[fb].reshape(3, 3) @ np.array(soles[0])
    sole = R_t.T @ (sole_world - d.xpos[tb])
    for a, b, what in ((anchors["l_hip_roll"], hip, "hip roll and hip pitch"),
                       (ankle, anchors["l_ankle_roll"], "ankle pitch and ankle roll")):
        _require(np.linalg.norm(a - b) < 0.005, source,
                 f"the {what} axes must intersect (they are {np.linalg.norm(a - b) * 1000:.1f} mm apart); "
                 f"give the leg dimensions under 'leg:' if your IK convention differs")
    return {"hip_offset_y": float(abs(hip[1])), "hip_offset_z": float(-hip[2]),
            "thigh": float(np.linalg.norm(hip - knee)), "shank": float(np.linalg.norm(knee - ankle)),
            "ankle_height": float(ankle[2] - sole[2])}


def leg_geometry_report(robot: RobotModel) -> str:
    L = robot.leg
    return (f"{robot.name}: hip offset y {L.hip_offset_y * 1000:.1f} mm, thigh {L.thigh * 1000:.1f} mm, "
            f"shank {L.shank * 1000:.1f} mm, ankle height {L.ankle_height * 1000:.1f} mm, "
            f"CoM {L.com_above_pelvis * 1000:.1f} mm above the pelvis, "
            f"straight-leg hip height {L.max_hip_height * 1000:.1f} mm")

