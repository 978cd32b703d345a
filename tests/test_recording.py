"""Recordings (gaits/robot/recorder.py, `simulate --record`, `gait-tuner log info`): MCAP files in the
HumanoidDataset layout that read back equal, say what they hold, survive being cut short, and
refuse to be what they are not in one line."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, run_cli
from gaits.control import Measurement
from gaits.robot.recorder import CHANNELS, Recorder, RecordingMeta, read_recording, recording_info


def _ticks(n=250, seed=0):
    rng = np.random.default_rng(seed)
    for k in range(n):
        yield (Measurement(k * 0.01, q=rng.normal(size=20), dq=rng.normal(size=20), imu_rpy=rng.normal(size=3),
                           gyro=rng.normal(size=3), accel=rng.normal(size=3), foot_force=rng.uniform(0, 20, 8)),
               rng.normal(size=3), rng.normal(size=20))


def test_a_recording_reads_back_equal(tmp_path):
    meta = RecordingMeta(robot="kid", task="match", simulated=False, maker="us", parameters={"period": 0.3},
                         surface="grass30")
    with Recorder(tmp_path / "r.mcap", meta, start_ns=1_700_000_000_000_000_000) as rec:
        ticks = list(_ticks())
        for m, c, q in ticks:
            rec.record(m, c, q)
    back = read_recording(tmp_path / "r.mcap")
    assert back.meta == meta and not back.truncated and set(back.channels) == set(CHANNELS)
    assert np.array_equal(back.values("/joints/measured", "position"), np.array([m.q for m, _, _ in ticks]))
    assert np.array_equal(back.values("/joints/target", "position"), np.array([q for _, _, q in ticks]))
    assert np.array_equal(back.values("/feet/force", "force"), np.array([m.foot_force for m, _, _ in ticks]))
    assert np.array_equal(back.values("/walk/command", "wz"), np.array([c[2] for _, c, _ in ticks]))
    assert np.array_equal(back.values("/imu/orientation", "pitch"), np.array([m.imu_rpy[1] for m, _, _ in ticks]))
    assert np.array_equal(back.times("/imu/gyro"), np.array([m.t for m, _, _ in ticks]))
    assert back.values("/time", "unix_ms")[1] == pytest.approx(1_700_000_000_000.0 + 10.0)
    info = recording_info(back)
    assert info["duration_s"] == pytest.approx(2.49) and info["channels"]["/imu/gyro"]["rate_hz"] == pytest.approx(100)
    assert all(c["gaps"] == [] and c["backwards"] == [] for c in info["channels"].values())


def test_gaps_and_time_going_back_are_named(tmp_path):
    with Recorder(tmp_path / "g.mcap", RecordingMeta(robot="kid")) as rec:
        for t in [0.0, 0.01, 0.02, 0.5, 0.51, 0.505, 0.52]:
            rec.record(Measurement(t, gyro=np.zeros(3)))
    c = recording_info(read_recording(tmp_path / "g.mcap"))["channels"]["/imu/gyro"]
    assert c["gaps"] == [(0.02, pytest.approx(0.48))] and c["backwards"] == [0.505]


def test_a_recording_cut_short_gives_what_it_held(tmp_path):
    path = tmp_path / "r.mcap"
    with Recorder(path, RecordingMeta(robot="kid")) as rec:
        for m, c, q in _ticks(1000):
            rec.record(m, c, q)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:path.stat().st_size // 2])
    back = read_recording(cut)
    n = len(back.times("/joints/target"))
    assert back.truncated and 100 < n < 1000
    assert np.array_equal(back.values("/joints/target", "position"), np.array([q for _, _, q in _ticks(1000)])[:n])


def test_a_recording_is_whole_or_not_at_all(tmp_path, monkeypatch):
    """Until it closes, a recording is written beside its name (NAME.partial.mcap): a run that fails
    half-way, or a disk that fills as it closes, leaves the old recording of the name as it was and
    what was recorded readable in the partial file; a recording that closes replaces it."""
    import errno
    import os
    from gaits.robot.recorder import partial_path
    path = tmp_path / "walk.mcap"
    path.write_bytes(b"the old recording")
    with pytest.raises(KeyboardInterrupt):
        with Recorder(path, RecordingMeta(robot="kid")) as rec:
            for m, c, q in _ticks(300):
                rec.record(m, c, q)
            raise KeyboardInterrupt
    assert path.read_bytes() == b"the old recording"
    assert len(read_recording(partial_path(path)).times("/joints/target")) == 300
    rec = Recorder(path, RecordingMeta(robot="kid"))
    for m, c, q in _ticks(50):
        rec.record(m, c, q)

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError):
        rec.close()
    monkeypatch.undo()
    assert path.read_bytes() == b"the old recording"
    with Recorder(path, RecordingMeta(robot="kid")) as rec:
        for m, c, q in _ticks(20):
            rec.record(m, c, q)
    assert len(read_recording(path).times("/joints/target")) == 20 and not partial_path(path).exists()


@pytest.mark.parametrize("content, words", [(b"", "not a readable recording"), (b"hello world" * 100, "not a readable"),
                                            ((ROOT / "README.md").read_bytes(), "not a readable recording")])
def test_what_is_not_a_recording_is_one_line(tmp_path, gait_tuner_cmd, run_env, content, words):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(content)
    r = run_cli(gait_tuner_cmd, ['log', 'info', str(bad)], run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and words in r.stderr, r.stderr


def test_simulate_records_and_log_info_says_what_it_holds(tmp_path, gait_tuner_cmd, run_env):
    r = run_cli(gait_tuner_cmd, ['simulate', '--params', 'kidsize-engine-carpet4', '--surface', 'carpet4',
                                 '--command', '0.2,0,0', '--duration', '2', '--record', str(tmp_path)], run_env)
    assert r.returncode == 0, r.stderr
    [path] = tmp_path.glob("*.mcap")
    assert f"recorded {path}" in r.stderr
    r = run_cli(gait_tuner_cmd, ['log', 'info', str(path), '--json'], run_env)
    info = json.loads(r.stdout)
    assert info["meta"]["robot"] == "kidsize" and info["meta"]["simulated"] and info["meta"]["surface"] == "carpet4"
    assert set(info["channels"]) == set(CHANNELS) and not info["truncated"]
    assert {c["messages"] for c in info["channels"].values()} == {200}
    assert all(c["rate_hz"] == pytest.approx(100.0) for c in info["channels"].values())


def test_a_joint_table_records_what_the_robot_sensed(tmp_path, capsys):
    """A table set senses nothing (the simulator may run it natively, never calling its step): its
    recording still holds every tick's encoders, IMU and sole forces, and the walk is the one
    walked without a recording (the same metrics)."""
    from tuner.cli import main
    args = ["simulate", "--params", "tkux-table2", "--surface", "rigid", "--duration", "1", "--json"]
    assert main(args) == 0
    plain = json.loads(capsys.readouterr().out)["metrics"]
    assert main(args + ["--record", str(tmp_path)]) == 0
    recorded = json.loads(capsys.readouterr().out)["metrics"]
    assert recorded == plain
    [path] = tmp_path.glob("*.mcap")
    back = read_recording(path)
    assert set(back.channels) == set(CHANNELS) - {"/walk/command"}
    assert len(back.times("/joints/measured")) == len(back.times("/joints/target")) == 100
    assert np.ptp(back.values("/joints/measured", "position"), axis=0).max() > 0.05     # the legs moved


def test_the_robot_loop_records(tmp_path):
    out = tmp_path / "loop.mcap"
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "robot_loop.py"),
                        str(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"), "--dry-run", "--seconds", "1",
                        "--record", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    back = read_recording(out)
    assert back.meta.robot == "stand-in" and len(back.times("/joints/target")) == 100


def test_robustness_records_every_walk(tmp_path, gait_tuner_cmd, run_env):
    """`robustness --record DIR`: one file per randomised walk (its rollout and push in the notes),
    each the same walk the report counts (its last tick at the walk's end, its fall included)."""
    r = run_cli(gait_tuner_cmd, ['robustness', '--params', 'kidsize-engine-carpet4', '--surface', 'carpet4',
                                 '--rollouts', '2', '--pushes', '1', '--push-rollouts', '1', '--command', '0.1,0,0',
                                 '--workers', '2', '--json', '--record', str(tmp_path / 'rec')], run_env)
    assert r.returncode == 0, r.stderr
    assert "recorded 3 walk(s) into" in r.stderr
    files = sorted((tmp_path / "rec").glob("*.mcap"))
    assert [f.name for f in files] == ["kidsize-engine-carpet4--carpet4--000.mcap",
                                       "kidsize-engine-carpet4--carpet4--001.mcap",
                                       "kidsize-engine-carpet4--carpet4--push1Ns-000.mcap"]
    report = json.loads(r.stdout)
    ends = []
    for f in files:
        rec = read_recording(f)
        assert rec.meta.task == "walk" and rec.meta.simulated and rec.meta.surface == "carpet4"
        assert "rollout" in rec.meta.notes and ("1 N s push" in rec.meta.notes) == ("push1Ns" in f.name)
        t = rec.times("/joints/target")
        assert not rec.truncated and len(t) > 100
        ends.append(t[-1])
    # the walks the report counts: as many ended early as fell
    assert sum(e < max(ends) - 0.5 for e in ends[:2]) == report["falls"]


def test_a_challenge_trial_records_its_walk(tmp_path):
    """push_trial(record=...) writes the trial's walk with its pushes named in the notes."""
    from tuner.robots import load_robot
    from tuner.params_io import resolve_drive
    from tuner.challenge.rules import push_trial
    from tuner.sim.rollout import Simulator
    from tuner.sim.surfaces import load_surface
    sim = Simulator(load_robot("kidsize"), load_surface("carpet4"), pendulum=1.5)
    drive = resolve_drive("kidsize-engine-carpet4", None)
    out = push_trial(sim, drive, 0.1, 0, pushes=[(3.0, 180.0)], record=tmp_path / "trial.mcap")
    rec = read_recording(tmp_path / "trial.mcap")
    assert rec.meta.task == "push-recovery" and "D 0.1 m" in rec.meta.notes and "180 deg" in rec.meta.notes
    t = rec.times("/joints/target")
    assert len(t) > 500 and (out["success"] or t[-1] < 6.0)


def test_a_tick_without_readings_is_a_gap(tmp_path):
    """The loop records nothing in a tick whose reading did not come (the bus late): log info names
    it (an interval of two ticks), where it said no gap before."""
    with Recorder(tmp_path / "g.mcap", RecordingMeta(robot="kid")) as rec:
        for k in [0, 1, 2, 3, 5, 6, 7, 8, 9]:
            rec.record(Measurement(k * 0.01, gyro=np.zeros(3)))
    c = recording_info(read_recording(tmp_path / "g.mcap"))["channels"]["/imu/gyro"]
    assert c["gaps"] == [(0.03, pytest.approx(0.02))]


def _crafted(path, msgs, meta_over=None):
    """A recording written by hand (an MCAP of this layout whose messages or metadata are wrong)."""
    from mcap.writer import Writer
    from gaits.robot.recorder import METADATA_NAME
    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start(profile="", library="test")
        w.add_metadata(METADATA_NAME, {**RecordingMeta(robot="kid").to_strings(), **(meta_over or {})})
        sid = w.register_schema("x", "jsonschema", b"{}")
        ids = {}
        for i, (topic, body) in enumerate(msgs):
            ids.setdefault(topic, w.register_channel(topic, "json", sid))
            w.add_message(ids[topic], log_time=i, publish_time=i, sequence=i, data=json.dumps(body).encode())
        w.finish()
    return path


_GOOD = [("/joints/measured", {"t": k * 0.01, "position": [0.0] * 20, "velocity": []}) for k in range(10)]


@pytest.mark.parametrize("msgs, meta, words", [
    ([("/joints/measured", {"t": float("nan"), "position": [0.0] * 20, "velocity": []})] + _GOOD, None,
     "channel /joints/measured, message 0: t = nan: expected a finite time"),
    ([("/joints/measured", {"t": 0.0})] + _GOOD, None, "message 0: no 'position' field"),
    ([("/joints/measured", {"t": 0.0, "position": ["a"] * 20, "velocity": []})], None,
     "position[0] = 'a': expected a number"),
    (_GOOD + [("/joints/measured", {"t": 0.2, "position": [0.0] * 3, "velocity": []})], None,
     "message 10: position has 3 values, the channel's first message 20"),
    (_GOOD + [("/joints/target", {"t": 0.0, "position": {"a": 1}})], None, "position = {'a': 1}: expected a list"),
    (_GOOD + [("/imu/gyro", {"t": 0.0, "x": "1", "y": 0, "z": 0})], None, "x = '1': expected a number"),
    (_GOOD + [("/walk/command", [1, 2])], None, "not a JSON object"),
    (_GOOD, {"joints": "5"}, "joints = 5: expected a list of names"),
    (_GOOD, {"parameters": '{"a": NaN}'}, "parameters.a = nan: expected a finite number"),
    (_GOOD, {"simulated": '"yes"'}, "simulated = 'yes': expected true or false"),
])
def test_a_recording_whose_messages_are_not_its_channels_is_one_line(tmp_path, msgs, meta, words):
    """Messages and metadata are checked as they are read (each was an internal error, or a NaN in
    --json, in log info and identify): one ValueError naming the channel, the message and the field;
    a NaN reading stays a reading (a sensor's value the robot did not get)."""
    path = _crafted(tmp_path / "r.mcap", msgs, meta)
    with pytest.raises(ValueError, match=re.escape(words)):
        read_recording(path)
    ok = _crafted(tmp_path / "ok.mcap", [("/joints/measured", {"t": 0.0, "position": [float("nan")] * 20,
                                                               "velocity": []})] + _GOOD[1:])
    assert np.isnan(read_recording(ok).values("/joints/measured", "position")[0]).all()


def test_log_info_of_a_broken_recording_is_one_line(tmp_path):
    from conftest import run_in_process
    path = _crafted(tmp_path / "r.mcap", [("/joints/measured", {"t": float("nan"), "position": [0.0] * 20,
                                                                "velocity": []})] + _GOOD)
    for extra in ([], ["--json"]):
        r = run_in_process(["log", "info", str(path), *extra])
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "t = nan" in r.stderr, r.stderr
