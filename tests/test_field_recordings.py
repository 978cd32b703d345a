"""Recordings in (tuner/identify/field_recordings.py): ROS 2 bags written here with rosbags (sqlite3 and MCAP
storage) and gait-tuner's own MCAP read back equal, a CSV with a column in degrees, and every bad
recording one line, exit 2, naming channel and time."""

from __future__ import annotations


import re

import numpy as np
import pytest

from conftest import ROOT, run_cli
from gaits.control import Measurement
from gaits.robot.recorder import Recorder, RecordingMeta
from tuner.identify.field_recordings import RecordingError, read_field_recording

KID3KG = ROOT / "examples" / "robots" / "kid3kg" / "kid3kg.yaml"
JOINTS = ("l_hip_pitch", "l_knee", "r_hip_pitch", "r_knee")
THEIRS = {"l_hip_pitch": "HipPitch_L", "l_knee": "Knee_L", "r_hip_pitch": "HipPitch_R", "r_knee": "Knee_R"}
DT = 0.01
T0_NS = 1_700_000_000_250_000_000          # [ns] the bag's clock at the first message


def _data(n=300, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    target = 0.3 * np.sin(2 * np.pi * 0.5 * t[:, None] + np.arange(4))
    measured = target + rng.normal(0, 1e-3, target.shape)
    rpy = np.stack([0.01 * np.sin(t), 0.02 * np.cos(t), 0.1 * t], axis=1)
    return t, target, measured, rpy


def _ours(path, n=300, target=True, q_scale=1.0, times=None, rpy_override=None):
    t, tg, q, rpy = _data(n)
    if times is not None:
        t = times
    if rpy_override is not None:
        rpy = rpy_override
    with Recorder(path, RecordingMeta(robot="kid3kg", joints=list(JOINTS)), start_ns=0) as rec:
        for k in range(n):
            rec.record(Measurement(float(t[k]), q=q[k] * q_scale, imu_rpy=rpy[k], joint_names=JOINTS), None,
                       tg[k] if target else None)
    return path


def _quat(rpy):
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r / 2), np.sin(r / 2), np.cos(p / 2), np.sin(p / 2), np.cos(y / 2), np.sin(y / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy)


def _bag(path, storage: str):
    """The same run as a ROS 2 bag: JointState with their joint names (the knees' sign theirs:
    flipped), the command as a Float64MultiArray, an Imu."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    JointState, Header, Time = ts.types["sensor_msgs/msg/JointState"], ts.types["std_msgs/msg/Header"], \
        ts.types["builtin_interfaces/msg/Time"]
    Float64MultiArray, Layout = ts.types["std_msgs/msg/Float64MultiArray"], ts.types["std_msgs/msg/MultiArrayLayout"]
    Imu, Quaternion, Vector3 = ts.types["sensor_msgs/msg/Imu"], ts.types["geometry_msgs/msg/Quaternion"], \
        ts.types["geometry_msgs/msg/Vector3"]
    t, tg, q, rpy = _data()
    sign = np.array([1.0, -1.0, 1.0, -1.0])
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        c_js = w.add_connection("/joint_states", JointState.__msgtype__, typestore=ts)
        c_cmd = w.add_connection("/forward_position_controller/commands", Float64MultiArray.__msgtype__, typestore=ts)
        c_imu = w.add_connection("/imu/data", Imu.__msgtype__, typestore=ts)
        for k in range(len(t)):
            ns = T0_NS + k * 10_000_000
            hdr = Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id="base")
            js = JointState(header=hdr, name=[THEIRS[j] for j in JOINTS], position=q[k] * sign,
                            velocity=np.zeros(4), effort=np.zeros(0))
            w.write(c_js, ns, ts.serialize_cdr(js, JointState.__msgtype__))
            cmd = Float64MultiArray(layout=Layout(dim=[], data_offset=0), data=tg[k] * sign)
            w.write(c_cmd, ns, ts.serialize_cdr(cmd, Float64MultiArray.__msgtype__))
            w_, x_, y_, z_ = _quat(rpy[k])
            imu = Imu(header=hdr, orientation=Quaternion(x=x_, y=y_, z=z_, w=w_), orientation_covariance=np.zeros(9),
                      angular_velocity=Vector3(x=0.0, y=0.0, z=0.0), angular_velocity_covariance=np.zeros(9),
                      linear_acceleration=Vector3(x=0.0, y=0.0, z=9.81), linear_acceleration_covariance=np.zeros(9))
            w.write(c_imu, ns, ts.serialize_cdr(imu, Imu.__msgtype__))
    topics = path.parent / "topics.yaml"
    topics.write_text("joint_command: /forward_position_controller/commands\n"
                      f"command_joints: [{', '.join(THEIRS[j] for j in JOINTS)}]\n"
                      "joints: {" + ", ".join(f"{v}: {k}" for k, v in THEIRS.items()) + "}\n"
                      "signs: {l_knee: -1, r_knee: -1}\n")
    return path, topics


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_ros2_bag_reads_back_equal_to_our_recording(tmp_path, storage):
    ours = read_field_recording(_ours(tmp_path / "ours.mcap"))
    bag, topics = _bag(tmp_path / "bag", storage)
    theirs = read_field_recording(bag, topics=topics)
    assert theirs.joints == ours.joints == JOINTS
    for a, b in ((theirs.measured, ours.measured), (theirs.target, ours.target)):
        assert np.allclose(a[0], b[0], atol=1e-12, rtol=0)        # times: the header stamps less the first
        assert np.array_equal(a[1], b[1])                         # angles: float64 both ways, signs ours
    assert np.allclose(theirs.imu["rpy"][1], ours.imu["rpy"][1], atol=1e-12)
    g1 = theirs.on_grid(DT, JOINTS)
    g2 = ours.on_grid(DT, JOINTS)
    assert all(np.allclose(x, y, atol=1e-9) for x, y in zip(g1, g2))
    store = next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))   # the storage file names the bag too
    assert np.array_equal(read_field_recording(store, topics=topics).measured[1], ours.measured[1])


def test_a_csv_with_a_column_in_degrees(tmp_path):
    t, tg, q, _ = _data(50)
    head = ["t"] + [f"measured.{j}" for j in JOINTS] + [f"target.{j}" for j in JOINTS]
    head[2] += "[deg]"
    rows = np.column_stack([t, q, tg])
    rows[:, 2] = np.degrees(rows[:, 2])
    path = tmp_path / "r.csv"
    path.write_text(",".join(head) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    rec = read_field_recording(path, robot_joints=JOINTS)
    assert np.allclose(rec.measured[1], q, atol=1e-12) and np.array_equal(rec.target[1], tg)


def _bad(tmp_path, kind):
    if kind == "truncated":
        p = _ours(tmp_path / "r.mcap", n=3000)
        data = p.read_bytes()
        p.write_bytes(data[: len(data) // 2])
        return p, "cut short after t = "
    if kind == "no commanded angles":
        return _ours(tmp_path / "r.mcap", target=False), "no commanded joint angles"
    if kind == "degrees":
        return _ours(tmp_path / "r.mcap", q_scale=180 / np.pi), "degrees where radians are expected"
    if kind == "time backwards":
        t = np.arange(300) * DT
        t[150] = t[148]
        return _ours(tmp_path / "r.mcap", times=t), "time goes backwards at t = 1.480 s"
    if kind == "a fall":
        _, _, _, rpy = _data()
        rpy[200:, 1] = 1.4
        return _ours(tmp_path / "r.mcap", rpy_override=rpy), "the robot falls at t = 2.000 s"
    t, tg, q, _ = _data(80)
    joints = list(JOINTS)
    if kind == "unknown joint":
        joints[1] = "l_tail"
    if kind == "NaN burst":
        q[40:45, 2] = np.nan
    head = ["t"] + [f"measured.{j}" for j in joints] + [f"target.{j}" for j in joints]
    p = tmp_path / "r.csv"
    p.write_text(",".join(head) + "\n" + "\n".join(",".join(str(float(v)) for v in r)
                                                  for r in np.column_stack([t, q, tg])) + "\n")
    return p, {"unknown joint": "joint 'l_tail' is not one of the robot's",
               "NaN burst": "5 sample(s) not a number from t = 0.400 s to 0.440 s (r_hip_pitch first)"}[kind]


@pytest.mark.parametrize("kind", ["truncated", "no commanded angles", "degrees", "time backwards", "a fall",
                                  "unknown joint", "NaN burst"])
def test_a_bad_recording_is_one_line_exit_2(tmp_path, gait_tuner_cmd, run_env, kind):
    path, says = _bad(tmp_path, kind)
    with pytest.raises(RecordingError, match=None) as exc:
        rec = read_field_recording(path, robot_joints=list(THEIRS) + ["r_hip_roll"])
        rec.on_grid(DT, JOINTS)
    assert says in str(exc.value), str(exc.value)
    r = run_cli(gait_tuner_cmd, ['identify', 'servos', '--robot', str(KID3KG), '--recording', str(path), '--out',
                                 str(tmp_path / 'fit')], run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr, r.stderr
    assert not (tmp_path / "fit").exists()


def test_a_topics_file_that_is_wrong_is_one_line(tmp_path):
    bag, topics = _bag(tmp_path / "bag", "mcap")
    topics.write_text("joint_state: /joint_states\n")
    with pytest.raises(RecordingError, match="unknown field 'joint_state'"):
        read_field_recording(bag, topics=topics)
    topics.write_text("joint_states: /nowhere\n")
    with pytest.raises(RecordingError, match="no topic /nowhere"):
        read_field_recording(bag, topics=topics)
    # each was an internal error: a sign in words, a binary file, topics of another message type
    for text, words in (("signs: {l_knee: minus}\n", "signs.l_knee = 'minus': expected 1 or -1"),
                        ("joints: {LKnee: 3}\n", "joints: 'LKnee': 3: expected their joint name: ours"),
                        ("imu: /forward_position_controller/commands\n",
                         "(the imu) carries std_msgs/msg/Float64MultiArray; expected sensor_msgs/msg/Imu"),
                        ("joint_states: /imu/data\nimu: null\n", "topic /imu/data (the joint states) carries "
                                                                  "sensor_msgs/msg/Imu"),
                        ("joint_states: /imu/data\n", "joint_states and imu both name /imu/data"),
                        ("walk_command: /imu/data\nimu: null\n", "expected geometry_msgs/msg/Twist")):
        topics.write_text(text)
        with pytest.raises(RecordingError, match=re.escape(words)):
            read_field_recording(bag, topics=topics)
    topics.write_bytes(bytes(range(128, 256)) * 4)
    with pytest.raises(RecordingError, match="the topics file does not read"):
        read_field_recording(bag, topics=topics)


def test_a_csv_teams_write_reads_or_is_one_line(tmp_path):
    """A spreadsheet's byte-order mark is skipped; a column twice, a cell past csv's size limit, a
    quote left open and a FIFO are each one error naming the file (they were a silent pick, internal
    errors and a hang)."""
    import os

    from tuner.identify.field_recordings import RecordingError, read_field_recording
    rows = "".join(f"{k * 0.01:.2f},{0.1 * k:.3f},{0.1 * k:.3f}\n" for k in range(20))
    bom = tmp_path / "bom.csv"
    bom.write_bytes("\ufefft,measured.l_knee,target.l_knee\n".encode("utf-8") + rows.encode())
    assert read_field_recording(bom).joints == ("l_knee",)
    cases = {"twice.csv": "t,measured.l_knee,measured.l_knee,target.l_knee\n" + "".join(
                 f"{k * 0.01:.2f},0,0,0\n" for k in range(20)),
             "huge.csv": "t,measured.l_knee,target.l_knee\n0," + "9" * 200_000 + ",0\n",
             "quote.csv": 't,measured.l_knee,target.l_knee\n0,"0,0\n0.01,0,0\n'}
    words = {"twice.csv": "appears twice", "huge.csv": "does not read as CSV", "quote.csv": "quote.csv: a value that is not a number"}
    for name, text in cases.items():
        f = tmp_path / name
        f.write_text(text)
        with pytest.raises(RecordingError, match=words[name]):
            read_field_recording(f)
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    with pytest.raises(RecordingError, match="not a regular file"):
        read_field_recording(fifo)


@pytest.mark.parametrize("named", [True, False])
def test_the_commanded_angles_of_a_robot_that_measures_fewer_joints_are_its_joints(tmp_path, named):
    """A robot with legs only (Wolfgang-OP in our map) measures 12 joints while its controller asks
    all our 20 roles: the commanded angles are read by name into the measured joints' columns (a
    recording names them, ``target_joints``; one made before names none, and its 20 columns are our
    20 roles). Before, the first 12 of the 20 (the arms and head, then half a leg) were read as the
    legs' targets: a walk replayed from them, ``identify ground`` and ``identify servos`` on it,
    fitted a robot doing something else."""
    from gaits import JOINT_NAMES
    legs = [j for j in JOINT_NAMES if j[2:].startswith(("hip", "knee", "ankle"))]
    assert len(legs) == 12
    meta = RecordingMeta(robot="legs", joints=legs, target_joints=list(JOINT_NAMES) if named else [])
    asked = np.arange(len(JOINT_NAMES), dtype=float) / 100.0          # each role its own number
    with Recorder(tmp_path / "r.mcap", meta, start_ns=0) as rec:
        for k in range(20):
            rec.record(Measurement(0.01 * k, q=np.zeros(12), joint_names=legs), None, asked + k * 1e-3)
    back = read_field_recording(tmp_path / "r.mcap")
    assert back.joints == tuple(legs)
    t, got = back.target
    want = np.array([[JOINT_NAMES.index(j) / 100.0 + k * 1e-3 for j in legs] for k in range(20)])
    np.testing.assert_array_equal(got, want)
    meta = RecordingMeta(robot="legs", joints=legs, target_joints=list(JOINT_NAMES[:19]))
    with Recorder(tmp_path / "bad.mcap", meta, start_ns=0) as rec:
        rec.record(Measurement(0.0, q=np.zeros(12), joint_names=legs), None, asked)
    with pytest.raises(RecordingError, match="holds 20 angles per message; its metadata names 19"):
        read_field_recording(tmp_path / "bad.mcap")
