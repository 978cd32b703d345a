"""Bring your own robot: a YAML map that names the parts of an unedited MJCF.

Format (paths relative to the map file)::

    mjcf: my_robot.xml            # the robot file, unedited (or urdf: my_robot.urdf, see urdf.py;
                                  #   an mjcf: path ending in .urdf is read as a URDF)
    packages: {my_robot_description: ../src/my_robot_description}   # URDF only: package:// folders
    ranges: {HeadPan: [-2.5, 2.5]}  # URDF only: [rad] ranges of continuous joints (or over the file's)
    balance_inertia: false        # optional: let MuJoCo raise principal moments that break A + B >= C
                                  #   (else such a body is one line naming it; urdf.compile_checked)
    foot_sensors: false           # optional: the soles measure no force (default true): a controller
                                  #   gets no foot_force reading, in the simulator as on the robot
    bus: {imu: {protocol: bitbots, id: 241}, soles: {left: 102, right: 101}}
                                  # optional: the boards on the robot's buses besides its servos
                                  #   (gaits/robot/robot_file.py); a map with servo ids whose soles sense
                                  #   force names its sole boards, or the robot side could not read them
    extends: ../my_robot.yaml     # optional: another map this one builds on (its keys, these over them;
                                  #   servo: merged group by group): init's copy of a team's map
    name: my_robot                # optional; default: the map file's stem
    torso: base_link              # the body with the free joint; its frame is the IK's pelvis frame
    feet: {left: l_foot, right: r_foot}
    joints:                       # our name: MJCF joint name, or {name: ..., sign: -1}
      l_hip_yaw: LHipYaw
      l_knee: {name: LKnee, sign: -1}
      ...                         # all 12 leg joints; head and arm joints optional
    extra_joints:                 # optional: joints beyond our 20 roles, by a name of yours (a-z, 0-9, _)
      l_shoulder_yaw: LShoulderYaw  #   as in joints:; the engines hold them at pose, a policy drives
                                  #   them by that name; the robot side holds them (robot file held:)
    leg: {thigh: 0.11}            # optional: LegGeometry fields, derived from the model otherwise
    servos: {default: {ticks_per_turn: 4096, centre: 2048}, Knee_L: {id: 14, direction: -1}}
                                  # optional: servo IDs and units for --format servo (servo_table.py)
    servo:                        # optional: per group (legs, arms, head, other) a preset name or
      legs: {speed: 5.5}          #   fields over the file's own servo (or over {preset: MX-64, ...})
    pose: {LShoulderRoll: 1.3}    # optional: held angle [rad] of non-leg joints (default: the file's
                                  #   first keyframe, else zero)
    sim: {control_period: 0.01, timestep: 0.002, max_tilt_deg: 50, min_height_ratio: 0.6}

What is derived, and every check, is described in ``tuner/robots/mjcf_geometry.py`` and
below; every mistake is a :class:`tuner.errors.UserError` naming the field, the value and
what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import Any, Mapping

import mujoco
import numpy as np

from gaits import JOINT_NAMES, LegGeometry, ParamError, did_you_mean
from gaits.leg_chain import LegChain, LegChains
from gaits.robot.robot_file import read_bus
from gaits.leg_kinematics import LEG_JOINTS
from gaits.trajectory import JOINT_NAME_PATTERN
from gaits.files import MAX_BYTES, read_bytes_checked

from ..errors import UserError
from ..yaml_input import read_yaml_file
from .mjcf_geometry import (CROUCH, axis_line_distance, body_chain, com_offset, crouch_angles, foot_geoms,
                            self_overlaps, sole_polygon)
from .robot_model import FINE_GROUPS, GROUPS, RobotModel, SimOptions, fine_group, joint_group
from ..servos import SERVO_FIELDS, PDServo, preset, servo_from_file, servo_from_mapping
from .servo_table import read_servo_units
from .urdf import UrdfRobot, compile_checked, mujoco_message, urdf_to_mjcf

__all__ = ["load_map", "map_with_servo", "extending", "read_map_doc", "LEG_AXES", "MAP_KEYS", "AXIS_TOLERANCE"]

#: Expected joint axis of each leg joint in the torso frame at the zero pose.
LEG_AXES = {"hip_yaw": (0, 0, 1), "hip_roll": (1, 0, 0), "hip_pitch": (0, 1, 0),
            "knee": (0, 1, 0), "ankle_pitch": (0, 1, 0), "ankle_roll": (1, 0, 0)}
MAP_KEYS = ("mjcf", "urdf", "packages", "ranges", "balance_inertia", "foot_sensors", "bus", "name", "torso", "feet",
            "joints", "extra_joints", "leg", "servo", "servos", "pose", "sim")
#: How far apart two axis lines that must meet may be, and how far the straight leg's
#: centres may stray from a vertical line [m] (ours).
AXIS_TOLERANCE = 0.005
#: How far a leg joint's axis may turn from its ideal (LEG_AXES) for the closed-form IK [rad] (ours);
#: beyond it, or beyond AXIS_TOLERANCE above, the legs get the numerical IK (gaits.leg_chain).
AXIS_ANGLE_TOLERANCE = math.radians(0.5)
#: How far a leg joint's axis may turn from its ideal and still be that joint (ours): 50 deg takes a
#: hip whose roll and yaw axes both lie 45 deg from the vertical (Berkeley Humanoid Lite's), and
#: still tells a pitch joint from a roll one; its sign is the one nearer the ideal.
AXIS_FIT = math.cos(math.radians(50.0))
#: the servo a group gets when neither its file nor the map states one: these presets (the dc-motor
#: law) at the built-in robot's battery voltage (kidsize.BATTERY_VOLTAGE)
_DEFAULT_PRESET = {"legs": "MX-64", "arms": "MX-28", "head": "MX-28", "other": "MX-28"}
DEFAULT_VOLTAGE = 15.0    # [V] a 4S LiPo's nominal (ours): what a map's default servos run at


def default_servo(group: str):
    """The servo of a group whose file and map state none (see ``_DEFAULT_PRESET``)."""
    return preset(_DEFAULT_PRESET[group]).replace(voltage=DEFAULT_VOLTAGE)


def _file_speed(group: str) -> float:
    """[rad/s] the target speed cap a file's own position actuator gets (a file states none): the
    round-one pd preset's of the group, as before the motor law."""
    return preset(f"{_DEFAULT_PRESET[group]}-pd").speed
_SIDES = (("left", "l_", 1), ("right", "r_", -1))


def map_with_servo(robot_map: Path, out_dir: Path, overlay: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """The map ``robot_map`` as a document to write into ``out_dir``: what it extends merged in, its
    paths (``mjcf``, ``urdf``, ``packages``) made relative to ``out_dir``, its ``name`` kept (the
    file's stem when unnamed), and ``overlay`` (servo group or joint -> fields) merged over its
    ``servo:`` entries."""
    doc = read_map_doc(robot_map)
    if not isinstance(doc, Mapping):
        raise UserError(f"{robot_map}: not a robot map (expected a mapping of {', '.join(MAP_KEYS)})")
    doc = _paths_from(doc, robot_map.resolve().parent, out_dir.resolve())
    servo = _servo_groups(doc.get("servo"))
    for k, v in overlay.items():
        entry = servo.get(k)
        merged = {"preset": entry} if isinstance(entry, str) else dict(entry or {})
        merged.update(v)
        servo[k] = merged
    doc["servo"] = servo
    doc.setdefault("name", robot_map.stem)
    return doc


def extending(robot_map: Path, out_dir: Path, overlay: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """A map to write into ``out_dir`` that extends ``robot_map`` (so an edit to it reaches this
    one) with ``overlay`` (servo group -> fields) over its ``servo:``."""
    import os
    doc: dict[str, Any] = {"extends": os.path.relpath(robot_map.resolve(), out_dir.resolve())}
    if overlay:
        doc["servo"] = {k: dict(v) for k, v in overlay.items()}
    return doc


def _require(cond: bool, source: str, msg: str) -> None:
    if not cond:
        raise UserError(f"{source}: {msg}")


def _has(model: mujoco.MjModel, obj: Any, name: Any) -> bool:
    return isinstance(name, str) and mujoco.mj_name2id(model, obj, name) >= 0


def _mm(x: float) -> str:
    return f"{x * 1000:.1f} mm"


#: how many maps deep ``extends:`` may go (ours: init's copy extends a team's map, which may extend one)
EXTENDS_DEPTH = 8


def _paths_from(doc: Mapping[str, Any], here: Path, there: Path) -> dict[str, Any]:
    """A map's document with its paths (``mjcf``, ``urdf``, ``packages``, ``extends``), written
    relative to ``here``, made relative to ``there``."""
    import os
    doc = dict(doc)
    for key in ("mjcf", "urdf", "extends"):
        if isinstance(doc.get(key), str):
            doc[key] = os.path.relpath(here / doc[key], there)
    if isinstance(doc.get("packages"), Mapping):
        doc["packages"] = {k: os.path.relpath(here / v, there) if isinstance(v, str) else v
                           for k, v in doc["packages"].items()}
    return doc


def _servo_groups(servo: Any) -> dict[str, Any]:
    servo = dict(servo or {}) if isinstance(servo, Mapping) else servo
    if isinstance(servo, dict) and servo and set(servo) <= set(SERVO_FIELDS) | {"preset"}:
        servo = {"legs": servo}            # the first map format: flat fields meant the legs
    return servo


def read_map_doc(path: Path, depth: int = 0) -> Any:
    """A robot map's document, with what it ``extends:`` (another map, its path relative to this
    one) under it: the other map's keys, this one's over them; ``servo:`` merged group by group,
    field by field (a map that extends a team's map changes a group's gains and keeps the rest, and
    an edit to the team's map reaches it)."""
    source = str(path)
    doc = read_yaml_file(path, "robot map")
    if not isinstance(doc, Mapping) or "extends" not in doc:
        return doc
    base = doc["extends"]
    _require(isinstance(base, str) and base != "", source, f"extends = {base!r}: expected the path of the map it "
                                                          f"builds on")
    _require(depth < EXTENDS_DEPTH, source, f"extends: more than {EXTENDS_DEPTH} maps deep (does a map extend "
                                            f"itself?)")
    base_path = path.parent / base
    _require(base_path.is_file(), source, f"extends: {base_path} is not a file")
    try:
        parent = read_map_doc(base_path, depth + 1)
    except UserError as exc:
        raise UserError(f"{source}: extends: {exc}") from None
    _require(isinstance(parent, Mapping), source, f"extends: {base_path} is not a robot map")
    out = _paths_from({k: v for k, v in parent.items() if k != "extends"}, base_path.parent, path.parent)
    for k, v in doc.items():
        if k == "extends":
            continue
        if k == "servo" and isinstance(out.get("servo"), Mapping) and isinstance(v, Mapping):
            merged = _servo_groups(out["servo"])
            for group, fields in _servo_groups(v).items():
                old = merged.get(group)
                if isinstance(old, Mapping) and isinstance(fields, Mapping):
                    merged[group] = {**old, **fields}
                elif isinstance(old, str) and isinstance(fields, Mapping) and "preset" not in fields:
                    merged[group] = {"preset": old, **fields}
                else:
                    merged[group] = fields
            out["servo"] = merged
        else:
            out[k] = v
    out.setdefault("name", Path(base).stem)
    return out


def load_map(path: Path) -> RobotModel:
    """Read a robot map YAML and check it against its MJCF (see the module docstring)."""
    source = str(path)
    doc = read_map_doc(path)
    _require(isinstance(doc, Mapping), source, f"expected a mapping with keys {', '.join(MAP_KEYS)}")
    for key in doc:
        _require(key in MAP_KEYS, source, f"unknown key {key!r} (allowed: {', '.join(MAP_KEYS)})")
    _require(("mjcf" in doc) != ("urdf" in doc), source,
             "give the robot file as mjcf: FILE or urdf: FILE (one of them)" if "mjcf" not in doc else
             "mjcf and urdf both given: give one robot file")
    for key in ("torso", "feet", "joints"):
        _require(key in doc, source, f"missing {key!r}")
    key = "mjcf" if "mjcf" in doc else "urdf"
    _require(isinstance(doc[key], str) and doc[key] != "", source, f"{key} = {doc[key]!r}: expected a file path")
    is_urdf = key == "urdf" or doc[key].lower().endswith(".urdf")
    for k in ("packages", "ranges"):
        _require(k not in doc or is_urdf, source, f"{k}: only for a URDF robot file (urdf: FILE)")
    mjcf = path.parent / doc[key]
    try:
        raw = read_bytes_checked(mjcf, "URDF" if is_urdf else "MJCF", MAX_BYTES["urdf" if is_urdf else "mjcf"],
                                 UserError)
    except UserError as exc:
        raise UserError(f"{source}: {key}: {exc}") from None
    mjcf = mjcf.resolve()
    _xml_finite(raw, mjcf.name, source)
    balance = doc.get("balance_inertia", False)
    _require(isinstance(balance, bool), source, f"balance_inertia = {balance!r}: expected true or false")
    foot_sensors = doc.get("foot_sensors", True)
    _require(isinstance(foot_sensors, bool), source, f"foot_sensors = {foot_sensors!r}: expected true (the soles "
             f"measure force, as the built-in robot's) or false (none, as an OP3's or a Darwin-OP's)")
    urdf_limits = None
    package_dirs: dict[str, str] = {}
    load_notes: list[str] = []
    try:
        xml = raw.decode("utf-8")
        if is_urdf:
            packages = _packages(doc.get("packages"), path.parent, source)
            package_dirs = _package_folders(xml, mjcf, packages)
            conv = urdf_to_mjcf(mjcf, raw, torso=doc["torso"] if isinstance(doc["torso"], str) else "",
                                packages=packages,
                                ranges=_ranges(doc.get("ranges"), source), source=source,
                                balance_inertia=balance)
            xml, urdf_limits = conv.xml, conv
            model = mujoco.MjModel.from_xml_string(xml)
        else:
            try:
                spec = mujoco.MjSpec.from_file(str(mjcf))
            except Exception as exc:
                raise UserError(f"{source}: {mjcf.name} does not load in MuJoCo: {mujoco_message(exc)}") from None
            model = compile_checked(spec, balance_inertia=balance, kind="body", fname=mjcf.name, source=source,
                                    notes=load_notes)
    except UnicodeDecodeError:
        raise UserError(f"{source}: {key} file {mjcf.name} is not UTF-8 text") from None
    except UserError:
        raise
    except Exception as exc:
        raise UserError(f"{source}: {mjcf.name} does not load in MuJoCo: {mujoco_message(exc)}") from None
    name = doc.get("name", path.stem)
    _require(isinstance(name, str) and re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._ -]{0,99}", name) is not None,
             source, f"name = {name!r}: expected letters, digits, '.', '_', '-' or spaces (at most 100, "
                     f"no path: it names exported files)")

    torso = doc["torso"]
    _require(_has(model, mujoco.mjtObj.mjOBJ_BODY, torso), source, f"torso body {torso!r} not in {mjcf.name}")
    tb = model.body(torso).id
    _require(model.body_jntnum[tb] >= 1 and model.jnt_type[model.body_jntadr[tb]] == mujoco.mjtJoint.mjJNT_FREE,
             source, f"torso body {torso!r} must carry the model's free joint")
    feet = doc["feet"]
    _require(isinstance(feet, Mapping) and set(feet) == {"left", "right"}, source,
             "feet must be {left: BODY, right: BODY}")
    for side, _, _ in _SIDES:
        _require(_has(model, mujoco.mjtObj.mjOBJ_BODY, feet[side]), source,
                 f"feet.{side}: body {feet[side]!r} not in {mjcf.name}")
    _require(feet["left"] != feet["right"], source, f"feet: left and right are the same body {feet['left']!r}")
    jmap = _read_joints(doc["joints"], model, source, mjcf.name)
    jmap.update(_read_extra_joints(doc.get("extra_joints"), jmap, model, source, mjcf.name))

    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    R_t, p_t = d.xmat[tb].reshape(3, 3), d.xpos[tb].copy()

    def in_torso(p: np.ndarray) -> np.ndarray:
        return R_t.T @ (np.asarray(p) - p_t)

    foot_ids = {side: model.body(feet[side]).id for side, _, _ in _SIDES}
    for side, _, s in _SIDES:
        y = in_torso(d.xpos[foot_ids[side]])[1]
        _require(s * y > 0, source, f"feet.{side}: body {feet[side]!r} lies at y = {_mm(y)} in the torso frame "
                 f"(the {'right' if s > 0 else 'left'} side; +y is left): left and right feet swapped?")
    orders = _check_chains(model, d, R_t, jmap, foot_ids, tb, source)
    final = _signs(model, d, jmap, R_t, source)

    # geometry from the axis lines at the zero pose, in the torso frame
    def line(ours: str) -> tuple[np.ndarray, np.ndarray]:
        j = model.joint(final[ours][0]).id
        return in_torso(d.xanchor[j]), R_t.T @ d.xaxis[j]

    geo: dict[str, dict[str, float]] = {}
    soles, hulls, axes, bodies, sizes, sources = [], [], [], [], [], {}
    chains: dict[str, LegChain] = {}
    numerical: list[tuple[str, str]] = []   # (side, why) where the closed form's ideal leg does not fit (ours)
    for side, p, s in _SIDES:
        why: list[str] = []
        hip_dist, hip = axis_line_distance(*line(p + "hip_roll"), *line(p + "hip_pitch"))
        if hip_dist >= AXIS_TOLERANCE:
            why.append(f"the hip roll and pitch axes pass {_mm(hip_dist)} apart")
        yaw_dist = float(np.linalg.norm(np.cross(hip - line(p + "hip_yaw")[0], line(p + "hip_yaw")[1])))
        if yaw_dist >= AXIS_TOLERANCE:
            why.append(f"the hip yaw axis passes {_mm(yaw_dist)} from the hip centre")
        ank_dist, ankle = axis_line_distance(*line(p + "ankle_pitch"), *line(p + "ankle_roll"))
        if ank_dist >= AXIS_TOLERANCE:
            why.append(f"the ankle pitch and roll axes pass {_mm(ank_dist)} apart")
        knee_p, knee_a = line(p + "knee")
        # the links' lengths: the hip centre's and the ankle centre's distances from the knee's axis
        # (for an ideal leg the distances between the pitch axes; not the skew lines' closest distance,
        # which for axes a hair from parallel lies anywhere along them)
        thigh = float(np.linalg.norm(np.cross(hip - knee_p, knee_a)))
        shank = float(np.linalg.norm(np.cross(ankle - knee_p, knee_a)))
        knee = knee_p - ((knee_p - hip) @ knee_a) * knee_a     # the knee line's point in the hip's plane
        for what, point in (("knee axis", knee), ("ankle centre", ankle)):
            off = point[:2] - hip[:2]
            if abs(off[0]) >= AXIS_TOLERANCE or abs(off[1]) >= AXIS_TOLERANCE:
                why.append(f"the {what} is {_mm(off[0])} ahead of and {_mm(off[1])} left of the hip centre at "
                           f"the zero pose")
        for kind in LEG_JOINTS:
            axis = abs(line(p + kind)[1] @ np.array(LEG_AXES[kind], dtype=float))
            if axis < math.cos(AXIS_ANGLE_TOLERANCE):
                why.append(f"the {kind.replace('_', ' ')} axis is tilted "
                           f"{math.degrees(math.acos(min(axis, 1.0))):.1f} deg from its ideal")
        _require(abs(hip[0]) <= 0.1, source,
                 f"the {side} hip centre is {_mm(hip[0])} ahead of the torso origin; the leg IK takes the hips "
                 f"at most 100.0 mm ahead or behind it: use a torso body whose origin lies nearer the hips")
        fb = foot_ids[side]
        sole = sole_polygon(model, d, fb, R_t)
        _require(sole is not None, source, f"feet.{side}: body {feet[side]!r} has no collision geom")
        S = sole.R_torso_sole                                  # the sole's axes at the zero pose
        c = in_torso(d.xpos[fb]) + S @ sole.centre_sole
        rel = S.T @ (ankle - c)                                # the ankle from the sole centre, sole axes
        tilt = math.degrees(math.acos(min(float(S[2, 2]), 1.0)))
        if tilt > math.degrees(AXIS_ANGLE_TOLERANCE):
            why.append(f"the sole is tilted {tilt:.1f} deg at the zero pose")
        if orders[side] != tuple(range(len(LEG_JOINTS))):
            why.append("the leg turns " + ", ".join(LEG_JOINTS[k].replace("_", " ") for k in orders[side])
                       + " going from the torso")
        if why:
            numerical.append((side, "; ".join(why)))
        # the chain as the file builds it (our signs), its sole point ankle_height below the ankle centre
        # along the sole's normal, its rotation the sole's axes at the zero pose
        chains[side] = LegChain(axes=[final[p + k][1] * line(p + k)[1] for k in LEG_JOINTS],
                                points=[line(p + k)[0] for k in LEG_JOINTS],
                                sole=ankle - rel[2] * S[:, 2], sole_rotation=S,
                                sole_offset=(-rel[0], -rel[1], 0.0), order=orders[side])
        # within the axis tolerance the hips count as under the torso origin, as the knee and ankle
        # count as under the hips (ours: the figures of robots that passed the old check unchanged)
        geo[side] = {"hip_offset_x": float(hip[0]) if abs(hip[0]) >= AXIS_TOLERANCE else 0.0,
                     "hip_offset_y": float(s * hip[1]), "hip_offset_z": float(-hip[2]), "thigh": thigh,
                     "shank": shank, "ankle_height": float(rel[2]),
                     "sole_forward": float(-rel[0]), "sole_outward": float(-s * rel[1])}
        soles.append(tuple(float(v) for v in sole.centre))
        hulls.append(sole.hull)
        sizes.append(sole.size)
        axes.append(sole.R_sole_foot)
        R_f = d.xmat[fb].reshape(3, 3)
        carriers = sorted({int(model.geom_bodyid[g]) for g in foot_geoms(model, fb)})
        bodies.append(tuple((model.body(b).name, R_f.T @ d.xmat[b].reshape(3, 3), R_f.T @ (d.xpos[b] - d.xpos[fb]))
                            for b in carriers))
        sources[f"sole.{side}"] = f"hull of {len(sole.geoms)} collision geom(s): {', '.join(sole.geoms)}"
    derived = geo["left"]
    notes = []
    for key, value in derived.items():
        if abs(geo["right"][key] - value) > 0.002:
            notes.append(f"legs differ: {key} left {_mm(value)}, right {_mm(geo['right'][key])}; "
                         + ("the numerical IK uses each leg's own, the planners the left leg's" if numerical else
                            f"the IK uses the left leg's (give leg.{key} to choose)"))

    leg_over = doc.get("leg") or {}
    _require(isinstance(leg_over, Mapping), source, "leg must be a mapping of LegGeometry fields")
    allowed = [f.name for f in dataclasses.fields(LegGeometry) if f.name != "chains"]
    for k, v in leg_over.items():
        _require(k in allowed, source, f"leg: unknown field {k!r} (allowed: {', '.join(allowed)})")
        _require(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v), source,
                 f"leg.{k} = {v!r}: expected a number [m]")
    try:
        leg = LegGeometry(**{**derived, **{k: float(v) for k, v in leg_over.items()}},
                          chains=LegChains(chains["left"], chains["right"], _ik_reason(numerical)) if numerical else None)
    except ParamError as exc:
        raise UserError(f"{source}: {exc}") from None
    if not {"com_above_pelvis", "com_forward", "com_lateral"} <= set(leg_over):
        try:
            com = com_offset(model, torso, crouch_angles(leg, final))
        except ValueError as exc:          # the crouched pose is out of the derived legs' reach
            raise UserError(f"{source}: leg: {exc}") from None
        leg = dataclasses.replace(leg, **{k: float(v) for k, v in
                                          zip(("com_forward", "com_lateral", "com_above_pelvis"), com)
                                          if k not in leg_over})
    _check_crouch(model, leg, final, source)
    overlaps = self_overlaps(model, [{}, crouch_angles(leg, final)])
    if overlaps:
        notes.append(f"self-collision: {len(overlaps)} pair(s) of bodies interpenetrate at the zero pose or the "
                     f"walking crouch, which the real robot cannot, so they do not collide with each other here: "
                     + ", ".join(f"{a} / {b} ({1000 * v:.1f} mm deep)" for a, b, v in overlaps))
    sources["leg"] = "joint axis lines at the zero pose" + (f"; overridden: {', '.join(leg_over)}" if leg_over else "")
    sources["com"] = f"the model's masses, legs at the walking crouch ({CROUCH:g} x straight hip height)"

    sim_doc = doc.get("sim") or {}
    _require(isinstance(sim_doc, Mapping), source, "sim must be a mapping of " +
             ", ".join(f.name for f in dataclasses.fields(SimOptions)))
    sim_fields = [f.name for f in dataclasses.fields(SimOptions)]
    for k in sim_doc:
        _require(k in sim_fields, source, f"sim: unknown field {k!r} (allowed: {', '.join(sim_fields)})")
    try:
        sim = SimOptions(**dict(sim_doc))
    except UserError as exc:
        raise UserError(f"{source}: {exc}") from None

    servos, servo_sources, preset_gains = _servos(model, final, doc.get("servo"), source, urdf_limits)
    units = read_servo_units(doc.get("servos"), tuple(servos), source)
    try:
        imu, sole_boards, sole_protocol = read_bus(doc.get("bus"), source, {u.id: j for j, u in units.items()})
    except ParamError as exc:
        raise UserError(str(exc)) from None
    sources.update(servo_sources)
    pose, pose_source = _pose(model, final, servos, doc.get("pose"), source)
    sources["pose"] = pose_source
    notes += _keyframe_notes(model)
    from .solver import solver_differences
    differ = solver_differences(model.opt)
    if differ:
        notes.append("the file's solver options are replaced by MuJoCo's defaults, with which the surfaces "
                     "were calibrated: " + ", ".join(differ))
    if model.nu:
        notes.append(f"the file's {model.nu} actuator(s) are replaced by our servo model of the same numbers "
                     f"(see servos), with a speed limit")
    if model.nsensor:
        notes.append(f"the file's {model.nsensor} sensor(s) are left out of the simulation")
    if urdf_limits is not None:
        notes = list(urdf_limits.notes) + notes
    notes = load_notes + notes
    bounding = (float(max(sizes[0][0], sizes[1][0])), float(max(sizes[0][1], sizes[1][1])))
    if max(abs(sizes[0][0] - sizes[1][0]), abs(sizes[0][1] - sizes[1][1])) > 0.001:
        notes.append(f"the feet differ: left sole {_mm(sizes[0][0])} x {_mm(sizes[0][1])}, right "
                     f"{_mm(sizes[1][0])} x {_mm(sizes[1][1])}; each foot's sensors and support use its own, the "
                     f"gaits keep the larger ({_mm(bounding[0])} x {_mm(bounding[1])}) apart")
    return RobotModel(name, xml, final, torso, (str(feet["left"]), str(feet["right"])),
                      (soles[0], soles[1]), bounding, leg, servos, pose, tuple(hulls), sources,
                      tuple(notes), sim, None if is_urdf else str(mjcf), str(path.resolve()), tuple(axes),
                      tuple(bodies), urdf_path=str(mjcf) if is_urdf else None, servo_units=units,
                      package_dirs=package_dirs,
                      foot_sizes=(tuple(sizes[0]), tuple(sizes[1])), balance_inertia=balance and not is_urdf,
                      exclude=tuple((a, b) for a, b, _ in overlaps), preset_gains=preset_gains,
                      foot_sensors=foot_sensors, imu_board=imu, sole_boards=sole_boards, sole_protocol=sole_protocol)


#: attributes that name things (a joint may be called "inf"), never checked as numbers
_NAME_KEYS = frozenset({"name", "class", "childclass", "joint", "joint1", "joint2", "link", "body", "body1", "body2",
                        "site", "mesh", "material", "texture", "objname", "target", "file", "filename", "type",
                        "mode", "tendon", "actuator", "geom", "geom1", "geom2", "hfield", "key"})


def _xml_finite(raw: bytes, fname: str, source: str) -> None:
    """A NaN or an infinity written in any attribute of the robot file, named by element and
    attribute before MuJoCo reads it (MuJoCo itself loads ``nan`` with a warning on the terminal)."""
    import xml.etree.ElementTree as ET
    try:
        root = ET.fromstring(raw)
    except ET.ParseError:
        return                                   # MuJoCo's own parser names the syntax error
    for el in root.iter():
        for key, value in el.attrib.items():
            if key in _NAME_KEYS:
                continue
            try:
                numbers = [float(tok) for tok in value.split()]
            except ValueError:
                continue                         # not a numeric attribute
            if numbers and not all(math.isfinite(v) for v in numbers):
                who = f"<{el.tag} name={el.get('name')!r}>" if el.get("name") else f"<{el.tag}>"
                raise UserError(f"{source}: {fname}: {who} {key}={value!r}: NaN or infinity is not a number "
                                f"a robot file can hold")


def _ik_reason(why: list[tuple[str, str]]) -> str:
    """Why the legs get the numerical IK, in words: per leg, or once when both legs say the same."""
    if len(why) == 2 and why[0][1] == why[1][1]:
        return f"both legs: {why[0][1]}"
    return "; ".join(f"{side} leg: {text}" for side, text in why)


def _check_crouch(model: mujoco.MjModel, leg: LegGeometry, final: Mapping[str, tuple[str, int]], source: str) -> None:
    """Every leg joint's range in the file holds the walking crouch (the legs bent by the IK to
    ``CROUCH`` x the straight hip height, feet under the hips), else one line naming the joint,
    its range and the angle the crouch needs."""
    try:
        angles = crouch_angles(leg, final)
    except ValueError as exc:
        raise UserError(f"{source}: leg: {exc}") from None
    for ours, (theirs, _) in final.items():
        if theirs not in angles:
            continue
        j = model.joint(theirs).id
        if not model.jnt_limited[j]:
            continue
        lo, hi = (float(v) for v in model.jnt_range[j])
        a = angles[theirs]
        _require(lo - 1e-6 <= a <= hi + 1e-6, source,
                 f"joints.{ours}: {theirs!r} has the range [{lo:+.3f}, {hi:+.3f}] rad in the file, which excludes "
                 f"the walking crouch ({CROUCH:g} x the straight hip height): it needs {a:+.3f} rad")


def _package_folders(text: str, urdf: Path, packages: Mapping[str, Path]) -> dict[str, str]:
    """Each ROS package a URDF's ``package://NAME/`` paths name -> its folder, as the URDF reader
    finds it (the map's ``packages:``, else beside or above the URDF, as a ROS workspace lies), for
    tools that read the URDF themselves (placo)."""
    from .urdf import _package_dirs
    out = {}
    for name in sorted(set(re.findall(r"package://([^/\"']+)/", text))):
        dirs = [packages[name]] if name in packages else _package_dirs(name, urdf)
        if dirs:
            out[name] = str(Path(dirs[0]).resolve())
    return out


def _packages(doc: Any, base: Path, source: str) -> dict[str, Path]:
    """The map's ``packages: {NAME: FOLDER}`` (folders relative to the map file, which must exist)."""
    if doc is None:
        return {}
    _require(isinstance(doc, Mapping), source, "packages must be a mapping of ROS package name: folder")
    out = {}
    for k, v in doc.items():
        _require(isinstance(k, str) and isinstance(v, str) and v != "", source,
                 f"packages.{k} = {v!r}: expected a folder path")
        folder = base / v
        _require(folder.is_dir(), source, f"packages.{k} = {v!r}: no such folder ({folder})")
        out[k] = folder
    return out


def _ranges(doc: Any, source: str) -> dict[str, tuple[float, float]]:
    """The map's ``ranges: {JOINT: [LOW, HIGH]}`` [rad], LOW < HIGH, finite."""
    if doc is None:
        return {}
    _require(isinstance(doc, Mapping), source, "ranges must be a mapping of URDF joint name: [LOW, HIGH] [rad]")
    out = {}
    for k, v in doc.items():
        ok = (isinstance(v, (list, tuple)) and len(v) == 2
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in v))
        _require(ok, source, f"ranges.{k} = {v!r}: expected [LOW, HIGH] in rad, finite numbers")
        _require(v[0] < v[1], source, f"ranges.{k} = {v!r}: LOW must be below HIGH")
        out[str(k)] = (float(v[0]), float(v[1]))
    return out


def _read_joint(section: str, ours: str, theirs: Any, model: mujoco.MjModel, source: str,
                fname: str) -> tuple[str, int | None]:
    """One entry ``ours: theirs`` or ``ours: {name: theirs, sign: 1 or -1}`` of a map's joint section."""
    sign = None
    if isinstance(theirs, Mapping):
        _require(set(theirs) <= {"name", "sign"} and "name" in theirs, source,
                 f"{section}.{ours}: expected {{name: ..., sign: 1 or -1}}")
        sign = theirs.get("sign")
        _require(sign is None or (sign in (1, -1) and not isinstance(sign, bool)), source,
                 f"{section}.{ours}.sign = {sign!r}: must be 1 or -1")
        theirs = theirs["name"]
    if not isinstance(theirs, str) or not _has(model, mujoco.mjtObj.mjOBJ_JOINT, theirs):
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
        _require(False, source, f"{section}.{ours}: {theirs!r} is not a joint of {fname}"
                                f"{did_you_mean(str(theirs), names)}")
    _require(model.jnt_type[model.joint(theirs).id] == mujoco.mjtJoint.mjJNT_HINGE, source,
             f"{section}.{ours}: {theirs!r} is not a hinge joint")
    return theirs, sign


def _read_extra_joints(doc: Any, jmap: Mapping[str, tuple[str, int | None]], model: mujoco.MjModel, source: str,
                       fname: str) -> dict[str, tuple[str, int | None]]:
    """The map's ``extra_joints:``: joints beyond our 20 roles (a shoulder yaw, a waist), by a name of
    the map's own (lower case, digits, underscores) -> the MJCF joint, as in ``joints:``. The walk
    engines hold them at ``pose``; a policy may drive them by that name (``gaits/policy.py``)."""
    if doc is None:
        return {}
    _require(isinstance(doc, Mapping), source, "extra_joints must be a mapping of a name of yours: MJCF joint")
    out: dict[str, tuple[str, int | None]] = {}
    taken = {theirs for theirs, _ in jmap.values()}
    for ours, theirs in doc.items():
        _require(isinstance(ours, str) and JOINT_NAME_PATTERN.fullmatch(ours) is not None, source,
                 f"extra_joints: {ours!r}: a name of lower-case letters, digits and underscores")
        _require(ours not in JOINT_NAMES, source, f"extra_joints.{ours}: one of our 20 roles; map it under joints:")
        name, sign = _read_joint("extra_joints", ours, theirs, model, source, fname)
        _require(name not in taken, source, f"extra_joints.{ours}: {name!r} is mapped twice")
        taken.add(name)
        out[ours] = (name, sign)
    return out


def _read_joints(joints: Any, model: mujoco.MjModel, source: str, fname: str) -> dict[str, tuple[str, int | None]]:
    _require(isinstance(joints, Mapping), source, "joints must be a mapping of our name: MJCF joint")
    jmap: dict[str, tuple[str, int | None]] = {}
    for ours, theirs in joints.items():
        if ours not in JOINT_NAMES:
            _require(False, source, f"joints: unknown joint {ours!r}{did_you_mean(ours, JOINT_NAMES)} "
                                    f"(ours are: {', '.join(JOINT_NAMES)}; a joint beyond them goes under "
                                    f"extra_joints:)")
        jmap[ours] = _read_joint("joints", ours, theirs, model, source, fname)
    missing = [j for j in JOINT_NAMES if j[2:] in LEG_JOINTS and j not in jmap]
    _require(not missing, source, f"joints: leg joints missing from the map: {', '.join(missing)}")
    used = [v[0] for v in jmap.values()]
    dup = sorted({u for u in used if used.count(u) > 1})
    _require(not dup, source, f"joints: MJCF joint(s) mapped twice: {', '.join(dup)}")
    return jmap


def _axis_fits(model: mujoco.MjModel, d: mujoco.MjData, R_t: np.ndarray, joint: str, kind: str) -> bool:
    axis = R_t.T @ d.xaxis[model.joint(joint).id]
    return abs(float(axis @ np.array(LEG_AXES[kind], dtype=float))) >= AXIS_FIT


_HIPS = ("hip_yaw", "hip_roll", "hip_pitch")
_ANKLES = ("ankle_pitch", "ankle_roll")


def _check_chains(model: mujoco.MjModel, d: mujoco.MjData, R_t: np.ndarray,
                  jmap: Mapping[str, tuple[str, int | None]], foot_ids: Mapping[str, int], tb: int,
                  source: str) -> dict[str, tuple[int, ...]]:
    """Each leg joint lies on the chain from the torso to its own foot: the three hip joints, then
    the knee, then the two ankle joints. Within the hip and within the ankle the file's order is the
    robot's own build (e.g. a hip that turns roll, then yaw, as Berkeley Humanoid Lite's) when each
    joint turns about its kind's axis: such legs get the numerical IK, composed in that order
    (ours: the papers' closed form is yaw, roll, pitch). Otherwise two names look swapped. Returns
    each side's order (indices into LEG_JOINTS, torso to foot)."""
    chains = {side: body_chain(model, foot_ids[side]) for side in foot_ids}
    orders: dict[str, tuple[int, ...]] = {}
    for side, p, _ in _SIDES:
        other = "right" if side == "left" else "left"
        _require(tb in chains[side], source, f"feet.{side}: body {model.body(foot_ids[side]).name!r} is not "
                 f"below the torso {model.body(tb).name!r}")
        ranks = []
        for kind in LEG_JOINTS:
            theirs = jmap[p + kind][0]
            j = model.joint(theirs).id
            b = int(model.jnt_bodyid[j])
            if b not in chains[side]:
                where = (f"on the {other} leg (the chain to {model.body(foot_ids[other]).name!r}): left and right "
                         f"swapped?" if b in chains[other] else
                         f"not on the chain from the torso to the {side} foot {model.body(foot_ids[side]).name!r}")
                raise UserError(f"{source}: joints.{p}{kind}: {theirs!r} is {where}")
            ranks.append((-chains[side].index(b), j))
        rank = dict(zip(LEG_JOINTS, ranks))
        order = tuple(sorted(range(len(LEG_JOINTS)), key=lambda k: ranks[k]))
        if order != tuple(range(len(LEG_JOINTS))) and not (
                max(rank[k] for k in _HIPS) < rank["knee"] < min(rank[k] for k in _ANKLES)
                and all(_axis_fits(model, d, R_t, jmap[p + kind][0], kind) for kind in LEG_JOINTS)):
            for k in range(len(LEG_JOINTS) - 1):
                if ranks[k] >= ranks[k + 1]:
                    a, b = LEG_JOINTS[k], LEG_JOINTS[k + 1]
                    raise UserError(
                        f"{source}: joints.{p}{a} and joints.{p}{b} look swapped: {jmap[p + b][0]!r} comes before "
                        f"{jmap[p + a][0]!r} going from the torso to the {side} foot (the order is the three hip "
                        f"joints, the knee, the two ankle joints; the closed-form IK's "
                        f"{', '.join(x.replace('_', ' ') for x in LEG_JOINTS)})")
        orders[side] = order
    return orders


def _signs(model: mujoco.MjModel, d: mujoco.MjData, jmap: Mapping[str, tuple[str, int | None]],
           R_t: np.ndarray, source: str) -> dict[str, tuple[str, int]]:
    """Leg joint signs from their axes (a given sign must agree); others keep theirs (default 1)."""
    final: dict[str, tuple[str, int]] = {}
    for ours, (theirs, sign) in jmap.items():
        j = model.joint(theirs).id
        kind = ours[2:] if ours[:2] in ("l_", "r_") else ours
        if kind in LEG_AXES:
            axis = R_t.T @ d.xaxis[j]
            expected = np.array(LEG_AXES[kind], dtype=float)
            dot = float(axis @ expected)
            _require(abs(dot) >= AXIS_FIT, source,
                     f"joints.{ours}: {theirs!r} turns about {np.round(axis, 3).tolist()} in the torso frame; "
                     f"a {kind.replace('_', ' ')} joint must turn about +-{list(LEG_AXES[kind])} (within "
                     f"{math.degrees(math.acos(AXIS_FIT)):.0f} deg)")
            natural = 1 if dot > 0 else -1
            _require(sign is None or sign == natural, source,
                     f"joints.{ours}.sign = {sign} contradicts the axis of {theirs!r} "
                     f"({np.round(axis, 3).tolist()}); use sign {natural} or leave it out")
            sign = natural
        final[ours] = (theirs, 1 if sign is None else int(sign))
    return final


def _servos(model: mujoco.MjModel, final: Mapping[str, tuple[str, int]], doc: Any,
            source: str, urdf: UrdfRobot | None = None) -> tuple[dict[str, Any], dict[str, str], tuple[str, ...]]:
    """A servo for every hinge joint but the free one: the file's own position actuator, else
    the group's default preset (for a URDF with its torque and speed from the joint's ``<limit
    effort velocity>`` where stated), then the map's ``servo:`` fields on top. The sources say,
    per group, where each field came from (the file, a preset and why, the URDF, the map). The third
    value names the groups whose gains are a preset's with nothing stating any (no file actuator on
    any of their joints, no ``kp`` or preset in the map's entries for them)."""
    doc = doc or {}
    _require(isinstance(doc, Mapping), source, f"servo must be a mapping with keys {', '.join(GROUPS)}")
    if doc and set(doc) <= set(SERVO_FIELDS) | {"preset"}:
        doc = {"legs": dict(doc)}            # the first map format: flat fields meant the legs
    joints_ours = set(final)
    for k in doc:
        _require(k in GROUPS or k in FINE_GROUPS or k in joints_ours, source,
                 f"servo: unknown group {k!r} (allowed: {', '.join(GROUPS + FINE_GROUPS)}, or one of the "
                 f"map's joints by our name)")
    ours_of = {theirs: ours for ours, (theirs, _) in final.items()}
    servos: dict[str, Any] = {}
    # per group: joints whose gains came from the file; why the others took the preset; URDF limits used
    from_file = {g: 0 for g in GROUPS}
    why_preset: dict[str, dict[str, int]] = {g: {} for g in GROUPS}
    urdf_used = {g: {"torque": 0, "speed": 0} for g in GROUPS}
    count = {g: 0 for g in GROUPS}
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        theirs = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        _require(theirs is not None, source, f"joint #{j} of the MJCF has no name; every hinge needs one "
                 f"(the tool holds unmapped joints by name)")
        group = joint_group(ours_of.get(theirs))
        count[group] += 1
        spec, why = servo_from_file(model, theirs, _file_speed(group))
        if spec is None:
            spec = default_servo(group)
            why = re.sub(r"^actuator '[^']*' ", "its actuator ", why)       # one reason per kind, not per joint
            why_preset[group][why] = why_preset[group].get(why, 0) + 1
        else:
            from_file[group] += 1
        if urdf is not None:
            effort, velocity = urdf.effort.get(theirs), urdf.velocity.get(theirs)
            lim = {}
            if effort is not None and 0 < effort <= 200:
                lim["torque"] = effort
                urdf_used[group]["torque"] += 1
            if velocity is not None and 0 < velocity <= 100:
                lim["speed"] = velocity
                urdf_used[group]["speed"] += 1
            if lim:
                try:                   # a motor's: the stall torque and unloaded speed at its voltage (kt, R)
                    spec = spec.replace(**lim) if isinstance(spec, PDServo) else spec.with_datasheet(**lim)
                except UserError as exc:
                    raise UserError(f"{source}: joint {theirs!r}: its <limit effort velocity>: {exc}") from None
        if group in doc:
            spec = servo_from_mapping(doc[group], f"servo.{group}", spec)
        ours = ours_of.get(theirs)
        fine = fine_group(ours) if ours is not None else None
        if fine is not None and fine in doc:                 # then the finer group (an identification's)
            spec = servo_from_mapping(doc[fine], f"servo.{fine}", spec)
        if ours is not None and ours in doc:                 # then the joint itself
            spec = servo_from_mapping(doc[ours], f"servo.{ours}", spec)
        servos[theirs] = spec
    sources = {}
    for g in GROUPS:
        n = count[g]
        if not n:
            continue
        entry = doc.get(g)
        map_preset = entry if isinstance(entry, str) else (entry.get("preset") if isinstance(entry, Mapping) else None)
        map_fields = sorted(k for k in entry if k != "preset") if isinstance(entry, Mapping) else []
        parts = []
        if map_preset is not None:
            parts.append(f"preset {map_preset} from the map on {n} joint(s)")
        else:
            if from_file[g]:
                parts.append(f"the file's actuators on {from_file[g]} joint(s) (the pd law)")
                if "speed" not in map_fields and not urdf_used[g]["speed"]:
                    parts.append(f"speed {_file_speed(g):g} rad/s from preset {_DEFAULT_PRESET[g]}-pd (a file states none)")
            for why, k in why_preset[g].items():
                what = "a URDF has no servo gains" if urdf is not None else why
                parts.append(f"preset {_DEFAULT_PRESET[g]} at {DEFAULT_VOLTAGE:g} V on {k} joint(s) ({what})")
            n_t, n_v = urdf_used[g]["torque"], urdf_used[g]["speed"]
            motor = " (the stall torque at its voltage: kt and R follow)" if why_preset[g] else ""
            if urdf is not None and n_t and "torque" not in map_fields:
                parts.append(f"torque from the URDF's <limit effort> on {n_t} joint(s){motor}")
            if urdf is not None and n_v and "speed" not in map_fields:
                parts.append(f"speed from the URDF's <limit velocity> on {n_v} joint(s)"
                             + (" (the unloaded speed)" if motor else ""))
        if "speed" in map_fields:
            parts.append("speed from the map")
        over = [f for f in map_fields if f != "speed"]
        if over:
            parts.append(f"map servo.{g} sets {', '.join(over)}")
        first = next(sv for theirs_, sv in servos.items() if joint_group(ours_of.get(theirs_)) == g)
        sources[f"servos.{g}"] = "; ".join(parts) + f" -> {first.describe()}"
    def states_gains(entry: Any) -> bool:
        return isinstance(entry, str) or (isinstance(entry, Mapping) and ("kp" in entry or "p_gain" in entry or "preset" in entry))

    stated = {g for g in GROUPS if states_gains(doc.get(g))}
    stated |= {"legs" if k in FINE_GROUPS else joint_group(k) for k in doc if k not in GROUPS and states_gains(doc[k])}
    preset_gains = tuple(g for g in GROUPS if count[g] and not from_file[g] and g not in stated)
    finer = [k for k in doc if k not in GROUPS]
    if finer:
        sources["servos.finer"] = (f"the map's servo.{', servo.'.join(finer)} over their group's "
                                   f"(joint groups, then joints: an identification's overlay)")
    return servos, sources, preset_gains


def _pose(model: mujoco.MjModel, final: Mapping[str, tuple[str, int]], servos: Mapping[str, Any], doc: Any,
          source: str) -> tuple[dict[str, float], str]:
    """Held angle of every actuated non-leg joint: the map's ``pose:``, else the file's first
    keyframe, else zero (clipped into the joint's range)."""
    doc = doc or {}
    _require(isinstance(doc, Mapping), source, "pose must be a mapping of MJCF joint name: angle [rad]")
    legs = {theirs for ours, (theirs, _) in final.items() if joint_group(ours) == "legs"}
    for k, v in doc.items():
        _require(k in servos and k not in legs, source,
                 f"pose: {k!r} is not a non-leg hinge joint of the file (leg joints follow the gait)")
        _require(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v), source,
                 f"pose.{k} = {v!r}: expected an angle [rad]")
    use_key = model.nkey > 0
    pose, clipped = {}, []
    for theirs in servos:
        if theirs in legs:
            continue
        j = model.joint(theirs).id
        if theirs in doc:
            value = float(doc[theirs])
        elif use_key:
            value = float(model.key_qpos[0, model.jnt_qposadr[j]])
        else:
            value = 0.0
        if model.jnt_limited[j]:
            lo, hi = model.jnt_range[j]
            if not lo <= value <= hi:
                clipped.append(theirs)
                _require(theirs not in doc, source, f"pose.{theirs} = {value!r} rad is out of the joint's range "
                         f"[{lo:g}, {hi:g}] rad")
                value = float(np.clip(value, lo, hi))
        pose[theirs] = value
    key_name = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, 0) or "#0") if use_key else None
    src = ("map pose:" if doc else "") + (f" the others from keyframe {key_name!r}" if use_key else
                                           " the others at zero (the file has no keyframe)")
    if clipped:
        src += f"; clipped into their range: {', '.join(clipped)}"
    return pose, src.strip()


def _keyframe_notes(model: mujoco.MjModel) -> list[str]:
    out = []
    for k in range(model.nkey):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k) or f"#{k}"
        out.append(f"keyframe {name!r}: its ctrl is rebuilt for our servos from its qpos")
    return out
