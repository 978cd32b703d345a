"""One robot file for the robot side (ours): everything the loop on the robot needs, written once by
``gait-tuner robot export MAP --out robot.yaml`` from the robot's own model and map, read here with
numpy and PyYAML only (no MuJoCo, no built-in geometry on the robot side)::

    robot: kid3kg                  # its name
    control_period: 0.01           # [s]
    mass: 3.154                    # [kg] the whole robot
    foot_size: [0.127, 0.078]      # [m] the sole's bounding box (length, width)
    leg: {thigh: 0.11, shank: 0.11, ...}   # [m] gaits.LegGeometry's fields, derived from the joint axes
    leg_chains: {reason: ..., left: {axes, points, sole, sole_rotation}, right: ...}   # only for legs the
                                   # closed-form IK does not fit: the numerical IK's chains (gaits.leg_chain)
    joints:                        # our joint name (gaits.JOINT_NAMES) -> the robot's joint
      l_knee: {name: Knee_L, sign: 1, lower: -2.6, upper: 0.0, speed: 6.5, torque: 6.0,
               kp: 31.0, damping: 0.69,   # [N m/rad], [N m s/rad]: what the servo gives way by (optional)
               servo: {id: 14, units_per_rad: 651.9, centre: 2048, direction: -1, offset: 0.05}}
    held: {HeadPan_C: 0.0}         # joints of the robot not mapped, held at an angle [rad, its convention]
    foot_sensors: true             # the soles measure force: the loop reads the sole boards below
    bus:                           # the boards besides the servos (optional; these are the defaults)
      imu: {protocol: gait-tuner, id: 200, port: 0}     # or {protocol: bitbots, id: 241}; null: none
      soles: {protocol: bitfoot, left: {id: 102, zero: [0, 0, 0, 0], newtons_per_unit: [1, 1, 1, 1]},
              right: {id: 101}, port: 0}                # none by default: a robot whose soles sense
                                                        # force must name its boards

A robot on several buses (Bit-Bots' Wolfgang-OP runs four) gives the loop every port
(``--port A,B,...``): each device is looked for on each port and used where it answers, as
Bit-Bots' own driver does; a servo's or a board's ``port`` (0 first) places it on the simulated
bus (``gait-tuner bus serve --link A,B,...``).

An angle goes from our convention (gaits' joint signs, what the engine returns) to the robot's by
its ``sign`` (q_robot = sign q_ours), then to the servo's units by ``servo``: ticks = centre +
direction (q_robot + offset) units_per_rad, rounded (the map's ``servos:`` section, the same formula
``--format servo`` tables use). Ranges [rad] are the robot's own (``lower``, ``upper``: the robot's
convention); a target outside is clipped before it is sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..files import MAX_BYTES, read_bytes_checked, write_text_atomic
from ..leg_chain import chains_from_mapping, chains_to_mapping
from ..leg_kinematics import LegGeometry
from ..params import ParamError
from ..trajectory import JOINT_NAMES

__all__ = ["ServoUnit", "JointSpec", "ImuBoard", "SoleBoard", "RobotFile", "load_robot_file", "save_robot_file",
           "to_units", "from_units", "IMU_PROTOCOLS", "SOLE_PROTOCOLS", "SENSING_GAP"]

#: IMU boards the loop reads (gaits.robot.dynamixel has each one's registers): ours, and Bit-Bots' IMU
#: board of their Wolfgang-OP (bitbots_main, bitbots_ros_control's IMU interface; its id there 241)
IMU_PROTOCOLS = {"gait-tuner": 200, "bitbots": 241}
#: sole boards: Bit-Bots' BitFoot (four load cells a foot; ids 101 right, 102 left on their robots)
SOLE_PROTOCOLS = {"bitfoot": (102, 101)}
#: the one line for a robot whose soles sense force and whose robot side reads none (the robot file,
#: and the map it is written from, say it so)
SENSING_GAP = ("the soles sense force (foot_sensors: true, the default), so the simulator's walks of this robot read "
               "them, but it names no sole boards (bus: soles:) and the loop on the robot could not: name them "
               "(bus: {soles: {protocol: bitfoot, left: ID, right: ID}}) or say foot_sensors: false")


@dataclass(frozen=True)
class ServoUnit:
    """How one joint's servo is addressed and what a unit of its position is."""

    id: int
    units_per_rad: float = 4096 / (2 * math.pi)   # [ticks/rad] (4096 ticks per turn, Dynamixel)
    centre: float = 2048.0                        # [ticks] the position sent for the servo's zero
    direction: int = 1                            # +1 or -1: the servo counts the file's way or against it
    offset: float = 0.0                           # [rad] added to the file's angle before conversion
    port: int = 0                                 # the bus it is on (0 first), for the simulated bus


def to_units(q: np.ndarray, u: ServoUnit) -> np.ndarray:
    """Angles [rad, the robot file's convention] -> the servo's integer positions."""
    return np.rint(u.centre + u.direction * (np.asarray(q, float) + u.offset) * u.units_per_rad).astype(np.int64)


def from_units(ticks: np.ndarray, u: ServoUnit) -> np.ndarray:
    """The servo's positions -> angles [rad, the robot's convention] (the inverse of :func:`to_units`
    up to its rounding: half a tick)."""
    return (np.asarray(ticks, float) - u.centre) / (u.direction * u.units_per_rad) - u.offset


@dataclass(frozen=True)
class JointSpec:
    """One of our joints on the robot: its name there, its sign, range, servo limits and servo."""

    name: str
    sign: int = 1
    lower: float = -math.pi           # [rad] the robot's convention
    upper: float = math.pi
    speed: float = 6.5                # [rad/s]
    torque: float = 6.0               # [N m]
    servo: ServoUnit | None = None
    kp: float = 0.0                   # [N m/rad] the servo's position gain as it holds a load (0: not stated)
    damping: float = 0.0              # [N m s/rad] its velocity terms: gain, back-EMF, viscous friction


@dataclass(frozen=True)
class ImuBoard:
    """The IMU on the bus: its protocol (:data:`IMU_PROTOCOLS`), id and port."""

    protocol: str = "gait-tuner"
    id: int = 200
    port: int = 0


@dataclass(frozen=True)
class SoleBoard:
    """One sole's force board: its id and port, and its four cells' calibration (front left, front
    right, back left, back right, as ``gaits.control.FOOT_FORCE_LABELS``): force [N] =
    (reading - zero) x newtons_per_unit."""

    id: int
    port: int = 0
    zero: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    newtons_per_unit: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)

    def newtons(self, raw: np.ndarray) -> np.ndarray:
        return (np.asarray(raw, float) - np.asarray(self.zero)) * np.asarray(self.newtons_per_unit)

    def raw(self, newtons: np.ndarray) -> np.ndarray:
        """What the board reads for forces [N] (the simulated bus serves this)."""
        return np.asarray(newtons, float) / np.asarray(self.newtons_per_unit) + np.asarray(self.zero)


@dataclass(frozen=True)
class RobotFile:
    """A robot as its loop sees it (the module docstring); it is a ``gaits.families.RobotGeometry``."""

    robot: str
    leg: LegGeometry
    foot_size: tuple[float, float]
    joints: Mapping[str, JointSpec]
    control_period: float = 0.01
    mass: float = 0.0
    held: Mapping[str, float] = field(default_factory=dict)
    foot_sensors: bool = True          # the soles measure force (eight readings); false: the engine walks without
    imu: ImuBoard | None = ImuBoard()  # None: no IMU on the bus
    soles: tuple[SoleBoard, SoleBoard] | None = None   # (left, right) boards; None: none on the bus
    sole_protocol: str = "bitfoot"

    def sensing_gap(self) -> str | None:
        """Why the loop could not read what this robot's walks were made with (soles said to sense
        force, no boards named), or None."""
        return SENSING_GAP if self.foot_sensors and self.soles is None else None

    def devices(self) -> dict[int, str]:
        """{id: what it is} of every device on the robot's buses (servos, the IMU, sole boards)."""
        out = {j.servo.id: ours for ours, j in self.joints.items() if j.servo is not None}
        if self.imu is not None:
            out[self.imu.id] = "the IMU"
        for side, b in zip(("left", "right"), self.soles or ()):
            out[b.id] = f"the {side} sole board"
        return out

    @property
    def ports(self) -> int:
        """How many buses the file places its devices on (the highest port + 1)."""
        ports = [j.servo.port for j in self.joints.values() if j.servo is not None]
        ports += [self.imu.port] if self.imu is not None else []
        ports += [b.port for b in self.soles or ()]
        return max(ports, default=0) + 1

    def to_robot(self, q_ours: np.ndarray) -> dict[str, float]:
        """Our 20 targets [rad] -> {the robot's joint name: angle [rad, its convention]}, clipped into
        each joint's range (joints the robot lacks are left out)."""
        q = np.asarray(q_ours, dtype=float)
        return {j.name: float(min(max(j.sign * q[JOINT_NAMES.index(ours)], j.lower), j.upper))
                for ours, j in self.joints.items()}

    def to_servos(self, q_ours: np.ndarray) -> dict[int, int]:
        """Our 20 targets [rad] -> {servo id: position} for the joints that have a servo."""
        angles = self.to_robot(q_ours)
        return {j.servo.id: int(to_units(angles[j.name], j.servo)) for j in self.joints.values()
                if j.servo is not None}

    def from_servos(self, ticks: Mapping[int, int]) -> np.ndarray:
        """{servo id: position} read from the bus -> our 20 angles [rad] (NaN for a joint not read)."""
        q = np.full(len(JOINT_NAMES), np.nan)
        for ours, j in self.joints.items():
            if j.servo is not None and j.servo.id in ticks:
                q[JOINT_NAMES.index(ours)] = j.sign * float(from_units(ticks[j.servo.id], j.servo))
        return q


def _num(v: Any, what: str, source: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
        raise ParamError(f"{source}: {what} = {v!r}: expected a finite number in [{lo:g}, {hi:g}]")
    return float(v)


def _mapping(v: Any, what: str, source: str) -> Mapping:
    if not isinstance(v, Mapping):
        raise ParamError(f"{source}: {what} must be a mapping")
    return v


def _known(doc: Mapping, allowed: tuple[str, ...], what: str, source: str) -> None:
    for k in doc:
        if k not in allowed:
            raise ParamError(f"{source}: {what}: unknown key {k!r} (allowed: {', '.join(allowed)})")


def load_robot_file(path: str | Path) -> RobotFile:
    """Read and check a robot file (one line naming the file, the field and the value for a mistake)."""
    import yaml
    path = Path(path)
    source = str(path)
    raw = read_bytes_checked(path, "robot", MAX_BYTES["yaml"], ParamError)
    try:
        doc = yaml.safe_load(raw.decode("utf-8"))
    except (UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ParamError(f"{source}: not a YAML robot file ({' '.join(str(exc).split())[:200]})") from None
    doc = _mapping(doc, "the file", source)
    _known(doc, ("robot", "control_period", "mass", "foot_size", "leg", "leg_chains", "joints", "held", "foot_sensors",
                 "bus"), "the file", source)
    foot_sensors = doc.get("foot_sensors", True)
    if not isinstance(foot_sensors, bool):
        raise ParamError(f"{source}: foot_sensors = {foot_sensors!r}: expected true or false")
    for k in ("robot", "leg", "foot_size", "joints"):
        if k not in doc:
            raise ParamError(f"{source}: missing {k!r} (write it with gait-tuner robot export MAP --out FILE)")
    leg_doc = _mapping(doc["leg"], "leg", source)
    leg_fields = tuple(f.name for f in fields(LegGeometry) if f.name != "chains")
    _known(leg_doc, leg_fields, "leg", source)
    chains = None if doc.get("leg_chains") is None else chains_from_mapping(doc["leg_chains"], source)
    try:
        leg = LegGeometry(**{k: _num(v, f"leg.{k}", source) for k, v in leg_doc.items()}, chains=chains)
    except (ValueError, TypeError) as exc:
        raise ParamError(f"{source}: {exc}") from None
    fs = doc["foot_size"]
    if not isinstance(fs, list) or len(fs) != 2:
        raise ParamError(f"{source}: foot_size = {fs!r}: expected [length, width] [m]")
    foot = (_num(fs[0], "foot_size[0]", source, 0.01, 1.0), _num(fs[1], "foot_size[1]", source, 0.01, 1.0))
    joints = {}
    ids = {}
    for ours, j in _mapping(doc["joints"], "joints", source).items():
        if ours not in JOINT_NAMES:
            raise ParamError(f"{source}: joints: {ours!r} is not one of our joints ({', '.join(JOINT_NAMES)})")
        j = _mapping(j, f"joints.{ours}", source)
        _known(j, ("name", "sign", "lower", "upper", "speed", "torque", "kp", "damping", "servo"), f"joints.{ours}",
               source)
        if not isinstance(j.get("name"), str) or not j["name"]:
            raise ParamError(f"{source}: joints.{ours}.name: the robot's joint name is missing")
        sign = j.get("sign", 1)
        if sign not in (1, -1) or isinstance(sign, bool):
            raise ParamError(f"{source}: joints.{ours}.sign = {sign!r}: must be 1 or -1")
        lower = _num(j.get("lower", -math.pi), f"joints.{ours}.lower", source)
        upper = _num(j.get("upper", math.pi), f"joints.{ours}.upper", source)
        if lower > upper:
            raise ParamError(f"{source}: joints.{ours}: lower = {lower:g} is above upper = {upper:g} rad")
        servo = None
        if j.get("servo") is not None:
            s = _mapping(j["servo"], f"joints.{ours}.servo", source)
            _known(s, ("id", "units_per_rad", "centre", "direction", "offset", "port"), f"joints.{ours}.servo", source)
            sid = s.get("id")
            if not isinstance(sid, int) or isinstance(sid, bool) or not 0 <= sid <= 253:
                raise ParamError(f"{source}: joints.{ours}.servo.id = {sid!r}: expected an integer in [0, 253]")
            if sid in ids:
                raise ParamError(f"{source}: servo id {sid} given to {ids[sid]} and {ours}")
            ids[sid] = ours
            direction = s.get("direction", 1)
            if direction not in (1, -1) or isinstance(direction, bool):
                raise ParamError(f"{source}: joints.{ours}.servo.direction = {direction!r}: must be 1 or -1")
            servo = ServoUnit(sid, _num(s.get("units_per_rad", 4096 / (2 * math.pi)), f"joints.{ours}.servo.units_per_rad",
                                        source, 1e-3, 1e7),
                              _num(s.get("centre", 2048.0), f"joints.{ours}.servo.centre", source),
                              int(direction), _num(s.get("offset", 0.0), f"joints.{ours}.servo.offset", source,
                                                   -math.pi, math.pi),
                              _port(s.get("port", 0), f"joints.{ours}.servo.port", source))
        joints[ours] = JointSpec(j["name"], int(sign), lower, upper,
                                 _num(j.get("speed", 6.5), f"joints.{ours}.speed", source, 0.01, 100.0),
                                 _num(j.get("torque", 6.0), f"joints.{ours}.torque", source, 0.01, 1000.0), servo,
                                 _num(j.get("kp", 0.0), f"joints.{ours}.kp", source, 0.0, 1e5),
                                 _num(j.get("damping", 0.0), f"joints.{ours}.damping", source, 0.0, 1e4))
    missing = [n for n in JOINT_NAMES if n[2:] in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch",
                                                   "ankle_roll") and n not in joints]
    if missing:
        raise ParamError(f"{source}: joints: the leg joints {', '.join(missing)} are missing")
    held = {str(k): _num(v, f"held.{k}", source) for k, v in _mapping(doc.get("held") or {}, "held", source).items()}
    name = doc["robot"]
    if not isinstance(name, str) or not name:
        raise ParamError(f"{source}: robot = {name!r}: expected the robot's name")
    imu, soles, sole_protocol = read_bus(doc.get("bus"), source, ids)
    return RobotFile(name, leg, foot, joints, _num(doc.get("control_period", 0.01), "control_period", source,
                                                   1e-4, 1.0), _num(doc.get("mass", 0.0), "mass", source, 0.0, 1000.0),
                     held, foot_sensors, imu, soles, sole_protocol)


#: how many buses a robot may have (ours: Bit-Bots' Wolfgang-OP runs four)
MAX_PORTS = 8


def _port(v: Any, what: str, source: str) -> int:
    if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v < MAX_PORTS:
        raise ParamError(f"{source}: {what} = {v!r}: expected a bus number in [0, {MAX_PORTS - 1}] (0 the first)")
    return v


def _device_id(v: Any, what: str, source: str, taken: dict[int, str], name: str) -> int:
    if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= 253:
        raise ParamError(f"{source}: {what} = {v!r}: expected an integer in [0, 253]")
    if v in taken:
        raise ParamError(f"{source}: {what} = {v}: id {v} is already {taken[v]}'s")
    taken[v] = name
    return v


def _four(v: Any, what: str, source: str, default: float, lo: float) -> tuple[float, float, float, float]:
    if v is None:
        return (default,) * 4
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        v = [v] * 4
    if not isinstance(v, list) or len(v) != 4:
        raise ParamError(f"{source}: {what} = {v!r}: expected a number or four (front left, front right, back left, "
                         f"back right)")
    return tuple(_num(x, f"{what}[{k}]", source, lo, 1e9) for k, x in enumerate(v))


def read_bus(doc: Any, source: str, taken: dict[int, str]) -> tuple[ImuBoard | None, tuple[SoleBoard, SoleBoard] | None,
                                                                     str]:
    """A robot file's (or map's) ``bus:`` section -> (the IMU, the two sole boards, their protocol);
    ``taken``: the servos' ids (a board's id may be no servo's)."""
    if doc is None:
        doc = {}
    doc = _mapping(doc, "bus", source)
    _known(doc, ("imu", "soles"), "bus", source)
    taken = dict(taken)
    imu: ImuBoard | None = ImuBoard()
    if "imu" in doc and doc["imu"] is None:
        imu = None
    elif "imu" in doc:
        i = _mapping(doc["imu"], "bus.imu", source)
        _known(i, ("protocol", "id", "port"), "bus.imu", source)
        protocol = i.get("protocol", "gait-tuner")
        if protocol not in IMU_PROTOCOLS:
            raise ParamError(f"{source}: bus.imu.protocol = {protocol!r}: expected one of {', '.join(IMU_PROTOCOLS)}")
        imu = ImuBoard(protocol, _device_id(i.get("id", IMU_PROTOCOLS[protocol]), "bus.imu.id", source, taken,
                                            "the IMU"), _port(i.get("port", 0), "bus.imu.port", source))
    elif IMU_PROTOCOLS["gait-tuner"] in taken:
        raise ParamError(f"{source}: servo id {IMU_PROTOCOLS['gait-tuner']} is the IMU's (ours, the default): give the "
                         f"IMU its own id (bus: {{imu: {{id: N}}}})")
    soles = None
    protocol = "bitfoot"
    if doc.get("soles") is not None:
        s = _mapping(doc["soles"], "bus.soles", source)
        _known(s, ("protocol", "left", "right", "port"), "bus.soles", source)
        protocol = s.get("protocol", "bitfoot")
        if protocol not in SOLE_PROTOCOLS:
            raise ParamError(f"{source}: bus.soles.protocol = {protocol!r}: expected one of {', '.join(SOLE_PROTOCOLS)}")
        port = _port(s.get("port", 0), "bus.soles.port", source)
        boards = []
        for side, default_id in zip(("left", "right"), SOLE_PROTOCOLS[protocol]):
            b = s.get(side, {})
            b = {"id": b} if isinstance(b, int) and not isinstance(b, bool) else _mapping(b, f"bus.soles.{side}", source)
            _known(b, ("id", "port", "zero", "newtons_per_unit"), f"bus.soles.{side}", source)
            boards.append(SoleBoard(_device_id(b.get("id", default_id), f"bus.soles.{side}.id", source, taken,
                                               f"the {side} sole board"),
                                    _port(b.get("port", port), f"bus.soles.{side}.port", source),
                                    _four(b.get("zero"), f"bus.soles.{side}.zero", source, 0.0, -1e9),
                                    _four(b.get("newtons_per_unit"), f"bus.soles.{side}.newtons_per_unit", source, 1.0,
                                          1e-9)))
        soles = (boards[0], boards[1])
    return imu, soles, protocol


def bus_mapping(robot: RobotFile) -> dict[str, Any]:
    """The ``bus:`` section that :func:`read_bus` reads back as ``robot``'s boards."""
    out: dict[str, Any] = {"imu": None if robot.imu is None else
                           {"protocol": robot.imu.protocol, "id": robot.imu.id, "port": robot.imu.port}}
    if robot.soles is not None:
        out["soles"] = {"protocol": robot.sole_protocol}
        for side, b in zip(("left", "right"), robot.soles):
            out["soles"][side] = {"id": b.id, "port": b.port, "zero": [float(v) for v in b.zero],
                                  "newtons_per_unit": [float(v) for v in b.newtons_per_unit]}
    return out


def save_robot_file(path: str | Path, robot: RobotFile, header: str = "") -> Path:
    """Write a robot file that :func:`load_robot_file` reads back equal."""
    import yaml

    def r(v: float) -> float:
        return float(v)
    doc = {"robot": robot.robot, "control_period": r(robot.control_period), "mass": r(robot.mass),
           "foot_size": [r(robot.foot_size[0]), r(robot.foot_size[1])],
           "leg": {f.name: r(getattr(robot.leg, f.name)) for f in fields(LegGeometry) if f.name != "chains"},
           "joints": {}, "held": {k: r(v) for k, v in robot.held.items()}, "foot_sensors": bool(robot.foot_sensors)}
    if robot.leg.chains is not None:                 # the numerical IK's legs (gaits.leg_chain)
        doc["leg_chains"] = chains_to_mapping(robot.leg.chains)
    for ours, j in robot.joints.items():
        entry = {"name": j.name, "sign": j.sign, "lower": r(j.lower), "upper": r(j.upper), "speed": r(j.speed),
                 "torque": r(j.torque)}
        if j.kp > 0:
            entry.update(kp=r(j.kp), damping=r(j.damping))
        if j.servo is not None:
            entry["servo"] = {"id": j.servo.id, "units_per_rad": r(j.servo.units_per_rad), "centre": r(j.servo.centre),
                              "direction": j.servo.direction, "offset": r(j.servo.offset)}
            if j.servo.port:
                entry["servo"]["port"] = j.servo.port
        doc["joints"][ours] = entry
    doc["bus"] = bus_mapping(robot)
    text = (f"# {header}\n" if header else "") + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
    return write_text_atomic(path, text)
