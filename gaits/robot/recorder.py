"""Recordings of what a robot did, in the layout the RoboCup community proposes (ours, read from the
HumanoidDataset proposal's description: one MCAP file per robot run, a metadata record saying
which robot, joints and task, simulated or not, and time-stamped channels).

A recording is written by whoever runs a controller, on the robot or in the simulator, through
:class:`RecordingController` (a controller wrapped so that every tick's :class:`Measurement`, walk
command and returned targets are recorded: what the controller saw and asked, not the simulator's
ground truth). Channels (JSON messages with a JSON schema; time in each message's ``log_time``,
nanoseconds, and ``t`` [s] since the start; SI units, gait-tuner's joint names and signs):

=====================  ====================================================================
``/time``              ``unix_ms``: the wall clock's UNIX time [ms] of the tick (the proposal's)
``/imu/gyro``          ``x, y, z`` [rad/s] body rates
``/imu/accel``         ``x, y, z`` [m/s^2] specific force (gravity included)
``/imu/orientation``   ``roll, pitch, yaw`` [rad]
``/joints/measured``   ``position`` [rad] and ``velocity`` [rad/s] per joint (the metadata's ``joints``)
``/joints/target``     ``position`` [rad] per joint: what the controller asked for the next tick (the
                       metadata's ``target_joints``, or its ``joints`` when it names none: a
                       controller asks all 20 roles of a robot whose encoders read fewer)
``/feet/force``        ``force`` [N], the eight sole readings (``gaits.control.FOOT_FORCE_LABELS``)
``/walk/command``      ``vx, vy`` [m/s], ``wz`` [rad/s]
=====================  ====================================================================

Every reading the robot has is recorded, whatever the controller uses (a joint table uses none);
a reading the robot lacks is not recorded; a missing command is none. Writing needs the ``mcap`` package (``pip install mcap``), as reading does; the rest of the
robot side needs numpy and PyYAML only. A run that is killed keeps what was flushed: MCAP's
chunks are written as they fill.
"""

from __future__ import annotations

import json
import os
import math
import time
import dataclasses
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..files import make_folder
from ..control import FOOT_FORCE_LABELS, READINGS, Measurement, Wrapped
from ..trajectory import JOINT_NAMES

__all__ = ["RecordingMeta", "Recorder", "RecordingController", "Recording", "read_recording", "recording_info",
           "CHANNELS", "METADATA_NAME"]

#: the metadata record's name in the MCAP file
METADATA_NAME = "humanoid_dataset"
#: channel -> (schema title, JSON schema properties)
CHANNELS = {
    "/time": ("UnixTime", {"unix_ms": "number"}),
    "/imu/gyro": ("Vector3", {"x": "number", "y": "number", "z": "number"}),
    "/imu/accel": ("Vector3", {"x": "number", "y": "number", "z": "number"}),
    "/imu/orientation": ("RollPitchYaw", {"roll": "number", "pitch": "number", "yaw": "number"}),
    "/joints/measured": ("JointState", {"position": "array", "velocity": "array"}),
    "/joints/target": ("JointTarget", {"position": "array"}),
    "/feet/force": ("FootForce", {"force": "array"}),
    "/walk/command": ("WalkCommand", {"vx": "number", "vy": "number", "wz": "number"}),
}


@dataclass
class RecordingMeta:
    """What a recording is of (the proposal's metadata: robot, joints, task, simulated or not)."""

    robot: str                                   # the robot's name
    task: str = "walk"                           # the primary task: walk, match, push-recovery, sweep, ...
    simulated: bool = True
    maker: str = ""
    model: str = ""
    joints: list[str] = field(default_factory=lambda: list(JOINT_NAMES))
    target_joints: list[str] = field(default_factory=list)    # /joints/target's columns (empty: as joints)
    foot_force: list[str] = field(default_factory=lambda: list(FOOT_FORCE_LABELS))
    controller: str = ""                         # what drove the joints
    parameters: dict = field(default_factory=dict)    # its parameters
    surface: str = ""
    location: str = ""
    notes: str = ""

    def to_strings(self) -> dict[str, str]:
        """MCAP metadata holds strings: lists and mappings as JSON."""
        return {k: (v if isinstance(v, str) else json.dumps(v)) for k, v in asdict(self).items()}

    @classmethod
    def from_strings(cls, d: dict[str, str]) -> "RecordingMeta":
        """The metadata read back (text fields as they are, the others from JSON; unknown keys kept
        out); a missing robot name or a field that does not parse is a ValueError."""
        fields_ = cls.__dataclass_fields__
        out = {k: (v if fields_[k].type == "str" else json.loads(v)) for k, v in d.items() if k in fields_}
        if "robot" not in out:
            raise ValueError("its metadata names no robot")
        for k in ("joints", "foot_force"):
            if k in out and (not isinstance(out[k], list) or not all(isinstance(x, str) for x in out[k])):
                raise ValueError(f"{k} = {str(out[k])[:60]}: expected a list of names")
        if "simulated" in out and not isinstance(out["simulated"], bool):
            raise ValueError(f"simulated = {out['simulated']!r}: expected true or false")
        params = out.get("parameters", {})
        if not isinstance(params, dict):
            raise ValueError(f"parameters = {str(params)[:60]}: expected a mapping of names to values")
        bad = [k for k, v in params.items() if isinstance(v, float) and not math.isfinite(v)]
        if bad:
            raise ValueError(f"parameters.{bad[0]} = {params[bad[0]]}: expected a finite number")
        return cls(**out)


def _mcap():
    try:
        from mcap.writer import CompressionType, Writer
    except ImportError:
        raise ImportError("recordings need the mcap package: pip install mcap") from None
    return Writer, CompressionType


def _list(v: Any) -> list[float]:
    return [float(x) for x in np.asarray(v, dtype=float).ravel()]


def partial_path(path: str | Path) -> Path:
    """Where a recording is written until it is whole: ``NAME.partial.mcap`` beside ``NAME.mcap``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.partial{path.suffix}")


class Recorder:
    """Writes one recording (an MCAP file). ``start_ns``: the wall clock of t = 0 [ns since the
    UNIX epoch] (default: now). Whole or not at all: it is written to :func:`partial_path` and put
    in place when it closes; a run killed, or a disk that fills, leaves any older recording of the
    name as it was and what was recorded readable in the partial file (``read_recording`` reads one
    cut short)."""

    def __init__(self, path: str | Path, meta: RecordingMeta, start_ns: int | None = None) -> None:
        Writer, Compression = _mcap()
        self.path = Path(path)
        self.partial = partial_path(self.path)
        make_folder(self.path.parent)
        self._fh = open(self.partial, "wb")
        # small chunks (~0.3 s of a 100 Hz walk): a run killed mid-way loses at most the last one
        self._w = Writer(self._fh, compression=Compression.ZSTD, chunk_size=32 * 1024)
        self._w.start(profile="", library="gait-tuner")
        self._w.add_metadata(METADATA_NAME, meta.to_strings())
        self._ids = {}
        for topic, (title, props) in CHANNELS.items():
            schema = {"title": title, "type": "object",
                      "properties": {"t": {"type": "number"},
                                     **{k: ({"type": "array", "items": {"type": "number"}} if t == "array"
                                            else {"type": t}) for k, t in props.items()}}}
            sid = self._w.register_schema(title, "jsonschema", json.dumps(schema).encode())
            self._ids[topic] = self._w.register_channel(topic, "json", sid)
        self.start_ns = time.time_ns() if start_ns is None else int(start_ns)
        self.messages = 0

    def _put(self, topic: str, t: float, body: dict) -> None:
        ns = self.start_ns + int(round(t * 1e9))
        self._w.add_message(self._ids[topic], log_time=ns, publish_time=ns, sequence=self.messages,
                            data=json.dumps({"t": t, **body}, separators=(",", ":")).encode())
        self.messages += 1

    def record(self, m: Measurement, command: Any = None, targets: Any = None) -> None:
        """One tick: what the controller was given (``m``, ``command``) and what it returned."""
        t = float(m.t)
        self._put("/time", t, {"unix_ms": (self.start_ns + t * 1e9) / 1e6})
        if m.gyro is not None:
            self._put("/imu/gyro", t, dict(zip("xyz", _list(m.gyro))))
        if m.accel is not None:
            self._put("/imu/accel", t, dict(zip("xyz", _list(m.accel))))
        if m.imu_rpy is not None:
            self._put("/imu/orientation", t, dict(zip(("roll", "pitch", "yaw"), _list(m.imu_rpy))))
        if m.q is not None:
            self._put("/joints/measured", t, {"position": _list(m.q),
                                               "velocity": [] if m.dq is None else _list(m.dq)})
        if targets is not None:
            self._put("/joints/target", t, {"position": _list(targets)})
        if m.foot_force is not None:
            self._put("/feet/force", t, {"force": _list(m.foot_force)})
        if command is not None:
            self._put("/walk/command", t, dict(zip(("vx", "vy", "wz"), _list(command))))

    def close(self, whole: bool = True) -> Path:
        """Finish the file and put it in place (``whole``), or leave it as the partial file (a run
        that failed or was stopped); returns where it is."""
        if self._fh.closed:
            return self.path if not self.partial.exists() else self.partial
        try:
            self._w.finish()
            self._fh.flush()
            os.fsync(self._fh.fileno())
        finally:
            self._fh.close()
        if not whole:
            return self.partial
        os.replace(self.partial, self.path)
        return self.path

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, kind: Any, *exc: Any) -> None:
        self.close(whole=kind is None)


class RecordingController(Wrapped):
    """A controller whose every tick is recorded (``gaits.control.Controller``: every attribute is
    the wrapped one's but these). A recording keeps every reading the robot has, whatever the
    controller uses (``senses``: all of :data:`gaits.control.READINGS`; the loop reads those the
    robot has), so a sweep or a joint table, which senses nothing, still records the encoders and
    the IMU that ``identify`` fits; the wrapped controller is given only the readings it senses, as
    without the recording. ``ahead`` is None: a recorded walk is run tick by tick (the simulator's
    native path skips ``step``; its walk is the tick loop's bit for bit)."""

    senses = frozenset(READINGS)
    ahead = None

    def __init__(self, inner: Any, recorder: Recorder) -> None:
        super().__init__(inner)
        self.recorder = recorder
        theirs = frozenset(getattr(inner, "senses", READINGS))
        self._unsensed = tuple(name for name in READINGS if name not in theirs)

    def _theirs(self, m: Measurement) -> Measurement:
        if not self._unsensed:
            return m
        return dataclasses.replace(m, **{name: None for name in self._unsensed})

    def reset(self, m: Measurement) -> None:
        self.inner.reset(self._theirs(m))

    def step(self, m: Measurement, command: Any = None) -> np.ndarray:
        q = self.inner.step(self._theirs(m), command)
        self.recorder.record(m, command, q)
        return q


@dataclass
class Recording:
    """A recording read back: its metadata and, per channel, the times [s] and the values (rows)."""

    meta: RecordingMeta
    channels: dict[str, tuple[np.ndarray, list[dict]]]
    truncated: bool = False                      # the file was cut short: what it held up to the cut

    def times(self, topic: str) -> np.ndarray:
        return self.channels.get(topic, (np.zeros(0), []))[0]

    def values(self, topic: str, key: str) -> np.ndarray:
        """One field of a channel's messages as an array (rows for list fields)."""
        rows = self.channels.get(topic, (None, []))[1]
        return np.array([r[key] for r in rows], dtype=float)


class _BadMessage(ValueError):
    """A message that is not what its channel holds (read_recording's ValueError, one line)."""


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _number_or_nan(v: Any) -> bool:
    """A reading: a number (a NaN is a reading the robot did not get: the loop records it as read)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and not math.isinf(v)


def _checked_message(path: Path, topic: str, body: Any, k: int, widths: dict[tuple[str, str], int]) -> float:
    """A message's time [s] after its body is checked against its channel (:data:`CHANNELS`): a JSON
    object, a finite ``t``, each field of the channel there and of its kind, a list the same length
    in every message of the channel; a ValueError naming channel, message and field otherwise."""
    where = f"{path}: channel {topic}, message {k}"
    if not isinstance(body, dict):
        raise _BadMessage(f"{where}: not a JSON object")
    t = body.pop("t", None)
    if not _finite(t):
        raise _BadMessage(f"{where}: t = {t!r}: expected a finite time [s]")
    for key, kind in CHANNELS.get(topic, ("", {}))[1].items():
        if key not in body:
            raise _BadMessage(f"{where}: no {key!r} field")
        v = body[key]
        if kind == "number":
            if not _number_or_nan(v):
                raise _BadMessage(f"{where}: {key} = {v!r}: expected a number")
            continue
        if not isinstance(v, list):
            raise _BadMessage(f"{where}: {key} = {str(v)[:60]}: expected a list of numbers")
        bad = next((i for i, x in enumerate(v) if not _number_or_nan(x)), None)
        if bad is not None:
            raise _BadMessage(f"{where}: {key}[{bad}] = {v[bad]!r}: expected a number")
        if not v and key == "velocity":     # a tick whose rates were not read: the angles alone
            continue
        width = widths.setdefault((topic, key), len(v))
        if len(v) != width:
            raise _BadMessage(f"{where}: {key} has {len(v)} values, the channel's first message {width}")
    return float(t)


def read_recording(path: str | Path) -> Recording:
    """Read a recording written by :class:`Recorder`, record by record: a file cut short (a run that
    was killed, a disk that filled) gives what it holds up to the cut, ``truncated``; one that is not
    a recording, or holds none of its metadata and messages, is a ValueError naming why."""
    _mcap()
    from mcap.records import Channel, Message, Metadata
    from mcap.stream_reader import StreamReader
    path = Path(path)
    meta, topics, found, truncated = None, {}, {}, False
    widths: dict[tuple[str, str], int] = {}
    with open(path, "rb") as fh:
        try:
            for record in StreamReader(fh, record_size_limit=1 << 28).records:
                if isinstance(record, Metadata) and record.name == METADATA_NAME:
                    meta = dict(record.metadata)
                elif isinstance(record, Channel):
                    topics[record.id] = record.topic
                elif isinstance(record, Message):
                    topic = topics[record.channel_id]
                    ts, rows = found.setdefault(topic, ([], []))
                    try:
                        body = json.loads(record.data)
                    except (ValueError, UnicodeDecodeError):
                        raise _BadMessage(f"{path}: channel {topic}, message {len(ts)}: not JSON") from None
                    ts.append(_checked_message(path, topic, body, len(ts), widths))
                    rows.append(body)
        except _BadMessage:
            raise
        except Exception as exc:  # noqa: BLE001 - the reader's errors on a cut or damaged file are many kinds
            if meta is None or not found:
                raise ValueError(f"{path}: not a readable recording ({type(exc).__name__}: "
                                 f"{' '.join(str(exc).split())[:200]})") from None
            truncated = True
    if meta is None:
        raise ValueError(f"{path}: no {METADATA_NAME} metadata: not a recording in this layout")
    try:
        info = RecordingMeta.from_strings(meta)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path}: its {METADATA_NAME} metadata does not read: {exc}") from None
    return Recording(info, {k: (np.array(ts), rows) for k, (ts, rows) in found.items()}, truncated)


def recording_info(rec: Recording, gap_factor: float = 1.8) -> dict[str, Any]:
    """What a recording holds: its metadata, duration [s], and per channel the messages, the rate
    [Hz] (median interval) and its gaps (intervals over ``gap_factor`` times the median:
    (start [s], length [s]); one tick the loop got no reading in is a gap of two ticks); and the
    time going backwards, where it does."""
    out: dict[str, Any] = {"meta": asdict(rec.meta), "truncated": rec.truncated, "channels": {}}
    t_all = [ts for ts, _ in rec.channels.values() if len(ts)]
    out["duration_s"] = float(max(ts.max() for ts in t_all) - min(ts.min() for ts in t_all)) if t_all else 0.0
    for topic, (ts, _) in sorted(rec.channels.items()):
        d = np.diff(ts)
        med = float(np.median(d)) if len(d) else math.nan
        gaps = [(float(ts[i]), float(d[i])) for i in np.flatnonzero(d > gap_factor * med)] if len(d) else []
        back = [float(ts[i + 1]) for i in np.flatnonzero(d < 0)]
        out["channels"][topic] = {"messages": int(len(ts)), "rate_hz": (1.0 / med) if med and med > 0 else None,
                                  "gaps": gaps, "backwards": back}
    return out
