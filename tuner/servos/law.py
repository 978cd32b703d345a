"""What every servo law gives the simulator, and the registry of laws.

A servo law is a frozen dataclass (SI units inside; each field with a default, a unit and a range)
that turns its parameters into MuJoCo's own pieces (:class:`ServoPieces`): a position actuator
(a gain and a velocity gain inside a torque clamp), a damping outside the clamp on the actuator
(the motor's back-EMF), the joint's viscous and dry friction and its armature, and a cap on how
fast the commanded target may move. A law that needs a term MuJoCo has no piece for (friction that
depends on speed or load) returns it from :meth:`ServoLaw.friction_term`; the simulator runs it
inside every physics step (``tuner/sim/native_step.c``).

Every law also answers the planners' questions in the same words: ``kp`` [N m/rad] (the position
gain at small errors), ``kv`` [N m s/rad], ``torque`` [N m] (the most it gives at rest),
``speed`` [rad/s] (the fastest it turns unloaded), ``armature``, ``damping``, ``frictionloss``,
``backlash`` [rad] and ``latency`` [s].

A new law is one file with one class and one :func:`register` call (``tuner/servos/__init__.py``
imports the built-in ones: ``pd.py``, ``motor.py``).
"""

from __future__ import annotations

import abc
import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

import numpy as np

from ..errors import UserError

__all__ = ["ServoPieces", "ServoLaw", "LAWS", "register", "configure", "SHARED_RANGES"]

#: the ranges of the fields every law has (each law's ``RANGES`` adds its own)
SHARED_RANGES = {"armature": (0.0, 1.0, "kg m^2"), "frictionloss": (0.0, 20.0, "N m"),
                 "backlash": (0.0, 0.2, "rad"), "latency": (0.0, 0.2, "s")}


@dataclass(frozen=True)
class ServoPieces:
    """A servo as MuJoCo's pieces (SI units; see the module docstring)."""

    kp: float                 # [N m/rad] position gain inside the clamp
    kv: float                 # [N m s/rad] velocity gain inside the clamp
    torque: float             # [N m] the clamp
    back_emf: float           # [N m s/rad] damping on the actuator, outside the clamp
    damping: float            # [N m s/rad] joint viscous friction
    frictionloss: float       # [N m] joint dry friction (the base of a friction term's budget)
    armature: float           # [kg m^2] reflected rotor and gear inertia
    target_speed: float       # [rad/s] cap on how fast the commanded target moves (inf: none)


class ServoLaw(abc.ABC):
    """Base of the servo laws: validation of the fields against ``RANGES``, and the shared words.

    A subclass is a frozen dataclass with a class attribute ``law`` (its registered name),
    ``RANGES`` {field: (low, high, unit)} for every numeric field (``STRICT`` names those whose low
    end is excluded) and implements :meth:`pieces`."""

    law: ClassVar[str] = ""
    RANGES: ClassVar[Mapping[str, tuple[float, float, str]]] = {}
    STRICT: ClassVar[tuple[str, ...]] = ()
    #: fields a map may not set (derived, or bookkeeping)
    FIXED: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name not in self.RANGES:
                continue
            value = getattr(self, f.name)
            lo, hi, unit = self.RANGES[f.name]
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise UserError(f"servo.{f.name} = {value!r}: expected a number in [{lo:g}, {hi:g}] {unit}")
            v = float(value)
            strict = f.name in self.STRICT
            if not math.isfinite(v) or (v <= lo if strict else v < lo) or v > hi:
                raise UserError(f"servo.{f.name} = {value!r} {unit} is out of range "
                                f"{'(' if strict else '['}{lo:g}, {hi:g}] {unit}")
            object.__setattr__(self, f.name, v)

    # --- what every law answers -------------------------------------------------------------
    @abc.abstractmethod
    def pieces(self) -> ServoPieces:
        """The servo as MuJoCo's pieces."""

    def friction_term(self) -> np.ndarray | None:
        """The per-step friction term's parameters (``native_step.FRICTION_WIDTH`` numbers), or
        None when the joint's constant friction loss and damping are the whole friction."""
        return None

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def settable(cls) -> tuple[str, ...]:
        return tuple(f for f in cls.fields() if f not in cls.FIXED)

    def replace(self, **changes: Any) -> "ServoLaw":
        unknown = [k for k in changes if k not in self.fields()]
        if unknown:
            raise UserError(f"servo.{unknown[0]}: not a field of the {self.law} law "
                            f"(its fields: {', '.join(self.settable())})")
        return dataclasses.replace(self, **changes)

    def to_mapping(self) -> dict[str, Any]:
        """The servo as a map's ``servo:`` entry (every field, the law named)."""
        out: dict[str, Any] = {"law": self.law}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            out[f.name] = float(f"{v:.6g}") if isinstance(v, float) else v
        return out

    def describe(self) -> str:
        """One line: the law and what it gives (gain, clamp, speed)."""
        p = self.pieces()
        return (f"{self.law}: kp {p.kp:.3g} N m/rad, {p.torque:.3g} N m at rest, unloaded "
                f"{self.speed:.3g} rad/s")

    @property
    def kp(self) -> float:
        return self.pieces().kp

    @property
    def kv(self) -> float:
        return self.pieces().kv

    @property
    def torque(self) -> float:
        return self.pieces().torque

    @property
    def back_emf(self) -> float:
        return self.pieces().back_emf

    @property
    def target_speed(self) -> float:
        return self.pieces().target_speed


#: registered laws by name
LAWS: dict[str, type[ServoLaw]] = {}


def register(cls: type[ServoLaw]) -> type[ServoLaw]:
    """Register a servo law class under its ``law`` name (once)."""
    if not cls.law or cls.law in LAWS:
        raise ValueError(f"servo law name {cls.law!r} is empty or taken")
    LAWS[cls.law] = cls
    return cls


#: [N m] the least friction loss a joint with a per-step friction term keeps in the model: MuJoCo makes
#: a joint's friction-loss constraint row only when it is positive, and the term bounds that row
FRICTION_ROW_MIN = 1e-9


def configure(spec: Any, joint: Any, actuator: Any, servo: ServoLaw) -> bool:
    """Give an MjSpec joint and its (new, joint-transmission) actuator the servo's pieces: the one
    place a servo law reaches MuJoCo. A per-step friction term goes into the actuator's user
    numbers (``spec`` widened to hold them). Returns whether the servo has such a term (its model
    then needs the native step, ``tuner/sim/native_step.py``)."""
    p = servo.pieces()
    joint.armature = p.armature
    joint.damping = [p.damping, 0.0, 0.0]
    joint.frictionloss = p.frictionloss
    actuator.set_to_position(kp=p.kp, kv=p.kv)
    actuator.forcelimited = 1
    actuator.forcerange = [-p.torque, p.torque]
    actuator.damping = [p.back_emf, 0.0, 0.0]
    term = servo.friction_term()
    if term is None:
        return False
    joint.frictionloss = max(p.frictionloss, FRICTION_ROW_MIN)
    if 0 <= spec.nuser_actuator < len(term):
        spec.nuser_actuator = len(term)
    actuator.userdata = [float(x) for x in term]
    return True
