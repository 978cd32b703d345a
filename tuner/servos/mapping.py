"""A servo from the YAML boundary (a map's ``servo:`` entries) and from a robot file's own actuator.

A map entry is a preset name, or a mapping: ``preset`` (a name of ``presets.yaml``),
``friction_model`` (a dc-motor preset's form, m1 ... m6), ``law`` (to change law without a preset),
and the law's own fields over the entry's base (the group's, then the finer group's, then the
joint's). On a dc-motor servo ``kp`` [N m/rad] is accepted as the position gain it should have, and
turned into the P register that gives it at the servo's voltage (said in the sources).
"""

from __future__ import annotations

from typing import Any, Mapping

import mujoco

from ..errors import UserError
from .law import LAWS, ServoLaw
from .motor import MotorServo
from .pd import PDServo
from .presets import preset, preset_names

__all__ = ["SERVO_FIELDS", "servo_from_mapping", "servo_from_file"]

#: every key a map's servo entry may hold, whatever its law
SERVO_FIELDS = tuple(dict.fromkeys(("preset", "law", "friction_model", "kp")
                                   + tuple(f for cls in LAWS.values() for f in cls.settable())))


def servo_from_mapping(doc: Any, where: str, base: ServoLaw) -> ServoLaw:
    """A servo from a map entry over ``base`` (see the module docstring); bad entries are one line
    naming ``where`` (e.g. ``servo.legs``), the field, its value and what is allowed."""
    if isinstance(doc, str):
        doc = {"preset": doc}
    if not isinstance(doc, Mapping):
        raise UserError(f"{where}: expected a preset name ({', '.join(preset_names())}) or a mapping of "
                        f"{', '.join(SERVO_FIELDS)}")
    fields = dict(doc)
    name = fields.pop("preset", None)
    law = fields.pop("law", None)
    form = fields.pop("friction_model", None)
    try:
        if name is not None:
            if not isinstance(name, str):
                raise UserError(f"preset = {name!r}: expected a preset name ({', '.join(preset_names())})")
            base = preset(name, form)
        elif form is not None:
            if not isinstance(base, MotorServo) or not base.preset:
                raise UserError(f"friction_model = {form!r} needs a dc-motor preset (the forms' parameters "
                                f"are a preset's): give preset: too")
            kept = {k: getattr(base, k) for k in ("voltage", "p_gain", "backlash", "latency")}
            base = preset(base.preset, form).replace(**kept)
        if law is not None and law != base.law:
            if law not in LAWS:
                raise UserError(f"law = {law!r}: one of {', '.join(LAWS)}")
            base = LAWS[law]()
        kp = fields.pop("kp", None) if isinstance(base, MotorServo) else None
        wrong = [k for k in fields if k not in base.settable()]
        if wrong:
            k = wrong[0]
            if isinstance(base, MotorServo) and k in PDServo.fields():
                raise UserError(f"{k}: not a field of the dc-motor law (its torque and speed follow from its "
                                f"voltage, kt and resistance: set those, or name a -pd preset for the old law)")
            allowed = ("preset", "law") + (("friction_model", "kp") if isinstance(base, MotorServo) else ()) \
                + base.settable()
            raise UserError(f"unknown field {k!r} (allowed for the {base.law} law: {', '.join(allowed)})")
        servo = base.replace(**fields)
        if kp is not None:
            if isinstance(kp, bool) or not isinstance(kp, (int, float)) or not kp > 0:
                raise UserError(f"kp = {kp!r}: expected a position gain > 0 N m/rad")
            per_unit = servo.gain / servo.p_gain               # N m/rad per P unit at this voltage
            servo = servo.replace(p_gain=float(kp) / per_unit)
        return servo
    except UserError as exc:
        msg = str(exc).removeprefix("servo.")
        field = msg.split(" ", 1)[0].rstrip(":")
        named = field in SERVO_FIELDS and (msg.startswith(f"{field} = ") or msg.startswith(f"{field}:"))
        raise UserError(f"{where}.{msg}" if named else f"{where}: {msg}") from None


def servo_from_file(model: mujoco.MjModel, joint: str, fallback_speed: float) -> tuple[ServoLaw | None, str]:
    """The servo an MJCF itself gives a hinge joint, as the pd law: its position actuator's kp, kv
    and force range, the joint's armature, damping and friction loss. Returns (None, why) when the
    file has no position actuator on the joint or gives it no torque limit. The file never states a
    speed: ``fallback_speed`` [rad/s] is used and said so by the caller."""
    j = model.joint(joint).id
    dof = model.jnt_dofadr[j]
    acts = [a for a in range(model.nu) if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
            and model.actuator_trnid[a, 0] == j]
    if not acts:
        return None, "no actuator in the file"
    a = acts[0]
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"#{a}"
    gain, bias = model.actuator_gainprm[a], model.actuator_biasprm[a]
    is_position = (model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
                   and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
                   and gain[0] > 0 and abs(bias[1] + gain[0]) < 1e-9 * max(1.0, gain[0]))
    if not is_position:
        return None, f"actuator {name!r} is not a position servo"
    gear = float(model.actuator_gear[a, 0])
    if model.actuator_forcelimited[a]:
        torque = float(max(abs(model.actuator_forcerange[a, 0]), abs(model.actuator_forcerange[a, 1])))
    elif model.jnt_actfrclimited[j]:
        torque = float(max(abs(model.jnt_actfrcrange[j, 0]), abs(model.jnt_actfrcrange[j, 1])))
    else:
        return None, f"actuator {name!r} has no force range (an unlimited servo)"
    try:
        spec = PDServo(kp=float(gain[0]) * gear * gear, kv=float(-bias[2]) * gear * gear,
                       torque=torque * abs(gear), speed=fallback_speed,
                       armature=float(model.dof_armature[dof]), damping=float(model.dof_damping[dof]),
                       frictionloss=float(model.dof_frictionloss[dof]))
    except UserError as exc:
        raise UserError(f"actuator {name!r} on joint {joint!r}: {exc}") from None
    return spec, f"actuator {name!r}"
