"""Where the robot's loop takes its walk command from (ours): a function of time, a command stream
file, or a small UDP/JSON socket a team's behaviour (or a laptop on the field's network) sends to.

Each source is a callable ``source(t) -> (3,)`` array (vx [m/s], vy [m/s], wz [rad/s]), called
once per control tick, never blocking:

* :class:`Scripted`: ``fn(t)``, the team's own behaviour as a Python function.
* :class:`FromStream`: a command stream (``t,vx,vy,wz`` CSV, :func:`read_command_stream`), each
  row held until the next, a stop after the last.
* :class:`UdpCommands`: datagrams of one JSON object ``{"vx": .., "vy": .., "wz": ..}`` (missing
  keys are 0). It binds to the loopback (127.0.0.1) unless the team names another address on
  purpose; a datagram that is not such an object, or holds a number that is not finite, is
  counted (``rejected``) and ignored; when no good datagram has come for ``timeout`` seconds the
  command is a stop (a behaviour that died must not leave the robot walking).
"""

from __future__ import annotations

import json
import math
import socket
from pathlib import Path
from typing import Callable

import numpy as np

from ..command_stream import CommandStream, read_command_stream
from ..params import ParamError

__all__ = ["Scripted", "FromStream", "UdpCommands", "parse_udp_address"]

#: the keys a UDP command may hold
UDP_KEYS = ("vx", "vy", "wz")


class Scripted:
    """The command of a function of time ``fn(t)`` [s] -> (vx, vy, wz)."""

    def __init__(self, fn: Callable[[float], np.ndarray]) -> None:
        self.fn = fn

    def __call__(self, t: float) -> np.ndarray:
        return np.asarray(self.fn(t), dtype=float)

    def describe(self) -> str:
        return f"the function {getattr(self.fn, '__name__', 'fn')}(t)"


class FromStream:
    """The command of a stream (a file's rows, or a :class:`CommandStream`) at time ``t``; after
    its last row plus its tail, a stop. ``duration`` [s] is how long the stream walks."""

    def __init__(self, stream: CommandStream | str | Path) -> None:
        self.path = None if isinstance(stream, CommandStream) else str(stream)
        self.stream = stream if isinstance(stream, CommandStream) else read_command_stream(stream)
        self.duration = self.stream.duration

    def __call__(self, t: float) -> np.ndarray:
        return np.zeros(3) if t >= self.stream.duration else self.stream.at(t).copy()

    def describe(self) -> str:
        return f"the stream {self.path or '(in memory)'} ({self.stream.duration:g} s)"


def parse_udp_address(text: str) -> tuple[str, int]:
    """``PORT`` or ``HOST:PORT`` -> (host, port); the host defaults to the loopback. A mistake is
    a :class:`ParamError` naming it."""
    host, _, port = text.rpartition(":")
    host = host or "127.0.0.1"
    try:
        number = int(port)
    except ValueError:
        raise ParamError(f"--udp {text!r}: expected PORT or HOST:PORT (e.g. 5005 or 0.0.0.0:5005)") from None
    if not 1 <= number <= 65535:
        raise ParamError(f"--udp {text!r}: the port must be in [1, 65535]")
    return host, number


class UdpCommands:
    """Walk commands from UDP datagrams of JSON (module docstring). ``host`` 127.0.0.1 unless the
    team opens it on purpose; ``timeout`` [s] without a good datagram: a stop."""

    def __init__(self, host: str = "127.0.0.1", port: int = 5005, timeout: float = 0.5) -> None:
        if not (math.isfinite(timeout) and timeout > 0):
            raise ParamError(f"UDP command timeout = {timeout!r} s: expected a positive number of seconds")
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            raise ParamError(f"--udp {host}:{port}: cannot listen there ({exc.strerror or exc})") from None
        self.sock.setblocking(False)
        self.host, self.port = host, self.sock.getsockname()[1]
        self.timeout = float(timeout)
        self.command = np.zeros(3)
        self.received = self.rejected = 0
        self._last_t: float | None = None

    def _parse(self, data: bytes) -> np.ndarray | None:
        try:
            doc = json.loads(data.decode("utf-8"))
        except (UnicodeDecodeError, ValueError):
            return None
        if not isinstance(doc, dict) or set(doc) - set(UDP_KEYS):
            return None
        values = [doc.get(k, 0.0) for k in UDP_KEYS]
        if any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in values):
            return None
        return np.array(values, dtype=float)

    def __call__(self, t: float) -> np.ndarray:
        while True:                                 # drain: the newest good datagram wins
            try:
                data = self.sock.recv(2048)
            except BlockingIOError:
                break
            except OSError:
                break
            cmd = self._parse(data)
            if cmd is None:
                self.rejected += 1
                continue
            self.received += 1
            self.command, self._last_t = cmd, t
        if self._last_t is None or t - self._last_t > self.timeout:
            return np.zeros(3)
        return self.command.copy()

    def close(self) -> None:
        self.sock.close()

    def describe(self) -> str:
        return f"UDP/JSON on {self.host}:{self.port} (a stop {self.timeout:g} s after the last command)"
