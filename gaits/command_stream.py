"""A stream of walk commands over time, as a robot's behaviour sends them (ours).

Rows (t [s], vx [m/s], vy [m/s], wz [rad/s]): each row's command holds from its t until the next
row's t; the walk lasts until the last row's t plus ``tail`` (2 s unless a file says otherwise).
The first row must be at t = 0. A stream file is CSV with the header ``t,vx,vy,wz``
(:func:`read_command_stream` reads it).

An online controller reads the stream tick by tick (:meth:`CommandStream.at`) and knows nothing
of the rows to come. A joint table can only be planned per step, before the walk:
:meth:`CommandStream.per_step` gives each step the command of its start time, which is what an
open-loop set walks for a stream (and why its CoM already knows the next steps' commands).
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .files import MAX_BYTES, read_bytes_checked
from .params import ParamError
from .walk_command import WalkCommand

__all__ = ["CommandStream", "read_command_stream", "MAX_STREAM_BYTES"]

MAX_ROWS = 100_000
MAX_T = 600.0               # [s] the last row's t at most (a RoboCup half is ten minutes; the tail adds)


@dataclass(frozen=True)
class CommandStream:
    """Piecewise-constant walk commands: ``t`` (n,) [s] increasing from 0, ``commands`` (n, 3)."""

    t: np.ndarray
    commands: np.ndarray
    tail: float = 2.0           # [s] walked after the last row's t

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        c = np.asarray(self.commands, dtype=float)
        if t.ndim != 1 or len(t) < 1 or len(t) > MAX_ROWS:
            raise ParamError(f"a command stream needs 1 to {MAX_ROWS} rows, got {t.shape}")
        if c.shape != (len(t), 3):
            raise ParamError(f"a command stream's commands must have shape ({len(t)}, 3), got {c.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(c))):
            bad = int(np.flatnonzero(~(np.isfinite(t) & np.all(np.isfinite(c), axis=1)))[0])
            raise ParamError(f"command stream row {bad + 1}: values must be finite numbers")
        if t[0] != 0.0:
            raise ParamError(f"command stream row 1: t = {t[0]:g} s; the first row must be at t = 0")
        steps = np.diff(t)
        if np.any(steps <= 0):
            bad = int(np.flatnonzero(steps <= 0)[0]) + 2
            raise ParamError(f"command stream row {bad}: t = {t[bad - 1]:g} s does not come after "
                             f"the previous row's {t[bad - 2]:g} s")
        if t[-1] > MAX_T:
            bad = int(np.flatnonzero(t > MAX_T)[0]) + 1
            raise ParamError(f"command stream row {bad}: t = {t[bad - 1]:g} s is beyond {MAX_T:g} s (a stream's "
                             f"rows lie within ten minutes, a RoboCup half)")
        for i, row in enumerate(c):
            try:
                WalkCommand(*row)
            except ParamError as exc:
                raise ParamError(f"command stream row {i + 1}: {exc}") from None
        if isinstance(self.tail, bool) or not (0.0 <= float(self.tail) <= 600.0) or math.isnan(self.tail):
            raise ParamError(f"command stream tail = {self.tail!r} s is out of range [0, 600] s")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "commands", c)
        object.__setattr__(self, "tail", float(self.tail))

    @classmethod
    def constant(cls, command, duration: float) -> "CommandStream":
        """One command held for ``duration`` [s], then a stop held for 2 s."""
        cmd = np.asarray(command.as_array() if isinstance(command, WalkCommand) else command, dtype=float)
        return cls(np.array([0.0, float(duration)]), np.vstack([cmd, np.zeros(3)]))

    @property
    def duration(self) -> float:
        """[s] the whole walk: the last row's t plus the tail."""
        return float(self.t[-1] + self.tail)

    def at(self, time: float) -> np.ndarray:
        """The command (vx, vy, wz) that holds at ``time`` [s], shape (3,)."""
        i = int(np.searchsorted(self.t, time + 1e-9, side="right")) - 1
        return self.commands[max(i, 0)]

    def segments(self) -> list[tuple[float, float, np.ndarray]]:
        """(start [s], end [s], command) of every row; the last ends with the walk."""
        ends = np.append(self.t[1:], self.duration)
        return [(float(a), float(b), self.commands[i]) for i, (a, b) in enumerate(zip(self.t, ends))]

    def per_step(self, step_starts: np.ndarray) -> np.ndarray:
        """The command of each step's start time (n, 3), for a walk planned before it starts."""
        return np.array([self.at(float(s)) for s in step_starts])

    def rows_not_walked(self, step_starts: np.ndarray) -> list[int]:
        """The rows no step starts in (a row shorter than a step, between two starts): a walk
        planned per step (:meth:`per_step`) never walks their command."""
        starts = np.asarray(step_starts, dtype=float)
        ends = np.append(self.t[1:], self.duration)
        return [i for i, (a, b) in enumerate(zip(self.t, ends))
                if not np.any((starts >= a - 1e-12) & (starts < b - 1e-12))]


#: a 10-minute stream at 100 Hz is ~2 MB
MAX_STREAM_BYTES = MAX_BYTES["csv"]
STREAM_HEADER = ["t", "vx", "vy", "wz"]


def read_command_stream(path: str | Path, tail: float | None = None, error: type[Exception] = ParamError) -> CommandStream:
    """A command stream file (CSV with the header ``t,vx,vy,wz``; ``#`` comments; a UTF-8 byte-order
    mark skipped) read and checked; every way it can be wrong is one ``error`` naming the file and
    the line. ``tail`` [s]: walked after the last row (default 2)."""
    path = Path(path)
    raw = read_bytes_checked(path, "command stream", MAX_STREAM_BYTES, error)
    try:
        text = raw.decode("utf-8-sig")          # a spreadsheet's byte-order mark is not part of the header
    except UnicodeDecodeError as exc:
        raise error(f"{path}: is not UTF-8 text (byte {exc.start})") from None
    reader = csv.reader(io.StringIO(text))
    try:
        rows = [(i + 1, r) for i, r in enumerate(reader)
                if r and not r[0].lstrip().startswith("#") and any(c.strip() for c in r)]
    except csv.Error as exc:                # a cell past the csv module's limit, a stray quote
        raise error(f"{path}: line {reader.line_num}: not CSV a stream can hold ({exc})") from None
    if not rows:
        raise error(f"{path}: empty; a command stream is CSV with the header t,vx,vy,wz")
    line, head = rows[0]
    if [c.strip() for c in head] != STREAM_HEADER:
        raise error(f"{path}: line {line}: the header must be t,vx,vy,wz, got {','.join(head)!r}")
    t, cmds = [], []
    for line, r in rows[1:]:
        if len(r) != 4:
            raise error(f"{path}: line {line}: expected 4 values t,vx,vy,wz, got {len(r)}")
        try:
            vals = [float(c) for c in r]
        except ValueError:
            raise error(f"{path}: line {line}: {','.join(r)!r} is not four numbers") from None
        t.append(vals[0])
        cmds.append(vals[1:])
    if not t:
        raise error(f"{path}: the header has no rows below it")
    try:
        return CommandStream(t, cmds, tail=2.0 if tail is None else tail)
    except ParamError as exc:
        raise error(f"{path}: {exc}") from None
