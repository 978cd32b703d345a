"""Online commands for every family: the family's own table, re-planned at each step from the
commands walked so far and the current one (ours).

EROS and the cosine law have no state feedback of their own; what an online engine asks of them is
that a command changed at any tick reaches the next step and that nothing of the future is known.
Their generators are causal (a command of step k first changes the table inside step k: measured
0.16 s into it for EROS), so at each step start :class:`OnlineTable` plans the family's table for
the commands walked so far, the current command for this step and ``preview`` more, and a stop,
and plays on from the same tick: the targets up to the step start are those already sent. The
command is read at each step start (a change inside a step waits for the next), rate-limited by
nothing but the family's step limits (a step beyond them is clipped to the envelope, like the
engine). With a zero command at a step start and ``idle`` "stand" the planned walk ends there and
the robot comes to stand; a later command starts a new walk from standing (with the family's own
start-up).

The cost: each re-plan generates the whole walk so far (EROS: tens of ms for a few dozen steps), at
step starts only; TLIPFM uses the walk engine (``gaits/engine/``) instead.
"""

from __future__ import annotations

import numpy as np

from .control import Measurement, PlanRecord, StartPose, TablePlayer
from .families import family_of
from .footstep_planner import PlanError
from .leg_kinematics import UnreachableTargetError

__all__ = ["OnlineTable"]


class OnlineTable:
    """A family's table walked online (module docstring)."""

    senses: frozenset[str] = frozenset()

    def __init__(self, params, robot, dt: float, limits, *, preview: int = 2, idle: str = "stand") -> None:
        self.params, self.robot, self.dt, self.limits = params, robot, float(dt), limits
        self.fam = family_of(params)
        self.preview = preview
        self.idle = idle
        self.duration = None
        self.walk_start = float(self.fam.step_starts(params, 1)[0])
        self.replans = 0
        self.step_starts: list[float] = []
        self._origin = 0.0

    def _envelope(self, c: np.ndarray) -> np.ndarray:
        T = self.fam.step_period(self.params)
        lim = self.limits
        axes = self.fam.command_axes
        return np.array([min(max(c[0], -lim.max_backward / T), lim.max_forward / T) if axes[0] else 0.0,
                         min(max(c[1], -lim.max_outward / (2 * T)), lim.max_outward / (2 * T)) if axes[1] else 0.0,
                         min(max(c[2], -lim.max_turn / (2 * T)), lim.max_turn / (2 * T)) if axes[2] else 0.0])

    def _plan(self, commands: list[np.ndarray], current: np.ndarray) -> None:
        ahead = [] if (not np.any(current) and self.idle == "stand") else [current] * self.preview
        rows = commands + ahead + [np.zeros(3)]
        if len(rows) < 2:                            # the cosine law's walk is a starting and an ending motion
            rows = [np.zeros(3)] + rows
        rows = np.array(rows, dtype=float)
        scale = 1.0
        while True:
            try:
                self.table = self.fam.walk(self.params, self.robot, self.dt, rows * scale)
                break
            except (PlanError, UnreachableTargetError):
                if scale < 0.05:                    # not even a crawl plans: stand where it is
                    self.table = self.fam.walk(self.params, self.robot, self.dt, np.zeros((1, 3)))
                    break
                scale *= 0.7                         # a command the family cannot walk: less of it
        self.player = TablePlayer(self.table)
        self.starts = self.fam.step_starts(self.params, len(rows))
        self.replans += 1

    def start_pose(self) -> StartPose:
        self._plan([], np.zeros(3))
        return self.player.start_pose()

    def reset(self, m: Measurement) -> None:
        self.commands: list[np.ndarray] = []
        self._plan([], np.zeros(3))
        self._walking = False
        self._stopping = False
        self._origin = 0.0                            # when the current walk's table starts
        self._k = 0                                   # the next step of the walk

    def step(self, m: Measurement, command: np.ndarray | None = None) -> np.ndarray:
        c = self._envelope(np.zeros(3) if command is None else np.asarray(command, dtype=float))
        if not self._walking:
            if not np.any(c) and self.idle == "stand":
                return self.table.q_ref[0]            # standing, waiting for a command
            self._walking, self._origin, self._k, self.commands, self._stopping = True, m.t, 0, [], False
            self._plan([], c)
        t_table = m.t - self._origin
        if self._k < len(self.starts) - 1 and t_table >= self.starts[self._k] - 1e-9:
            stop = not np.any(c) and self.idle == "stand"
            if not (stop and self._stopping):          # a stop is planned once: the walk then ends
                self.commands.append(c)
                self.step_starts.append(self._origin + float(self.starts[self._k]))
                self._plan(self.commands, c)
            self._stopping = stop
            self._k += 1
        i = int(round(t_table / self.dt)) + 1
        if i >= len(self.table.t) - 1:                # the planned walk has ended: stand
            self._walking = False
            return self.table.q_ref[-1]
        return self.table.q_ref[i]

    def plan(self, n: int) -> PlanRecord:
        """The last table's plan, shifted to the current walk's start (what was planned per tick)."""
        rec = self.player.plan(n)
        shift = int(round(self._origin / self.dt))
        if shift:
            for name in ("support", "p_world_zmp_ref", "p_world_foot_l", "p_world_foot_r"):
                a = getattr(rec, name)
                setattr(rec, name, np.concatenate([np.repeat(a[:1], shift, axis=0), a])[:n])
        rec.walk_start += self._origin
        rec.meta["step_starts"] = list(self.step_starts)
        rec.meta["replans"] = self.replans
        return rec
