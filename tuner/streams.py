"""Reading a command stream file: CSV with the header ``t,vx,vy,wz`` (``gaits.CommandStream``).

``t`` in seconds from the start, ``vx``, ``vy`` in m/s, ``wz`` in rad/s; each row's command holds
until the next row's t, and the walk lasts until the last row's t plus ``tail`` (the caller's
``--duration``, or 2 s); the rows lie within 600 s. Lines starting with ``#`` are comments; a
UTF-8 byte-order mark (as spreadsheets write) is skipped. Every way a file can be wrong is
one :class:`UserError` naming the file and the row. The reader itself is the robot side's
(``gaits/command_stream.py``: the loop walks stream files too).
"""

from __future__ import annotations

from pathlib import Path

from gaits import CommandStream
from gaits.command_stream import MAX_STREAM_BYTES, read_command_stream

from .errors import UserError

__all__ = ["load_stream", "MAX_STREAM_BYTES"]


def load_stream(path: str | Path, tail: float | None = None) -> CommandStream:
    """``gaits.command_stream.read_command_stream`` with its mistakes as :class:`UserError`."""
    return read_command_stream(path, tail, UserError)
