"""An IMU feedback stabiliser a servo controller can run every control tick (ours, not the papers').

The papers' gaits are open loop. This is the smallest closed loop a kid-size robot's
microcontroller runs: proportional-derivative corrections of the ankle and hip pitch/roll
targets from the torso's measured tilt and tilt rate, clipped, added to the gait's joint
targets of *both* legs. With torso pitch ``p`` (forward lean positive) and roll ``r`` (left
side up positive) [rad], their rates ``p'``, ``r'`` [rad/s] from the gyro::

    d_ankle_pitch = clip(k_ankle_pitch * p + d_ankle_pitch * p', +-limit)
    d_hip_pitch   = clip(k_hip_pitch   * p + d_hip_pitch   * p', +-limit)
    d_ankle_roll  = clip(k_ankle_roll  * r + d_ankle_roll  * r', +-limit)
    d_hip_roll    = clip(k_hip_roll    * r + d_hip_roll    * r', +-limit)

in gait-tuner's joint convention (positive ankle pitch presses the toes down, positive hip
pitch bends the torso forward over the legs; the roll joints likewise about x). A robot
tipping forward presses its toes down, moving the ZMP forward (the ankle strategy), and bends
at the hips with the tilt (the hip strategy: swinging the torso's mass makes the ground push
back against the fall). The hip sign is measured, not guessed: on the built-in robot standing
on the rigid floor, hip terms of the opposite sign (straightening the torso back) turned
0.5-1.0 N s pushes into 11-51 deg swings and falls; these signs damped them (``tests/
test_randomisation.py``). Port it by mapping the four corrections through your joints' signs
(``gait-tuner robot check`` lists them).
Off unless ``enabled``; the papers' open-loop comparisons never switch it on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .params import ParamError, fields_from_mapping

__all__ = ["StabiliserParams", "stabiliser_corrections", "stabiliser_from_mapping", "STABILISER_FIELDS"]

_RANGES = {"k_ankle_pitch": (0.0, 5.0, "rad/rad"), "d_ankle_pitch": (0.0, 1.0, "rad s/rad"),
           "k_hip_pitch": (0.0, 5.0, "rad/rad"), "d_hip_pitch": (0.0, 1.0, "rad s/rad"),
           "k_ankle_roll": (0.0, 5.0, "rad/rad"), "d_ankle_roll": (0.0, 1.0, "rad s/rad"),
           "k_hip_roll": (0.0, 5.0, "rad/rad"), "d_hip_roll": (0.0, 1.0, "rad s/rad"),
           "limit": (0.0, 0.5, "rad")}


@dataclass(frozen=True)
class StabiliserParams:
    """Gains and limit of the IMU stabiliser (see the module docstring for the formula)."""

    enabled: bool = False
    k_ankle_pitch: float = 0.0     # [rad/rad]
    d_ankle_pitch: float = 0.0     # [rad s/rad]
    k_hip_pitch: float = 0.0       # [rad/rad]
    d_hip_pitch: float = 0.0       # [rad s/rad]
    k_ankle_roll: float = 0.0      # [rad/rad]
    d_ankle_roll: float = 0.0      # [rad s/rad]
    k_hip_roll: float = 0.0        # [rad/rad]
    d_hip_roll: float = 0.0        # [rad s/rad]
    limit: float = 0.15            # [rad] largest correction of any joint

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ParamError(f"stabiliser.enabled = {self.enabled!r}: expected true or false")
        for name, (lo, hi, unit) in _RANGES.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
                raise ParamError(f"stabiliser.{name} = {v!r} is out of range [{lo:g}, {hi:g}] {unit}")
            object.__setattr__(self, name, float(v))

    def to_mapping(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


STABILISER_FIELDS = tuple(f.name for f in fields(StabiliserParams))


def stabiliser_from_mapping(doc: Any, source: str = "stabiliser") -> StabiliserParams:
    """A validated stabiliser from a YAML mapping (missing fields take their defaults)."""
    return fields_from_mapping(StabiliserParams, doc, source, STABILISER_FIELDS)


def stabiliser_corrections(p: StabiliserParams, pitch: float, roll: float, pitch_rate: float,
                           roll_rate: float) -> np.ndarray:
    """(d_ankle_pitch, d_hip_pitch, d_ankle_roll, d_hip_roll) [rad], gait-tuner's joint convention."""
    if not p.enabled:
        return np.zeros(4)
    lim = p.limit
    return np.array([
        min(max(p.k_ankle_pitch * pitch + p.d_ankle_pitch * pitch_rate, -lim), lim),
        min(max(p.k_hip_pitch * pitch + p.d_hip_pitch * pitch_rate, -lim), lim),
        min(max(p.k_ankle_roll * roll + p.d_ankle_roll * roll_rate, -lim), lim),
        min(max(p.k_hip_roll * roll + p.d_hip_roll * roll_rate, -lim), lim)])
