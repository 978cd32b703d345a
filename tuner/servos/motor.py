"""A hobby servo as it is: a DC motor driven by a voltage, behind the firmware's position loop.

Per physics step (a servo's firmware loop runs faster than our control tick), after Rhoban's BAM
(Duclusaud & Passault, "Extended friction models for the physics simulation of servo actuators",
2024; ``better-actuator-models`` 1.0.2, whose published parameters the presets carry):

    duty   = clip(error_gain * p_gain * (q_target - q), -max_duty, +max_duty)
    torque = kt / R * (V * duty - kt * q')  -  friction(q', torque, external torque)

``p_gain`` is the firmware's P register in the servo's own control-table units as a team writes
it, ``error_gain`` the duty one unit of it gives per radian of error (measured per firmware family:
``presets.yaml``). The back-EMF takes torque away *after* the duty saturates, so the torque left
falls in a straight line with speed, to none at V max_duty / kt.

In MuJoCo's own pieces (``law.ServoPieces``) this is exact for the Coulomb-viscous friction (BAM's
M1): a position actuator of gain kt V error_gain p_gain / R clamped at kt V max_duty / R; the
back-EMF kt^2 / R as the actuator's damping, outside the clamp (MuJoCo integrates it implicitly);
the viscous friction as the joint's damping, the Coulomb friction as its friction loss, the rotor
and gear inertia as its armature. ``mujoco.rollout`` and a saved scene keep working.

BAM's extended friction (M2 to M6) makes the dry friction a budget that depends on speed and load:

    F = base + stribeck * s + [load terms]            s = exp(-|q' / stribeck_speed| ** alpha)
    M3:  + load * |ext - motor|                       M4: + (load + load_stribeck * s) * |ext - motor|
    M5:  + |ext * load_external - motor * load_motor|
         + s * |ext * load_external_stribeck - motor * load_motor_stribeck|
    M6:  M5 + s * (load_external_quad * ext^2   where |ext| < |motor|,
                   load_motor_quad * motor^2    where |ext| > |motor|)   when ext and motor differ in sign

(the quadratic term's pairing is BAM's own, kept as its code writes it). ``motor`` is the motor's
torque, back-EMF included; ``ext`` the torque the rest of the body puts on the joint. MuJoCo has
no piece for a friction loss that changes within a walk, so this term runs inside every physics
step (``tuner/sim/native_step.c``), which sets the joint's friction constraint to F; ours: the
external torque is the bias force (gravity, Coriolis) of that step, the contacts left out (BAM's
bench has none; a standing leg's contact torque is met by the motor's, which the term sees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .law import SHARED_RANGES, ServoLaw, ServoPieces, register

__all__ = ["MotorServo", "FRICTION_MODELS", "friction_budget", "FRICTION_WIDTH", "FRICTION_MAGIC"]

#: BAM's friction forms: which terms each has (stribeck, load-dependent, directional, quadratic)
FRICTION_MODELS = {"m1": (False, False, False, False), "m2": (True, False, False, False),
                   "m3": (False, True, False, False), "m4": (True, True, False, False),
                   "m5": (True, True, True, False), "m6": (True, True, True, True)}

#: the per-step term's parameters on the actuator (``actuator_user``), mirrored in native_step.c
FRICTION_MAGIC = 31415.0
FRICTION_WIDTH = 15
(_MAGIC, _FLAGS, _BASE, _STRIBECK, _STRIBECK_SPEED, _ALPHA, _LOAD, _LOAD_S, _LOAD_M, _LOAD_E, _LOAD_MS, _LOAD_ES,
 _LOAD_MQ, _LOAD_EQ, _BACK_EMF) = range(FRICTION_WIDTH)
#: the term's columns others write (an identification's fit)
(FRICTION_FLAGS, FRICTION_BASE, FRICTION_STRIBECK, FRICTION_STRIBECK_SPEED, FRICTION_ALPHA, FRICTION_LOAD_MOTOR,
 FRICTION_BACK_EMF) = (_FLAGS, _BASE, _STRIBECK, _STRIBECK_SPEED, _ALPHA, _LOAD_M, _BACK_EMF)


@register
@dataclass(frozen=True)
class MotorServo(ServoLaw):
    """A voltage-controlled servo (SI units; defaults: BAM's MX-64, M1, at its bench's 15 V and P 32)."""

    law: ClassVar[str] = "dc-motor"
    RANGES: ClassVar = {"voltage": (0.0, 60.0, "V"), "p_gain": (0.0, 100000.0, "control-table units"),
                        "error_gain": (0.0, 10.0, "duty per rad per P unit"), "max_duty": (0.0, 1.0, "-"),
                        "profile_speed": (0.0, 100.0, "rad/s"),
                        "kt": (0.0, 20.0, "N m/A"), "resistance": (0.0, 1000.0, "ohm"), **SHARED_RANGES,
                        "damping": (0.0, 20.0, "N m s/rad"), "stribeck": (0.0, 20.0, "N m"),
                        "stribeck_speed": (0.0, 100.0, "rad/s"), "stribeck_alpha": (0.0, 20.0, "-"),
                        "load": (0.0, 5.0, "-"), "load_stribeck": (0.0, 5.0, "-"), "load_motor": (0.0, 5.0, "-"),
                        "load_external": (0.0, 5.0, "-"), "load_motor_stribeck": (0.0, 5.0, "-"),
                        "load_external_stribeck": (0.0, 5.0, "-"), "load_motor_quad": (0.0, 1.0, "1/(N m)"),
                        "load_external_quad": (0.0, 1.0, "1/(N m)")}
    STRICT: ClassVar = ("voltage", "p_gain", "error_gain", "max_duty", "kt", "resistance", "stribeck_speed",
                        "stribeck_alpha")
    FIXED: ClassVar = ("preset",)

    preset: str = ""                    # the preset it came from (bookkeeping, said in reports)
    friction_model: str = "m1"          # which of BAM's forms the friction follows: m1 ... m6
    voltage: float = 15.0               # [V] supply at the servo
    p_gain: float = 32.0                # [control-table units] the firmware's P gain as written
    error_gain: float = 0.158           # [1/(rad unit)] duty per radian of error per unit of p_gain
    max_duty: float = 0.9625            # [-] the firmware's largest PWM duty
    profile_speed: float = 0.0          # [rad/s] the firmware's cap on how fast the goal moves (0: none)
    kt: float = 1.6224668               # [N m/A] torque constant at the output (= back-EMF [V s/rad])
    resistance: float = 3.9494337       # [ohm] winding resistance
    armature: float = 0.0119512         # [kg m^2] rotor and gear inertia at the output
    frictionloss: float = 0.0903868     # [N m] dry (Coulomb) friction, the budget's base
    damping: float = 0.0116916          # [N m s/rad] viscous friction
    stribeck: float = 0.0               # [N m] extra dry friction near rest (M2, M4-M6)
    stribeck_speed: float = 0.2         # [rad/s] speed scale of the Stribeck effect
    stribeck_alpha: float = 1.35        # [-] its curvature
    load: float = 0.0                   # [-] load-dependent friction per N m of gearbox torque (M3, M4)
    load_stribeck: float = 0.0          # [-] its part near rest (M4)
    load_motor: float = 0.0             # [-] directional: per N m of motor torque (M5, M6)
    load_external: float = 0.0          # [-] per N m of external torque
    load_motor_stribeck: float = 0.0    # [-] their parts near rest
    load_external_stribeck: float = 0.0
    load_motor_quad: float = 0.0        # [1/(N m)] quadratic terms (M6)
    load_external_quad: float = 0.0
    backlash: float = 0.0               # [rad] gearbox dead band, full width (identified; presets state none)
    latency: float = 0.0                # [s] command to servo (identified; one per robot)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.friction_model not in FRICTION_MODELS:
            from ..errors import UserError
            raise UserError(f"servo.friction_model = {self.friction_model!r}: one of {', '.join(FRICTION_MODELS)} "
                            f"(BAM's forms: m1 Coulomb-viscous ... m6 Stribeck, load-dependent, quadratic)")

    # --- the motor's figures ------------------------------------------------------------------
    @property
    def stall_torque(self) -> float:
        """[N m] the torque at full duty and rest, before friction."""
        return self.kt * self.voltage * self.max_duty / self.resistance

    @property
    def gain(self) -> float:
        """[N m/rad] torque per radian of error while the duty is not saturated."""
        return self.kt * self.voltage * self.error_gain * self.p_gain / self.resistance

    @property
    def back_emf_damping(self) -> float:
        """[N m s/rad] kt^2 / R: the torque the back-EMF takes per rad/s."""
        return self.kt * self.kt / self.resistance

    @property
    def speed(self) -> float:
        """[rad/s] the fastest it turns unloaded: where full duty's torque meets the friction."""
        room = self.stall_torque - self.frictionloss
        return max(room, 0.0) / (self.back_emf_damping + self.damping)

    def torque_at(self, speed: np.ndarray | float, duty: float | None = None) -> np.ndarray:
        """[N m] the motor's torque at ``speed`` [rad/s] and ``duty`` (default its largest), before
        friction: the torque-speed line kt / R (V duty - kt speed)."""
        d = self.max_duty if duty is None else duty
        return self.kt / self.resistance * (self.voltage * d - self.kt * np.asarray(speed, dtype=float))

    def pieces(self) -> ServoPieces:
        return ServoPieces(kp=self.gain, kv=0.0, torque=self.stall_torque, back_emf=self.back_emf_damping,
                           damping=self.damping, frictionloss=self.frictionloss, armature=self.armature,
                           target_speed=self.profile_speed or math.inf)

    def friction_term(self) -> np.ndarray | None:
        stribeck, load, directional, quadratic = FRICTION_MODELS[self.friction_model]
        if not (stribeck or load):
            return None
        u = np.zeros(FRICTION_WIDTH)
        u[_MAGIC] = FRICTION_MAGIC
        u[_FLAGS] = stribeck * 1 + load * 2 + directional * 4 + quadratic * 8
        u[_BASE], u[_STRIBECK], u[_STRIBECK_SPEED], u[_ALPHA] = (self.frictionloss, self.stribeck,
                                                                 self.stribeck_speed, self.stribeck_alpha)
        u[_LOAD], u[_LOAD_S] = self.load, self.load_stribeck
        u[_LOAD_M], u[_LOAD_E], u[_LOAD_MS], u[_LOAD_ES] = (self.load_motor, self.load_external,
                                                            self.load_motor_stribeck, self.load_external_stribeck)
        u[_LOAD_MQ], u[_LOAD_EQ] = self.load_motor_quad, self.load_external_quad
        u[_BACK_EMF] = self.back_emf_damping
        return u

    def with_friction_term(self, u: np.ndarray) -> "MotorServo":
        """The servo whose per-step friction term is ``u`` (:meth:`friction_term`'s numbers, an
        identification's): the BAM form its flags name, and every friction field from it (the
        back-EMF column is the motor's own and is not read)."""
        flags = int(u[_FLAGS])
        has = (bool(flags & 1), bool(flags & 2), bool(flags & 4), bool(flags & 8))
        form = next((k for k, v in FRICTION_MODELS.items() if v == has), None)
        if u[_MAGIC] != FRICTION_MAGIC or form is None:
            raise ValueError(f"not a friction term of BAM's forms (flags {flags})")
        return self.replace(friction_model=form, frictionloss=float(u[_BASE]), stribeck=float(u[_STRIBECK]),
                            stribeck_speed=float(u[_STRIBECK_SPEED]), stribeck_alpha=float(u[_ALPHA]),
                            load=float(u[_LOAD]), load_stribeck=float(u[_LOAD_S]), load_motor=float(u[_LOAD_M]),
                            load_external=float(u[_LOAD_E]), load_motor_stribeck=float(u[_LOAD_MS]),
                            load_external_stribeck=float(u[_LOAD_ES]), load_motor_quad=float(u[_LOAD_MQ]),
                            load_external_quad=float(u[_LOAD_EQ]))

    def with_datasheet(self, torque: float | None = None, speed: float | None = None) -> "MotorServo":
        """The servo whose stall torque [N m] and unloaded speed [rad/s] at its voltage and full duty
        are these (a datasheet's, a URDF's ``<limit effort velocity>``), friction included: kt / R
        from the torque, then kt from the speed where the torque left meets the friction. A figure
        not given keeps this servo's."""
        torque = self.stall_torque if torque is None else float(torque)
        speed = self.speed if speed is None else float(speed)
        vd = self.voltage * self.max_duty
        room = torque - self.frictionloss - self.damping * speed
        if not (torque > 0 and speed > 0 and room > 0):
            from ..errors import UserError
            raise UserError(f"stall torque {torque:g} N m and unloaded speed {speed:g} rad/s leave no room over the "
                            f"servo's friction ({self.frictionloss:g} N m + {self.damping:g} N m s/rad)")
        kt = room * vd / (torque * speed)
        return self.replace(kt=kt, resistance=kt * vd / torque)

    def with_pieces(self, *, kp: float | None = None, torque: float | None = None, back_emf: float | None = None,
                    **joint: float) -> "MotorServo":
        """The servo whose MuJoCo pieces are these (an identification's): the stall ``torque``
        [N m] and the back-EMF damping ``back_emf`` [N m s/rad] fix kt and R at this voltage
        (torque = kt V max_duty / R, back_emf = kt^2 / R), the position gain ``kp`` [N m/rad] the
        P register; ``joint`` sets the joint's own fields (damping, frictionloss, armature) as
        they are. A piece not given keeps this servo's."""
        torque = self.stall_torque if torque is None else float(torque)
        back_emf = self.back_emf_damping if back_emf is None else float(back_emf)
        kt = back_emf * self.voltage * self.max_duty / torque
        resistance = kt * kt / back_emf
        kp = self.gain if kp is None else float(kp)
        p_gain = kp * resistance / (kt * self.voltage * self.error_gain)
        return self.replace(kt=kt, resistance=resistance, p_gain=p_gain, **joint)

    def describe(self) -> str:
        name = f"{self.preset} " if self.preset else ""
        return (f"{name}dc-motor ({self.friction_model}) at {self.voltage:g} V, P {self.p_gain:g}: "
                f"kp {self.gain:.3g} N m/rad, {self.stall_torque:.3g} N m at rest, "
                f"{self.torque_at(5.0).item():.3g} at 5 rad/s, unloaded {self.speed:.3g} rad/s")


def friction_budget(u: np.ndarray, speed: np.ndarray | float, motor: np.ndarray | float,
                    external: np.ndarray | float) -> np.ndarray:
    """The dry-friction budget F [N m] of the per-step term (``MotorServo.friction_term``'s numbers
    ``u``) at a joint speed [rad/s], motor torque and external torque [N m]: the numpy reference of
    ``native_step.c`` (tested equal)."""
    speed, motor, external = (np.asarray(x, dtype=float) for x in (speed, motor, external))
    flags = int(u[_FLAGS])
    stribeck, load, directional, quadratic = bool(flags & 1), bool(flags & 2), bool(flags & 4), bool(flags & 8)
    s = np.exp(-np.abs(speed / u[_STRIBECK_SPEED]) ** u[_ALPHA]) if stribeck else 0.0
    f = u[_BASE] + (u[_STRIBECK] * s if stribeck else 0.0)
    if load:
        if directional:
            f = f + np.abs(external * u[_LOAD_E] - motor * u[_LOAD_M])
            if stribeck:
                f = f + s * np.abs(external * u[_LOAD_ES] - motor * u[_LOAD_MS])
            if quadratic:
                opposed = np.sign(external) != np.sign(motor)
                ext_smaller = np.abs(external) < np.abs(motor)
                ext_larger = np.abs(external) > np.abs(motor)
                quad = (ext_smaller * u[_LOAD_EQ] * external ** 2 + ext_larger * u[_LOAD_MQ] * motor ** 2)
                f = f + s * quad * opposed
        else:
            gearbox = np.abs(external - motor)
            f = f + u[_LOAD] * gearbox + (u[_LOAD_S] * gearbox * s if stribeck else 0.0)
    return np.asarray(f, dtype=float)
