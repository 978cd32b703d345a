"""Recordings in: what a team's robot did, read from the formats the field writes, checked, and put
on the control period's grid. One adapter per format, one object out (:class:`FieldRecording`).

Formats:

* **gait-tuner's MCAP** (``gaits/robot/recorder.py``: the HumanoidDataset layout the loop, the simulated
  bus and ``simulate --record`` write), found by its metadata record;
* **ROS 2 bags** (a bag folder, its ``.mcap`` or ``.db3``), read with ``rosbags`` (pure Python,
  no ROS install) through a small topics file (``--topics``; :data:`DEFAULT_TOPICS` otherwise)::

      joint_states: /joint_states            # sensor_msgs/JointState: measured positions [rad]
      joint_command: /joint_command          # sensor_msgs/JointState, std_msgs/Float64MultiArray
                                             #   or trajectory_msgs/JointTrajectory: targets [rad]
      command_joints: [l_hip_yaw, ...]       # the Float64MultiArray's order (their names)
      imu: /imu/data                         # sensor_msgs/Imu (optional)
      walk_command: /cmd_vel                 # geometry_msgs/Twist (optional)
      joints: {LHipYaw: l_hip_yaw, ...}      # their joint names -> ours (default: ours already)
      signs: {l_knee: -1}                    # where their sign is not ours (default +1)

  Times are the messages' header stamps where they have one (JointState, Imu), else the bag's;
* **CSV**: a header row, then one row per sample: ``t`` [s], ``measured.<joint>`` and
  ``target.<joint>`` [rad] (our joint names), optionally ``roll, pitch, yaw`` [rad], ``gyro_x, gyro_y,
  gyro_z`` [rad/s], ``accel_x, accel_y, accel_z`` [m/s^2], ``vx, vy, wz`` (the walk command). A
  column in degrees says so in its name (``measured.l_knee[deg]``) and is converted.

Checks (each a one-line ``RecordingError`` naming the file, channel and time): a missing channel,
time going backwards, non-finite values, joint angles beyond 2 pi (degrees where radians are
expected), joints not in the robot, a file cut short, a fall (the torso tilted past 60 deg, where
the recording has an orientation). Gaps (over 3x the median interval) and clock jumps are kept
and reported (``gaps``), not refused.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["RecordingError", "FieldRecording", "read_field_recording", "DEFAULT_TOPICS", "FALL_TILT_DEG",
           "load_topics"]

FALL_TILT_DEG = 60.0        # [deg] past this the recording holds a fall (ours)
GAP_FACTOR = 3.0

DEFAULT_TOPICS: dict[str, Any] = {"joint_states": "/joint_states", "joint_command": "/joint_command",
                                  "imu": "/imu/data", "walk_command": "/cmd_vel"}


class RecordingError(ValueError):
    """A recording that cannot serve: one line naming the file, channel and time."""


@dataclass
class FieldRecording:
    """A recording read back, in SI units and gait-tuner's joint names and signs.

    ``measured`` / ``target``: (times (N,), angles (N, n)) per channel, columns ``joints``;
    ``imu``: times and ``rpy``/``gyro``/``accel`` (K, 3) where recorded; ``walk``: (times,
    (K, 3)) where recorded; ``gaps``: one sentence per gap or clock jump found."""

    name: str
    joints: tuple[str, ...]
    measured: tuple[np.ndarray, np.ndarray]
    target: tuple[np.ndarray, np.ndarray] | None
    imu: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    walk: tuple[np.ndarray, np.ndarray] | None = None
    foot_force: tuple[np.ndarray, np.ndarray] | None = None
    simulated: bool = False
    robot: str = ""
    surface: str = ""
    gaps: list[str] = field(default_factory=list)
    grid_start: float = 0.0                    # [s] where the last on_grid began
    #: the last on_grid's ticks whose measured angles were recorded within half a tick (not
    #: interpolated across a gap): what a fit may compare
    grid_valid: np.ndarray | None = None

    @property
    def duration(self) -> float:
        t = self.measured[0]
        return float(t[-1] - t[0]) if len(t) > 1 else 0.0

    def on_grid(self, dt: float, joints) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t (N,), targets (N, n), measured (N, n)) on a grid of ``dt`` [s] over the span both
        channels cover, columns ``joints``: measured angles interpolated linearly, targets held
        from the last one asked (a servo keeps its last goal)."""
        if self.target is None:
            raise RecordingError(f"{self.name}: no commanded joint angles (channel joint_command / "
                                 f"/joints/target / target.<joint>): identification needs what was asked")
        missing = [j for j in joints if j not in self.joints]
        if missing:
            raise RecordingError(f"{self.name}: no angles of {', '.join(missing[:4])}"
                                 f"{' ...' if len(missing) > 4 else ''} (the robot's joints)")
        idx = [self.joints.index(j) for j in joints]
        tm, qm = self.measured
        tt, qt = self.target
        t0, t1 = max(tm[0], tt[0]), min(tm[-1], tt[-1])
        if t1 - t0 < 10 * dt:
            raise RecordingError(f"{self.name}: its measured and commanded angles overlap {max(t1 - t0, 0):.3f} s; "
                                 f"too short to identify from")
        t = t0 + np.arange(int(math.floor((t1 - t0) / dt + 1e-9)) + 1) * dt
        meas = np.stack([np.interp(t, tm, qm[:, i]) for i in idx], axis=1)
        k = np.clip(np.searchsorted(tt, t + 1e-9, side="right") - 1, 0, len(tt) - 1)
        self.grid_start = float(t0)
        j = np.clip(np.searchsorted(tm, t), 1, len(tm) - 1)
        nearest = np.minimum(np.abs(tm[j] - t), np.abs(t - tm[j - 1]))
        self.grid_valid = nearest <= 0.5 * dt + 1e-9
        return t - t0, qt[k][:, idx], meas


    def not_hanging(self) -> str | None:
        """Why this recording is not of a robot hanging in a harness (None when nothing says so): a
        walk command that moves, soles that carry weight, or a torso that turns (ours: a sweep in a
        harness holds the torso; 0.3 rad/s RMS of gyro and 10 N on the soles are far above a held one)."""
        if self.walk is not None and len(self.walk[1]) and float(np.max(np.abs(self.walk[1]))) > 1e-6:
            return "it carries a walk command that moves"
        if self.foot_force is not None and len(self.foot_force[1]):
            load = float(np.median(np.sum(self.foot_force[1], axis=1)))
            if load > 10.0:
                return f"its soles carry {load:.0f} N (median)"
        gyro = self.imu.get("gyro")
        if gyro is not None and len(gyro[1]):
            rms = float(np.sqrt(np.mean(np.sum(np.square(gyro[1]), axis=1))))
            if rms > 0.3:
                return f"its torso turns ({rms:.2f} rad/s RMS on the gyro)"
        return None

    def imu_on_grid(self, t: np.ndarray, t_start: float) -> dict[str, np.ndarray | None]:
        """The IMU's ``rpy``, ``gyro`` and ``accel`` at ``t`` [s after ``t_start``] (linear
        interpolation; None where not recorded); roll, pitch and gyro are required."""
        out: dict[str, np.ndarray | None] = {}
        for key, what in (("rpy", "orientation"), ("gyro", "gyro"), ("accel", "accelerometer")):
            if key not in self.imu:
                if key == "accel":
                    out[key] = None
                    continue
                raise RecordingError(f"{self.name}: no IMU {what} channel: identifying the ground needs the "
                                     f"torso's orientation and rates")
            ti, v = self.imu[key]
            if key == "rpy":
                v = np.unwrap(v, axis=0)
            out[key] = np.stack([np.interp(t + t_start, ti, v[:, i]) for i in range(3)], axis=1)
        return out


# --- checks ----------------------------------------------------------------------------------------
def _check_times(name: str, channel: str, t: np.ndarray, gaps: list[str]) -> None:
    if len(t) == 0:
        raise RecordingError(f"{name}: channel {channel} holds no messages")
    if not np.all(np.isfinite(t)):
        i = int(np.argmax(~np.isfinite(t)))
        raise RecordingError(f"{name}: channel {channel}: a time that is not a number at message {i}")
    d = np.diff(t)
    back = np.flatnonzero(d < 0)
    if back.size:
        i = int(back[0])
        raise RecordingError(f"{name}: channel {channel}: time goes backwards at t = {t[i + 1]:.3f} s "
                             f"(from {t[i]:.3f} s)")
    if len(d):
        med = float(np.median(d))
        for i in np.flatnonzero(d > GAP_FACTOR * med)[:20] if med > 0 else []:
            gaps.append(f"channel {channel}: a gap of {d[i]:.3f} s at t = {t[i]:.3f} s")


def _check_values(name: str, channel: str, t: np.ndarray, v: np.ndarray, labels, angles: bool = False) -> None:
    bad = ~np.isfinite(v)
    if bad.any():
        rows = np.flatnonzero(bad.any(axis=1))
        col = int(np.argmax(bad[rows[0]]))
        raise RecordingError(f"{name}: channel {channel}: {len(rows)} sample(s) not a number from t = "
                             f"{t[rows[0]]:.3f} s to {t[rows[-1]]:.3f} s ({labels[col]} first)")
    if angles and v.size:
        big = np.abs(v) > 2 * math.pi
        if big.any():
            r, c = (int(x[0]) for x in np.nonzero(big))
            raise RecordingError(f"{name}: channel {channel}: {labels[c]} reads {v[r, c]:.1f} at t = {t[r]:.3f} s, "
                                 f"beyond 2 pi: degrees where radians are expected? (mark a CSV column "
                                 f"in degrees with [deg])")


def _check_fall(name: str, rec: FieldRecording) -> None:
    if "rpy" not in rec.imu:
        return
    t, rpy = rec.imu["rpy"]
    tilt = np.degrees(np.arccos(np.clip(np.cos(rpy[:, 0]) * np.cos(rpy[:, 1]), -1, 1)))
    over = np.flatnonzero(tilt > FALL_TILT_DEG)
    if over.size:
        i = int(over[0])
        raise RecordingError(f"{name}: the robot falls at t = {t[i]:.3f} s (torso tilted {tilt[i]:.0f} deg): "
                             f"cut the recording before the fall")


def _finish(rec: FieldRecording, robot_joints) -> FieldRecording:
    name = rec.name
    if robot_joints is not None:
        unknown = [j for j in rec.joints if j not in robot_joints]
        if unknown:
            raise RecordingError(f"{name}: joint {unknown[0]!r} is not one of the robot's (ours: "
                                 f"{', '.join(list(robot_joints)[:6])} ...; a ROS bag maps its names with "
                                 f"the topics file's joints:)")
    for label, pair in (("measured joints", rec.measured), ("commanded joints", rec.target)):
        if pair is None:
            continue
        _check_times(name, label, pair[0], rec.gaps)
        _check_values(name, label, pair[0], pair[1], rec.joints, angles=True)
    for k, (t, v) in rec.imu.items():
        _check_times(name, f"imu {k}", t, rec.gaps)
        _check_values(name, f"imu {k}", t, v, ["x", "y", "z"], angles=False)
    _check_fall(name, rec)
    return rec


# --- gait-tuner's MCAP ----------------------------------------------------------------------------
def _ours(path: Path, robot_joints) -> FieldRecording:
    from gaits.robot.recorder import read_recording
    try:
        rec = read_recording(path)
    except ValueError as exc:
        raise RecordingError(str(exc)) from None
    name = str(path)
    if rec.truncated:
        t_end = max((float(ts[-1]) for ts, _ in rec.channels.values() if len(ts)), default=0.0)
        raise RecordingError(f"{name}: the file is cut short after t = {t_end:.3f} s (a run killed or a disk "
                             f"full); re-record, or cut it there with a tool of your own")
    joints = tuple(rec.meta.joints)
    if "/joints/measured" not in rec.channels:
        raise RecordingError(f"{name}: no /joints/measured channel (the measured joint angles)")
    meas = (rec.times("/joints/measured"), rec.values("/joints/measured", "position"))
    if meas[1].ndim != 2 or meas[1].shape[1] != len(joints):
        raise RecordingError(f"{name}: channel /joints/measured holds {meas[1].shape[-1]} angles per message; "
                             f"its metadata names {len(joints)} joints")
    target = None
    if "/joints/target" in rec.channels:
        target = _targets_as_measured(name, rec.meta, joints, rec.times("/joints/target"),
                                      rec.values("/joints/target", "position"))
    imu = {}
    if "/imu/orientation" in rec.channels:
        t = rec.times("/imu/orientation")
        imu["rpy"] = (t, np.stack([rec.values("/imu/orientation", k) for k in ("roll", "pitch", "yaw")], axis=1))
    for ch, key in (("/imu/gyro", "gyro"), ("/imu/accel", "accel")):
        if ch in rec.channels:
            imu[key] = (rec.times(ch), np.stack([rec.values(ch, k) for k in "xyz"], axis=1))
    walk = None
    if "/walk/command" in rec.channels:
        walk = (rec.times("/walk/command"),
                np.stack([rec.values("/walk/command", k) for k in ("vx", "vy", "wz")], axis=1))
    feet = (rec.times("/feet/force"), rec.values("/feet/force", "force")) if "/feet/force" in rec.channels else None
    out = FieldRecording(name, joints, meas, target, imu, walk, feet, rec.meta.simulated, rec.meta.robot,
                         rec.meta.surface)
    return _finish(out, robot_joints)


def _targets_as_measured(name: str, meta: Any, joints: tuple[str, ...], t: np.ndarray,
                         values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The commanded angles in the measured joints' columns: a controller asks all our 20 roles (and
    a robot's extra joints) of a robot whose encoders read fewer; the metadata's ``target_joints``
    names them (a recording made before it did: our 20 roles when there are 20 columns and fewer
    measured joints, else the measured joints)."""
    from gaits import JOINT_NAMES
    width = values.shape[1] if values.ndim == 2 else -1
    names = list(getattr(meta, "target_joints", None) or [])
    if not names:
        names = list(JOINT_NAMES) if width == len(JOINT_NAMES) != len(joints) else list(joints)
    if width != len(names):
        raise RecordingError(f"{name}: channel /joints/target holds {width} angles per message; its metadata "
                             f"names {len(names)} joints")
    missing = [j for j in joints if j not in names]
    if missing:
        raise RecordingError(f"{name}: no commanded angle of {missing[0]!r} in /joints/target (it names "
                             f"{', '.join(names[:6])} ...)")
    return t, values[:, [names.index(j) for j in joints]]


# --- ROS 2 bags ------------------------------------------------------------------------------------
def load_topics(path: str | Path | None) -> dict[str, Any]:
    """The topics file (YAML) over :data:`DEFAULT_TOPICS`; a field of the wrong kind is a one-line error."""
    out = dict(DEFAULT_TOPICS)
    if path is None:
        return out
    import yaml

    from gaits.files import MAX_BYTES, read_bytes_checked
    raw = read_bytes_checked(path, "topics", MAX_BYTES["yaml"], RecordingError)
    try:
        doc = yaml.safe_load(raw.decode("utf-8")) or {}
    except (UnicodeDecodeError, yaml.YAMLError) as exc:
        raise RecordingError(f"{path}: the topics file does not read ({' '.join(str(exc).split())[:160]})") from None
    if not isinstance(doc, dict):
        raise RecordingError(f"{path}: the topics file must be a mapping (joint_states, joint_command, imu, ...)")
    allowed = set(DEFAULT_TOPICS) | {"joints", "signs", "command_joints"}
    for k, v in doc.items():
        if k not in allowed:
            raise RecordingError(f"{path}: unknown field {k!r} (allowed: {', '.join(sorted(allowed))})")
        if k in ("joints", "signs") and not isinstance(v, dict):
            raise RecordingError(f"{path}: {k} must be a mapping")
        if k == "joints":
            bad = next((x for x in v.items() if not all(isinstance(n, str) and n for n in x)), None)
            if bad is not None:
                raise RecordingError(f"{path}: joints: {bad[0]!r}: {bad[1]!r}: expected their joint name: ours")
        if k == "signs":
            bad = next((x for x in v.items() if isinstance(x[1], bool) or x[1] not in (1, -1)), None)
            if bad is not None:
                raise RecordingError(f"{path}: signs.{bad[0]} = {bad[1]!r}: expected 1 or -1")
        if k == "command_joints" and not (isinstance(v, list) and all(isinstance(x, str) for x in v)):
            raise RecordingError(f"{path}: command_joints must be a list of joint names")
        if k in DEFAULT_TOPICS and v is not None and not isinstance(v, str):
            raise RecordingError(f"{path}: {k} must be a topic name (or null)")
    out.update(doc)
    return out


#: the message types each topic of a bag must carry (the joint command's three are checked where it is read)
_MESSAGE_TYPES = {"joint_states": ("sensor_msgs/msg/JointState",), "imu": ("sensor_msgs/msg/Imu",),
                  "walk_command": ("geometry_msgs/msg/Twist",)}


def _stamp(msg: Any, t_bag: int) -> int:
    """The message's time [ns] (an integer: seconds since 1970 as a float keep only ~0.2 us)."""
    h = getattr(msg, "header", None)
    if h is not None and (h.stamp.sec or h.stamp.nanosec):
        return int(h.stamp.sec) * 1_000_000_000 + int(h.stamp.nanosec)
    return int(t_bag)


def _bag(path: Path, topics: dict[str, Any], robot_joints) -> FieldRecording:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise RecordingError("reading ROS 2 bags needs rosbags: pip install rosbags") from None
    bag = path.parent if path.suffix in (".mcap", ".db3") and (path.parent / "metadata.yaml").exists() else path
    name = str(path)
    their_to_ours = dict(topics.get("joints") or {})
    signs = {k: float(v) for k, v in (topics.get("signs") or {}).items()}
    rows: dict[str, list] = {"joint_states": [], "joint_command": [], "imu": [], "walk_command": []}
    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            by_topic = {c.topic: c for c in reader.connections}
            for key in rows:
                topic = topics.get(key)
                if topic and topic not in by_topic and key in ("joint_states",):
                    raise RecordingError(f"{name}: no topic {topic} (its {key}); the bag has "
                                         f"{', '.join(sorted(by_topic)) or 'none'} (name yours in --topics)")
            named = [k for k in rows if topics.get(k)]
            twice = next(((a, b) for i, a in enumerate(named) for b in named[i + 1:] if topics[a] == topics[b]), None)
            if twice is not None:
                raise RecordingError(f"{name}: {twice[0]} and {twice[1]} both name {topics[twice[0]]} (one topic a "
                                     f"reading: set the other in --topics, or null)")
            wanted = {topics[k]: k for k in rows if topics.get(k) in by_topic}
            conns = [by_topic[t] for t in wanted]
            for conn, t_bag, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                rows[wanted[conn.topic]].append((conn.msgtype, _stamp(msg, t_bag), msg))
    except RecordingError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags' errors on a damaged bag are many kinds
        raise RecordingError(f"{name}: not a readable ROS 2 bag ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:160]})") from None

    def ours(n: str) -> str:
        return their_to_ours.get(n, n)

    for key, kinds in _MESSAGE_TYPES.items():       # a topic of another message type: one line, not its fields
        other = next((msgtype for msgtype, _, _ in rows[key] if msgtype not in kinds), None)
        if other is not None:
            raise RecordingError(f"{name}: topic {topics[key]} (the {key.replace('_', ' ')}) carries {other}; expected "
                                 f"{' or '.join(kinds)} (name another topic in --topics)")
    states = rows["joint_states"]
    if not states:
        raise RecordingError(f"{name}: no messages on {topics['joint_states']} (the measured joint angles)")
    t0 = states[0][1]
    first_names = list(states[0][2].name) if states else []
    joints = tuple(ours(n) for n in first_names)
    if robot_joints is not None:
        unknown = [first_names[i] for i, j in enumerate(joints) if j not in robot_joints]
        if unknown:
            raise RecordingError(f"{name}: joint {unknown[0]!r} of {topics['joint_states']} is not one of the robot's "
                                 f"(map it in the topics file's joints:)")
    sign = np.array([signs.get(j, 1.0) for j in joints])

    def table(entries, channel: str) -> tuple[np.ndarray, np.ndarray]:
        t, q = [], []
        order = topics.get("command_joints")
        for msgtype, stamp, msg in entries:
            if msgtype.endswith("JointState"):
                names, pos = [ours(n) for n in msg.name], np.asarray(msg.position, dtype=float)
            elif msgtype.endswith("Float64MultiArray"):
                if not order:
                    raise RecordingError(f"{name}: channel {channel} is a Float64MultiArray: name its order "
                                         f"in the topics file's command_joints")
                names, pos = [ours(n) for n in order], np.asarray(msg.data, dtype=float)
            elif msgtype.endswith("JointTrajectory"):
                if not msg.points:
                    continue
                names, pos = [ours(n) for n in msg.joint_names], np.asarray(msg.points[0].positions, dtype=float)
            else:
                raise RecordingError(f"{name}: channel {channel} is a {msgtype}; expected sensor_msgs/JointState, "
                                     f"std_msgs/Float64MultiArray or trajectory_msgs/JointTrajectory")
            if len(pos) != len(names):
                raise RecordingError(f"{name}: channel {channel} at t = {(stamp - t0) * 1e-9:.3f} s: {len(pos)} positions "
                                     f"for {len(names)} names")
            row = np.full(len(joints), np.nan)
            where = {n: i for i, n in enumerate(names)}
            for i, j in enumerate(joints):
                if j in where:
                    row[i] = pos[where[j]]
            t.append((stamp - t0) * 1e-9)
            q.append(row * sign)
        return np.array(t), (np.array(q) if q else np.zeros((0, len(joints))))

    tm, qm = table(states, topics["joint_states"])
    target = None
    if rows["joint_command"]:
        tt, qt = table(rows["joint_command"], topics["joint_command"])
        # a command that names only some joints: the others hold their last (or first) value
        for i in range(qt.shape[1]):
            col = qt[:, i]
            ok = np.isfinite(col)
            if not ok.any():
                raise RecordingError(f"{name}: channel {topics['joint_command']} never commands {joints[i]}")
            idx = np.maximum.accumulate(np.where(ok, np.arange(len(col)), 0))
            idx[: int(np.argmax(ok))] = int(np.argmax(ok))
            qt[:, i] = col[idx]
        target = (tt, qt)
    imu = {}
    if rows["imu"]:
        from gaits.control import rpy_from_quat
        t = (np.array([s for _, s, _ in rows["imu"]], dtype=np.int64) - t0) * 1e-9
        quat = np.array([[m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z] for _, _, m in rows["imu"]])
        imu["rpy"] = (t, np.asarray(rpy_from_quat(quat)))
        imu["gyro"] = (t, np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z]
                                    for _, _, m in rows["imu"]]))
        imu["accel"] = (t, np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
                                     for _, _, m in rows["imu"]]))
    walk = None
    if rows["walk_command"]:
        walk = ((np.array([s for _, s, _ in rows["walk_command"]], dtype=np.int64) - t0) * 1e-9,
                np.array([[m.linear.x, m.linear.y, m.angular.z] for _, _, m in rows["walk_command"]]))
    return _finish(FieldRecording(name, joints, (tm, qm), target, imu, walk), robot_joints)


# --- CSV -----------------------------------------------------------------------------------------
_CSV_IMU = {"rpy": ("roll", "pitch", "yaw"), "gyro": ("gyro_x", "gyro_y", "gyro_z"),
            "accel": ("accel_x", "accel_y", "accel_z")}


def _csv(path: Path, robot_joints) -> FieldRecording:
    name = str(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:     # a spreadsheet's byte-order mark skipped
            reader = csv.reader(fh)
            header = next(reader, None)
            body = [r for r in reader if r and not r[0].startswith("#")]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:       # a cell past csv's size limit, a quote left open
        raise RecordingError(f"{name}: does not read as CSV ({' '.join(str(exc).split())})") from None
    if not header:
        raise RecordingError(f"{name}: an empty CSV (expected a header row: t, measured.<joint>, target.<joint>, ...)")
    cols, scale = [], []
    for h in header:
        h = h.strip()
        deg = h.endswith("[deg]")
        base = h[:-5].strip() if deg else h.removesuffix("[rad]").strip()
        cols.append(base)
        scale.append(math.pi / 180 if deg else 1.0)
    if "t" not in cols:
        raise RecordingError(f"{name}: no t column (seconds) in its header")
    twice = sorted({c for c in cols if cols.count(c) > 1})
    if twice:
        raise RecordingError(f"{name}: the column {twice[0]!r} appears twice in its header: which is meant?")
    try:
        a = np.array([[float(x) for x in r] for r in body], dtype=float)
    except ValueError as exc:
        raise RecordingError(f"{name}: a value that is not a number ({exc})") from None
    if a.ndim != 2 or a.shape[0] == 0 or a.shape[1] != len(cols):
        raise RecordingError(f"{name}: rows do not match its header ({len(cols)} columns)")
    a = a * np.array(scale)
    t = a[:, cols.index("t")]
    meas = [c for c in cols if c.startswith("measured.")]
    if not meas:
        raise RecordingError(f"{name}: no measured.<joint> columns (the measured joint angles)")
    joints = tuple(c.split(".", 1)[1] for c in meas)
    qm = a[:, [cols.index(c) for c in meas]]
    tg = [f"target.{j}" for j in joints]
    target = None
    if any(c.startswith("target.") for c in cols):
        missing = [c for c in tg if c not in cols]
        if missing:
            raise RecordingError(f"{name}: no {missing[0]} column beside its measured one")
        target = (t, a[:, [cols.index(c) for c in tg]])
    imu = {k: (t, a[:, [cols.index(c) for c in names]]) for k, names in _CSV_IMU.items()
           if all(c in cols for c in names)}
    walk = (t, a[:, [cols.index(c) for c in ("vx", "vy", "wz")]]) if all(c in cols for c in ("vx", "vy", "wz")) else None
    return _finish(FieldRecording(name, joints, (t, qm), target, imu, walk), robot_joints)


def _is_ours(path: Path) -> bool:
    """gait-tuner's MCAP (JSON messages, its metadata) or a ROS 2 bag's (CDR messages)."""
    try:
        from mcap.reader import make_reader
        with open(path, "rb") as fh:
            summary = make_reader(fh).get_summary()
        if summary is not None and summary.channels:
            return not any(c.message_encoding == "cdr" for c in summary.channels.values())
    except Exception:  # noqa: BLE001 - a file cut short has no summary: look at its first records
        pass
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 20)
    except OSError:
        return False
    return b"/joints/measured" in head or b"humanoid_dataset" in head


def read_field_recording(path: str | Path, *, topics: str | Path | dict | None = None,
                         robot_joints=None) -> FieldRecording:
    """Read and check one recording (the format from the file: see the module's docstring).
    ``robot_joints``: our names of the robot's joints (a recorded joint outside them is an error)."""
    p = Path(path)
    if not p.exists():
        raise RecordingError(f"{p}: no such file or folder")
    if not p.is_dir() and not p.is_file():          # a FIFO, a device: reading it would wait forever
        raise RecordingError(f"{p}: not a regular file (a pipe or a device): record to a file")
    if robot_joints is not None:
        robot_joints = tuple(robot_joints)
    if p.suffix.lower() == ".csv":
        return _csv(p, robot_joints)
    if p.is_dir() or p.suffix == ".db3" or (p.suffix == ".mcap" and not _is_ours(p)):
        t = topics if isinstance(topics, dict) else load_topics(topics)
        return _bag(p, t, robot_joints)
    if p.suffix == ".mcap":
        return _ours(p, robot_joints)
    raise RecordingError(f"{p}: not a recording this tool reads (gait-tuner's .mcap, a ROS 2 bag folder, "
                         f".mcap or .db3, or a .csv)")

