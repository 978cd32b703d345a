"""Match walks: command streams and pushes drawn from a stated distribution (ours).

A match asks a walk for a new command every second or two, stops it, turns it, and robots bump
into it. A :class:`MatchDistribution` states the distribution; :func:`draw_scenario` turns it and a seed into
one walk's command stream (``gaits.CommandStream``) and pushes, reproducibly (numpy's
``SeedSequence`` with the seed namespace of the randomisation, so tuning and evaluation never
share a walk). Each walk:

* starts standing, then segments of U(``segment_min``, ``segment_max``) seconds until
  ``duration``; each segment is a stop with probability ``stop``, else one direction drawn from
  forward, backward, left, right, turning either way (equally likely), or forward while turning
  with probability ``combined``, at U(0.3, 1) of that direction's top speed (``forward``,
  ``backward``, ``sideways`` [m/s], ``turn`` [rad/s]); then, when ``top_hold`` > 0, the top
  forward speed held that long (the walk a team asks for at the top of its range, and its stop);
  the walk ends with a stop of 2 s;
* pushes arrive as a Poisson process of ``push_rate`` per second after the first 2 s, each
  horizontal, in a random direction, of U(``push_min``, ``push_max``) [N s], on the torso over one
  control tick.

Scored (``tuner/search/objective.py``): survival, velocity tracking (``metrics.tracking``) and
torso pitch, under the study's randomisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaits import CommandStream
from gaits.params import fields_from_mapping

from ..errors import UserError

__all__ = ["MatchDistribution", "draw_scenario", "scenario_from_mapping", "SCENARIO_FIELDS"]

_RANGES = {"duration": (2.0, 600.0, "s"), "segment_min": (0.3, 30.0, "s"), "segment_max": (0.3, 60.0, "s"),
           "forward": (0.0, 2.0, "m/s"), "backward": (0.0, 2.0, "m/s"), "sideways": (0.0, 2.0, "m/s"),
           "turn": (0.0, 10.0, "rad/s"), "stop": (0.0, 1.0, "-"), "combined": (0.0, 1.0, "-"),
           "push_rate": (0.0, 5.0, "1/s"), "push_min": (0.0, 50.0, "N s"), "push_max": (0.0, 50.0, "N s"),
           "top_hold": (0.0, 60.0, "s")}


@dataclass(frozen=True)
class MatchDistribution:
    """The distribution of a match walk's commands and pushes (module docstring)."""

    duration: float = 12.0        # [s] commanded time before the final stop
    segment_min: float = 1.0      # [s]
    segment_max: float = 3.0      # [s]
    forward: float = 0.3          # [m/s] top forward speed drawn
    backward: float = 0.2         # [m/s]
    sideways: float = 0.1         # [m/s]
    turn: float = 1.0             # [rad/s]
    stop: float = 0.15            # [-] share of segments that stop
    combined: float = 0.2         # [-] share of the moving segments that walk forward while turning
    push_rate: float = 0.0        # [1/s] pushes per second (0: none)
    push_min: float = 0.5         # [N s]
    push_max: float = 1.5         # [N s]
    top_hold: float = 0.0         # [s] the top forward speed held this long after the drawn segments (0: not)

    def __post_init__(self) -> None:
        for name, (lo, hi, unit) in _RANGES.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
                raise UserError(f"{name} = {v!r}: expected a number in [{lo:g}, {hi:g}] {unit}")
            object.__setattr__(self, name, float(v))
        if self.segment_min > self.segment_max:
            raise UserError(f"segment_min = {self.segment_min:g} s exceeds segment_max = "
                            f"{self.segment_max:g} s")
        if self.push_min > self.push_max:
            raise UserError(f"push_min = {self.push_min:g} N s exceeds push_max = {self.push_max:g} N s")

    @property
    def length(self) -> float:
        """[s] a walk: the commanded time, the top speed's hold and its final 2 s stop."""
        return self.duration + self.top_hold + 2.0

    def to_mapping(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in _RANGES}


SCENARIO_FIELDS = tuple(_RANGES)


def scenario_from_mapping(doc: Any, source: str) -> MatchDistribution:
    if doc is None:
        return MatchDistribution()
    return fields_from_mapping(MatchDistribution, doc, source, SCENARIO_FIELDS, UserError)


def draw_scenario(s: MatchDistribution, seed: int | tuple[int, ...], namespace: int) -> tuple[CommandStream, list]:
    """One walk of the scenario: (command stream, pushes [(t [s], impulse (3,) [N s])])."""
    parts = seed if isinstance(seed, tuple) else (seed,)
    rng = np.random.default_rng(np.random.SeedSequence([int(namespace), 0x5CE7] + [int(v) for v in parts]))
    t, rows = 0.0, []
    units = {"forward": (s.forward, 0, 0), "backward": (-s.backward, 0, 0), "left": (0, s.sideways, 0),
             "right": (0, -s.sideways, 0), "turn_left": (0, 0, s.turn), "turn_right": (0, 0, -s.turn)}
    names = list(units)
    while t < s.duration - 1e-9:
        if rng.uniform() < s.stop:
            cmd = np.zeros(3)
        elif rng.uniform() < s.combined:
            cmd = np.array([s.forward * rng.uniform(0.3, 1.0), 0.0, s.turn * rng.uniform(0.3, 0.6) * rng.choice([-1, 1])])
        else:
            cmd = np.array(units[names[int(rng.integers(len(names)))]], dtype=float) * rng.uniform(0.3, 1.0)
        rows.append((t, cmd))
        t += float(rng.uniform(s.segment_min, s.segment_max))
    if s.top_hold > 0:                      # no random draw: the other fields' walks are as without it
        rows.append((s.duration, np.array([s.forward, 0.0, 0.0])))
    rows.append((s.duration + s.top_hold, np.zeros(3)))
    stream = CommandStream(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), tail=2.0)
    pushes = []
    if s.push_rate > 0 and s.push_max > 0:
        tp = 2.0
        while True:
            tp += float(rng.exponential(1.0 / s.push_rate))
            if tp >= s.duration:
                break
            size, ang = float(rng.uniform(s.push_min, s.push_max)), float(rng.uniform(0, 2 * math.pi))
            pushes.append((round(tp, 2), np.array([size * math.cos(ang), size * math.sin(ang), 0.0])))
    return stream, pushes
