"""Reading a command stream file: CSV with the header ``t,vx,vy,wz`` (``gaits.CommandStream``).

``t`` in seconds from the start, ``vx``, ``vy`` in m/s, ``wz`` in rad/s; each row's command holds
until the next row's t, and the walk lasts until the last row's t plus ``tail`` (the caller's
``--duration``, or 2 s); the rows lie within 600 s. Lines starting with ``#`` are comments; a
UTF-8 byte-order mark (as spreadsheets write) is skipped. Every way a file can be wrong is
one :class:`UserError` naming the file and the row.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from gaits import CommandStream, ParamError
from gaits.files import MAX_BYTES, read_bytes_checked

from .errors import UserError

__all__ = ["load_stream", "MAX_STREAM_BYTES"]

MAX_STREAM_BYTES = MAX_BYTES["csv"]   # a 10-minute stream at 100 Hz is ~2 MB
HEADER = ["t", "vx", "vy", "wz"]


def load_stream(path: str | Path, tail: float | None = None) -> CommandStream:
    path = Path(path)
    raw = read_bytes_checked(path, "command stream", MAX_STREAM_BYTES, UserError)
    try:
        text = raw.decode("utf-8-sig")          # a spreadsheet's byte-order mark is not part of the header
    except UnicodeDecodeError as exc:
        raise UserError(f"{path}: is not UTF-8 text (byte {exc.start})") from None
    reader = csv.reader(io.StringIO(text))
    try:
        rows = [(i + 1, r) for i, r in enumerate(reader)
                if r and not r[0].lstrip().startswith("#") and any(c.strip() for c in r)]
    except csv.Error as exc:                # a cell past the csv module's limit, a stray quote
        raise UserError(f"{path}: line {reader.line_num}: not CSV a stream can hold ({exc})") from None
    if not rows:
        raise UserError(f"{path}: empty; a command stream is CSV with the header t,vx,vy,wz")
    line, head = rows[0]
    if [c.strip() for c in head] != HEADER:
        raise UserError(f"{path}: line {line}: the header must be t,vx,vy,wz, got {','.join(head)!r}")
    t, cmds = [], []
    for line, r in rows[1:]:
        if len(r) != 4:
            raise UserError(f"{path}: line {line}: expected 4 values t,vx,vy,wz, got {len(r)}")
        try:
            vals = [float(c) for c in r]
        except ValueError:
            raise UserError(f"{path}: line {line}: {','.join(r)!r} is not four numbers") from None
        t.append(vals[0])
        cmds.append(vals[1:])
    if not t:
        raise UserError(f"{path}: the header has no rows below it")
    try:
        return CommandStream(t, cmds, tail=2.0 if tail is None else tail)
    except ParamError as exc:
        raise UserError(f"{path}: {exc}") from None
