"""Walk commands: a velocity (vx, vy, wz) per step, from rest and back to rest (ours).

None of the three papers takes a velocity command; they walk straight ahead with a
fixed step. A command sequence gives each step n its own (vx [m/s], vy [m/s], wz
[rad/s]) in the robot's heading frame; ``gaits/footstep_planner.py`` turns it into
footsteps and the generators (TLIPFM, cosine law) walk them.

:class:`CommandRamp` is the sequence a user means by "walk at this command": it
raises the command linearly from rest over ``ramp_steps`` steps, holds it for
``hold_steps`` steps, brings it back down over ``ramp_steps`` steps and ends with
one step of zero command, the step that sets the swing foot down beside the
support foot. The velocity of the walk is measured over the *steady window*: the
hold steps after ``settle_steps`` of them, a whole number of gait cycles (two
steps each) so that the sway of the torso averages out.

:class:`SpeedStaircase` is the speed test of a speed study: the command rises in
``levels`` equal stairs up to ``top``, each held for ``steps_per_level`` steps, so
that one rollout finds the highest command the robot still walks and tracks
(``tuner`` scores it). It is our variant of the published Optuna walk tuner's
search (Bestmann and Zhang, RoboCup 2022), which raises the command between
separate rollouts until the robot falls: one rollout per direction instead of one
per level, at the price that a level is reached with the state the previous level
left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import ParamError

__all__ = ["WalkCommand", "CommandRamp", "SpeedStaircase", "parse_command", "DIRECTIONS"]

#: Unit command of each direction a speed study scores: forward, backward, left, right,
#: turning left and right (a sideways or turning score is the same in both senses on a
#: symmetric robot, so studies usually score one of each).
DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "forward": (1.0, 0.0, 0.0),
    "backward": (-1.0, 0.0, 0.0),
    "left": (0.0, 1.0, 0.0),
    "right": (0.0, -1.0, 0.0),
    "turn_left": (0.0, 0.0, 1.0),
    "turn_right": (0.0, 0.0, -1.0),
}

_LIMIT_V = 2.0      # [m/s] no kid-size robot walks faster; beyond it a command is a typo
_LIMIT_W = 10.0     # [rad/s]


@dataclass(frozen=True)
class WalkCommand:
    """A walking velocity in the robot's heading frame."""

    vx: float = 0.0   # [m/s] forward positive
    vy: float = 0.0   # [m/s] left positive
    wz: float = 0.0   # [rad/s] counter-clockwise (turning left) positive

    def __post_init__(self) -> None:
        for name, lim, unit in (("vx", _LIMIT_V, "m/s"), ("vy", _LIMIT_V, "m/s"), ("wz", _LIMIT_W, "rad/s")):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ParamError(f"command {name} must be a finite number, got {v!r}")
            if abs(v) > lim:
                raise ParamError(f"command {name} = {v:g} {unit} is out of range [-{lim:g}, {lim:g}] {unit}")
            object.__setattr__(self, name, float(v))

    def as_array(self) -> np.ndarray:
        return np.array([self.vx, self.vy, self.wz])

    def __str__(self) -> str:
        return f"{self.vx:g},{self.vy:g},{self.wz:g}"


def parse_command(text: str) -> WalkCommand:
    """``"VX,VY,WZ"`` (m/s, m/s, rad/s) -> :class:`WalkCommand`; ParamError naming the problem."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 3:
        raise ParamError(f"command {text!r} must be three numbers VX,VY,WZ (m/s, m/s, rad/s), "
                         f"got {len(parts)} value(s)")
    values = []
    for name, part in zip(("vx", "vy", "wz"), parts):
        try:
            values.append(float(part))
        except ValueError:
            raise ParamError(f"command {name} = {part!r} is not a number") from None
    return WalkCommand(*values)


def _check_int(name: str, value: int, lo: int, hi: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ParamError(f"{name} = {value!r} is out of range [{lo}, {hi}] (an integer)")


@dataclass(frozen=True)
class CommandRamp:
    """Rest -> linear ramp -> hold -> linear ramp -> rest, one command per step."""

    target: WalkCommand
    ramp_steps: int = 4       # [steps] from rest to the target, and back
    hold_steps: int = 12      # [steps] at the target
    settle_steps: int = 2     # [steps] of the hold left out of the steady window

    def __post_init__(self) -> None:
        _check_int("ramp_steps", self.ramp_steps, 0, 100)
        _check_int("hold_steps", self.hold_steps, 2, 1000)
        _check_int("settle_steps", self.settle_steps, 0, self.hold_steps - 2)

    def fractions(self) -> np.ndarray:
        """Fraction of the target commanded at each step, shape (n_steps,)."""
        r = self.ramp_steps
        up = np.arange(1, r + 1) / (r + 1)
        return np.concatenate([up, np.ones(self.hold_steps), up[::-1], [0.0]])

    def per_step(self) -> np.ndarray:
        """Commands (vx, vy, wz) of every step, shape (n_steps, 3)."""
        return self.fractions()[:, None] * self.target.as_array()[None, :]

    def steady_steps(self) -> tuple[int, int]:
        """[first, last) step indices of the steady window: whole cycles of the hold."""
        first = self.ramp_steps + self.settle_steps
        n = self.hold_steps - self.settle_steps
        return first, first + 2 * (n // 2)


@dataclass(frozen=True)
class SpeedStaircase:
    """A staircase of commands along one direction, for the speed test of a study."""

    direction: str
    top: float                 # [m/s or rad/s] the last stair
    levels: int = 6            # stairs from top / levels to top
    steps_per_level: int = 4   # [steps] each stair is held (whole cycles)
    lead_steps: int = 2        # [steps] at the first stair before it counts

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise ParamError(f"direction {self.direction!r} is not one of {', '.join(DIRECTIONS)}")
        if isinstance(self.top, bool) or not isinstance(self.top, (int, float)) or not 0 < self.top <= 3.0:
            raise ParamError(f"top = {self.top!r} is out of range (0, 3] (m/s or rad/s)")
        _check_int("levels", self.levels, 1, 50)
        _check_int("steps_per_level", self.steps_per_level, 2, 40)
        if self.steps_per_level % 2:
            raise ParamError(f"steps_per_level = {self.steps_per_level} must be even (whole gait cycles)")
        _check_int("lead_steps", self.lead_steps, 0, 40)

    @property
    def unit(self) -> str:
        return "rad/s" if self.direction.startswith("turn") else "m/s"

    def level_values(self) -> np.ndarray:
        """The commanded speed of each stair (in the direction's unit), shape (levels,)."""
        return self.top * np.arange(1, self.levels + 1) / self.levels

    def per_step(self) -> np.ndarray:
        """Commands of every step: lead, stairs, then one stop step, shape (n_steps, 3)."""
        unit = np.array(DIRECTIONS[self.direction])
        speeds = np.concatenate([np.full(self.lead_steps, self.level_values()[0]),
                                 np.repeat(self.level_values(), self.steps_per_level), [0.0]])
        return speeds[:, None] * unit[None, :]

    def level_steps(self, level: int) -> tuple[int, int]:
        """[first, last) step indices of a stair."""
        first = self.lead_steps + level * self.steps_per_level
        return first, first + self.steps_per_level
