"""The built-in robot, ``kidsize``: a parametric kid-size humanoid generated as MJCF.

20 DoF laid out as the EROS robot (Pristovani et al., Table 1: 2 head, 3 per arm, 6 per
leg), 52 cm tall like EROS. Where each number comes from:

* masses: the TKU-X mass distribution (Wong et al. 2020, Table 1): head 0.36 kg,
  trunk 1.85 kg, arms 0.84 kg (0.42 each), thigh 0.2 kg, calf 0.5 kg, sole
  0.25 kg per leg; 4.95 kg in all. Per leg, 0.05 kg of the thigh budget sits
  in the hip-yaw/roll servo bodies.
* height: 52 cm (EROS): sole to hip 25.5 cm (ankle 3.5 + shank 11 + thigh 11),
  trunk 17 cm, neck and head 8.5 cm (head top at 0.52 m).
* feet: 10 cm x 6 cm soles, a typical kid-size foot (RoboCup kid-size rules
  cap the foot area by the robot's height).
* servos: MX-64 in the legs (BAM's identification, the dc-motor law, firmware P 32), MX-28 in
  arms and head (datasheet-derived), all at 15 V, a 4S LiPo's nominal (``tuner/servos/``); on a Dynamixel bus
  (``gait-tuner bus serve``, ``robot export``) ids 1 to 20 in ``gaits.JOINT_NAMES`` order, 4096
  ticks a turn centred on 2048, no offsets, our IMU board at id 200 and a BitFoot sole board a foot
  (Bit-Bots' ids: 102 left, 101 right; its cells read newtons) (ours: a robot built that way).
* joint limits: typical kid-size ranges (knee 0..150 deg, hip pitch -110..60 deg).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Mapping

import mujoco

from gaits import JOINT_NAMES, LegGeometry
from gaits.robot.robot_file import SOLE_PROTOCOLS, ServoUnit, SoleBoard

from .mjcf_geometry import CROUCH, com_offset, crouch_angles, sole_polygon
from .robot_model import RobotModel, joint_group
from ..servos import ServoLaw, preset

__all__ = ["RobotSpec", "kidsize_spec", "kidsize_xml", "kidsize_model", "LEG_SERVO", "ARM_SERVO", "BATTERY_VOLTAGE"]

BATTERY_VOLTAGE = 15.0     # [V] a 4S LiPo's nominal (ours; full 16.8, drained about 13.5)
LEG_SERVO = preset("MX-64").replace(voltage=BATTERY_VOLTAGE)
ARM_SERVO = preset("MX-28").replace(voltage=BATTERY_VOLTAGE)


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
    leg_servo: ServoLaw = LEG_SERVO
    arm_servo: ServoLaw = ARM_SERVO
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


def kidsize_model(spec: RobotSpec = RobotSpec()) -> RobotModel:
    """The built-in robot ready for the simulator (leg geometry from the spec, CoM from its model)."""
    jmap = {name: (name, 1) for name in JOINT_NAMES}
    xml = kidsize_xml(spec)
    model = mujoco.MjModel.from_xml_string(xml)
    com = com_offset(model, "torso", crouch_angles(spec.leg, jmap))
    # The horizontal CoM offset stays zero for the built-in robot: its gaits and the EROS
    # experiment's calibration (issue 3) were made with the pelvis over the planned CoM. Its
    # crouched CoM sits 8.1 mm ahead of the pelvis; planning with that offset moves the legs and
    # changes the calibrated figures (the toe-first landing on grass50: 5.9 -> 3.7 deg).
    # Robots from a map get the offset (robot_map.py): theirs can sit a centimetre behind the hips.
    leg = dataclasses.replace(spec.leg, com_above_pelvis=float(com[2]))
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    sole = sole_polygon(model, d, model.body("l_foot").id)
    servos = {name: (spec.leg_servo if joint_group(name) == "legs" else spec.arm_servo) for name in JOINT_NAMES}
    c = (0.0, 0.0, -spec.leg.ankle_height)
    return RobotModel(spec.name, xml, jmap, "torso", ("l_foot", "r_foot"), (c, c),
                      (spec.foot_length, spec.foot_width), leg, servos,
                      pose={n: 0.0 for n in JOINT_NAMES if joint_group(n) != "legs"},
                      servo_units={n: ServoUnit(id=i + 1) for i, n in enumerate(JOINT_NAMES)},
                      sole_boards=tuple(SoleBoard(i) for i in SOLE_PROTOCOLS["bitfoot"]),
                      sole_hulls=(sole.hull, sole.hull),
                      sources={"robot": "built-in (tuner/robots/kidsize.py)",
                               "leg": "RobotSpec.leg", "servos": "presets MX-64 (legs), MX-28 (arms, head)",
                               "com": f"the model's masses, legs at the walking crouch ({CROUCH:g} x straight hip height); "
                                      f"horizontal offset not planned (see kidsize_model)"})
