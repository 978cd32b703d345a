"""The position servo of rounds one to four, kept by name (``law: pd``) for the papers' figures.

MuJoCo's position actuator, torque = clip(kp (q_cmd - q) - kv q', +-torque), the velocity term
inside the clamp, so at speed it keeps the stall torque; a cap on how fast the commanded target
may move (``speed``), applied every control tick; armature, damping and friction loss on the
joint. Real hobby servos lose torque with speed (``motor.py``); this law does not. Its presets
(``presets.yaml``, names ending ``-pd``) are the ones the papers' reproductions and the studies
of rounds one to four were tuned on. A robot file's own position actuator is read as this law.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .law import SHARED_RANGES, ServoLaw, ServoPieces, register

__all__ = ["PDServo"]


@register
@dataclass(frozen=True)
class PDServo(ServoLaw):
    """A position-controlled hobby servo as MuJoCo's position actuator (SI units)."""

    law: ClassVar[str] = "pd"
    RANGES: ClassVar = {"kp": (0.0, 1000.0, "N m/rad"), "kv": (0.0, 100.0, "N m s/rad"),
                        "torque": (0.0, 200.0, "N m"), "speed": (0.0, 100.0, "rad/s"),
                        "damping": (0.0, 100.0, "N m s/rad"), **SHARED_RANGES,
                        "frictionloss": (0.0, 100.0, "N m")}
    STRICT: ClassVar = ("kp", "torque", "speed")

    kp: float = 40.0            # [N m/rad] proportional gain
    kv: float = 0.5             # [N m s/rad] velocity feedback, inside the clamp
    torque: float = 6.0         # [N m] torque limit at any speed
    speed: float = 6.5          # [rad/s] speed limit of the commanded target
    armature: float = 0.008     # [kg m^2] reflected rotor inertia
    damping: float = 0.2        # [N m s/rad] gearbox viscous friction
    frictionloss: float = 0.03  # [N m] gearbox dry friction
    backlash: float = 0.0       # [rad] gearbox dead band, full width (identified; the presets state none)
    latency: float = 0.0        # [s] from a command to the servo acting on it (identified; one per robot)

    def pieces(self) -> ServoPieces:
        return ServoPieces(kp=self.kp, kv=self.kv, torque=self.torque, back_emf=0.0, damping=self.damping,
                           frictionloss=self.frictionloss, armature=self.armature, target_speed=self.speed)
