"""Servo models: a position-controlled hobby servo, named presets, and reading one off an MJCF.

A servo here is MuJoCo's position actuator (torque = kp (q_cmd - q) - kv q', clipped to
+-torque) on a joint with armature, damping and friction loss, plus a limit on how fast the
commanded target may move (``speed``), which the simulator applies every control tick, and, where
identified from a recording (``gait-tuner identify servos``), a gearbox dead band (``backlash``)
and a command latency (``latency``; the simulator delays every command by the largest servo's,
in whole control ticks).

Presets (``SERVO_PRESETS``): stall torque and no-load speed are ROBOTIS e-manual figures at
12 V (MX-28: 2.5 N m, 55 rpm; MX-64: 6.0 N m, 63 rpm; MX-106: 8.4 N m, 45 rpm; XM430-W350:
4.1 N m, 46 rpm). The gains, armature, damping and friction loss are ours: values of the size
that identified Dynamixel models use (the manual gives none of them in SI units); the MX-64
preset is the built-in robot's leg servo and the MX-28 preset its arm servo.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

import mujoco
import numpy as np

from ..errors import UserError

__all__ = ["ServoSpec", "SERVO_PRESETS", "SERVO_FIELDS", "servo_from_mapping", "servo_from_file"]


#: Allowed range of each servo field: (low, high, unit). Low is exclusive for kp, torque, speed.
_RANGES = {"kp": (0.0, 1000.0, "N m/rad"), "kv": (0.0, 100.0, "N m s/rad"),
           "torque": (0.0, 200.0, "N m"), "speed": (0.0, 100.0, "rad/s"),
           "armature": (0.0, 1.0, "kg m^2"), "damping": (0.0, 100.0, "N m s/rad"),
           "frictionloss": (0.0, 100.0, "N m"), "backlash": (0.0, 0.2, "rad"), "latency": (0.0, 0.2, "s")}
_STRICTLY_POSITIVE = ("kp", "torque", "speed")


@dataclass(frozen=True)
class ServoSpec:
    """A position-controlled hobby servo (SI units). Validated on construction."""

    kp: float = 40.0            # [N m/rad] proportional gain
    kv: float = 0.5             # [N m s/rad] velocity feedback
    torque: float = 6.0         # [N m] torque limit (stall)
    speed: float = 6.5          # [rad/s] speed limit of the commanded target
    armature: float = 0.008     # [kg m^2] reflected rotor inertia
    damping: float = 0.2        # [N m s/rad] gearbox viscous friction
    frictionloss: float = 0.03  # [N m] gearbox dry friction
    backlash: float = 0.0       # [rad] gearbox dead band, full width (identified; the presets state none)
    latency: float = 0.0        # [s] from a command to the servo acting on it (identified; one per robot)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            lo, hi, unit = _RANGES[f.name]
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise UserError(f"servo.{f.name} = {value!r}: expected a number in [{lo:g}, {hi:g}] {unit}")
            v = float(value)
            bad_low = v <= lo if f.name in _STRICTLY_POSITIVE else v < lo
            if not math.isfinite(v) or bad_low or v > hi:
                bracket = "(" if f.name in _STRICTLY_POSITIVE else "["
                raise UserError(f"servo.{f.name} = {value!r} {unit} is out of range {bracket}{lo:g}, {hi:g}] {unit}")
            object.__setattr__(self, f.name, v)


SERVO_FIELDS = tuple(f.name for f in dataclasses.fields(ServoSpec))

SERVO_PRESETS: dict[str, ServoSpec] = {
    "MX-28": ServoSpec(kp=15.0, kv=0.2, torque=2.5, speed=5.8, armature=0.004),
    "MX-64": ServoSpec(kp=40.0, kv=0.5, torque=6.0, speed=6.5, armature=0.008),
    "MX-106": ServoSpec(kp=55.0, kv=0.6, torque=8.4, speed=4.7, armature=0.012),
    "XM430-W350": ServoSpec(kp=30.0, kv=0.4, torque=4.1, speed=4.8, armature=0.006),
}


def servo_from_mapping(doc: Any, where: str, base: ServoSpec) -> ServoSpec:
    """A servo from a map entry: a preset name, or {preset: NAME, FIELD: value, ...} over ``base``."""
    if isinstance(doc, str):
        doc = {"preset": doc}
    if not isinstance(doc, Mapping):
        raise UserError(f"{where}: expected a preset name ({', '.join(SERVO_PRESETS)}) or a mapping "
                        f"of {', '.join(('preset',) + SERVO_FIELDS)}")
    fields = dict(doc)
    preset = fields.pop("preset", None)
    if preset is not None:
        if preset not in SERVO_PRESETS:
            raise UserError(f"{where}.preset = {preset!r}: unknown (allowed: {', '.join(SERVO_PRESETS)})")
        base = SERVO_PRESETS[preset]
    unknown = [k for k in fields if k not in SERVO_FIELDS]
    if unknown:
        raise UserError(f"{where}: unknown field {unknown[0]!r} (allowed: {', '.join(('preset',) + SERVO_FIELDS)})")
    try:
        return dataclasses.replace(base, **fields)
    except UserError as exc:
        raise UserError(f"{where}: {exc}") from None


def servo_from_file(model: mujoco.MjModel, joint: str, fallback_speed: float) -> tuple[ServoSpec | None, str]:
    """The servo an MJCF itself gives a hinge joint: its position actuator's kp, kv and force
    range, the joint's armature, damping and friction loss. Returns (None, why) when the file
    has no position actuator on the joint or gives it no torque limit. The file never states a
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
        spec = ServoSpec(kp=float(gain[0]) * gear * gear, kv=float(-bias[2]) * gear * gear,
                         torque=torque * abs(gear), speed=fallback_speed,
                         armature=float(model.dof_armature[dof]), damping=float(model.dof_damping[dof]),
                         frictionloss=float(model.dof_frictionloss[dof]))
    except UserError as exc:
        raise UserError(f"actuator {name!r} on joint {joint!r}: {exc}") from None
    return spec, f"actuator {name!r}"
