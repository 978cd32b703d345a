"""What drives the joints is one value: every walk verb uses a gait file's stabiliser, --no-stabiliser
turns it off, and a command stream is walked (planned per step by a table) and its tracking scored."""

from __future__ import annotations

import json

import numpy as np
import pytest

import gaits
from gaits import CommandStream, Drive, ParamError
from tuner.params_io import resolve_params
from tuner.robots import load_robot
from conftest import run_cli

FB = "kidsize-robust-fb-grass50"
ROBOT = load_robot("kidsize")


def run(cmd, args, env, **kw):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env, **kw)


def test_simulate_uses_the_files_stabiliser_and_no_stabiliser_turns_it_off(gait_tuner_cmd, run_env):
    on = run(gait_tuner_cmd, ["simulate", "--params", FB, "--surface", "grass50", "--duration", "6", "--json"], run_env)
    off = run(gait_tuner_cmd, ["simulate", "--params", FB, "--surface", "grass50", "--duration", "6", "--json",
                               "--no-stabiliser"], run_env)
    assert on.returncode == 0 and off.returncode == 0, on.stderr + off.stderr
    a, b = json.loads(on.stdout), json.loads(off.stdout)
    assert a["stabiliser"] is True and "with the IMU stabiliser" in a["drive"]
    assert b["stabiliser"] is False and "stabiliser" not in b["drive"]
    assert a["metrics"]["pitch_rms_deg"] < 0.8 * b["metrics"]["pitch_rms_deg"]


def test_render_and_view_use_it_too(gait_tuner_cmd, run_env, tmp_path):
    r = run(gait_tuner_cmd, ["render", "--params", FB, "--surface", "grass50", "--duration", "0.5",
                             "--out", tmp_path / "w.mp4", "--size", "160x128"], run_env)
    assert r.returncode == 0, r.stderr
    assert "with the IMU stabiliser" in r.stdout
    r = run(gait_tuner_cmd, ["render", "--params", FB, "--surface", "grass50", "--duration", "0.5",
                             "--out", tmp_path / "w.mp4", "--size", "160x128", "--no-stabiliser"], run_env)
    assert r.returncode == 0 and "stabiliser" not in r.stdout.split(";")[1], r.stdout
    # view walks the same drive, then opens its window: on a display that is not there, one line
    env = {**run_env, "DISPLAY": ":97", "MUJOCO_GL": "glfw"}
    r = run(gait_tuner_cmd, ["view", "--params", FB, "--surface", "grass50", "--duration", "0.3"], env)
    assert "with the IMU stabiliser" in r.stdout
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_stabiliser_flag_on_a_set_without_one_is_one_line(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["simulate", "--params", "tkux-table2", "--stabiliser"], run_env)
    assert r.returncode == 2 and "holds no stabiliser section" in r.stderr and len(r.stderr.splitlines()) == 1


def test_drive_resolves_the_file_once():
    gf = resolve_params(FB, None)
    d = Drive.of(gf, source=FB)
    assert d.closed_loop and d.stabiliser == gf.stabiliser
    assert not Drive.of(gf, stabiliser=False).closed_loop
    with pytest.raises(ParamError, match="holds no stabiliser"):
        Drive.of(resolve_params("tkux-table2", None), stabiliser=True)
    ctl = d.controller(ROBOT, 0.01)
    assert type(ctl).__name__ == "Stabilised" and "imu_rpy" in ctl.senses


# --- command streams -------------------------------------------------------------------------

STREAM = "t,vx,vy,wz\n0,0.1,0,0\n3,0,0,0.4\n6,0,0,0\n"


def test_a_stream_holds_each_row_until_the_next():
    s = CommandStream([0.0, 1.0, 2.5], [[0.1, 0, 0], [0, 0.05, 0], [0, 0, 0]], tail=1.0)
    assert list(s.at(0.99)) == [0.1, 0, 0] and list(s.at(1.0)) == [0, 0.05, 0] and s.duration == 3.5
    with pytest.raises(ParamError, match="row 2: t = 0 s does not come after"):
        CommandStream([0.0, 0.0], [[0, 0, 0], [0, 0, 0]])
    with pytest.raises(ParamError, match="row 1: t = 1 s; the first row must be at t = 0"):
        CommandStream([1.0], [[0, 0, 0]])
    with pytest.raises(ParamError, match="row 2: command vx = 5 m/s is out of range"):
        CommandStream([0.0, 1.0], [[0, 0, 0], [5, 0, 0]])
    with pytest.raises(ParamError, match="row 3: t = 601 s is beyond 600 s"):     # a walk of days: refused
        CommandStream([0.0, 600.0, 601.0, 1e9], np.zeros((4, 3)))
    assert CommandStream([0.0, 600.0], np.zeros((2, 3)), tail=600.0).duration == 1200.0


def test_a_stream_file_from_a_spreadsheet_loads_as_written(tmp_path):
    """A UTF-8 byte-order mark before the header (as spreadsheets write CSV) and CRLF line ends."""
    from tuner.streams import load_stream
    plain, marked = tmp_path / "plain.csv", tmp_path / "marked.csv"
    plain.write_text(STREAM)
    marked.write_bytes(b"\xef\xbb\xbf" + STREAM.replace("\n", "\r\n").encode())
    a, b = load_stream(plain), load_stream(marked)
    assert np.array_equal(a.t, b.t) and np.array_equal(a.commands, b.commands) and a.tail == b.tail


def test_a_table_walks_a_stream_planned_per_step():
    p = gaits.load_baseline("tkux-table2").params
    s = CommandStream([0.0, 3.0], [[0.05, 0, 0], [0, 0, 0]])
    d = Drive(p, stream=s)
    cmds = d.stream_commands()
    starts = gaits.step_starts(p, len(cmds))
    assert np.all(cmds[starts[:-1] < 3.0][:, 0] == 0.05) and np.all(cmds[starts[:-1] >= 3.0] == 0.0)
    traj = d.table(ROBOT, 0.01)
    assert traj.meta["stream"] == "planned per step" and "planned per step" in d.describe()


def test_simulate_a_stream_reports_its_tracking(gait_tuner_cmd, run_env, tmp_path):
    f = tmp_path / "match.csv"
    f.write_text(STREAM)
    r = run(gait_tuner_cmd, ["simulate", "--params", "kidsize-omni-carpet4", "--surface", "carpet4",
                             "--commands", f, "--duration", "1", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    tr = out["metrics"]["tracking"]
    assert out["commands"] == str(f) and "planned per step" in out["drive"]
    assert {"vx_rmse_mps", "vy_rmse_mps", "wz_rmse_radps"} <= set(tr) and tr["steps"] > 5
    assert [seg["command"] for seg in tr["segments"]] == [[0.1, 0, 0], [0, 0, 0.4], [0, 0, 0]]
    assert all(v is None or v >= 0 for v in (tr["vx_rmse_mps"], tr["vy_rmse_mps"], tr["wz_rmse_radps"]))
    for seg in tr["segments"]:                 # each measured step: its start inside the segment, the mean
        steps = seg["step_velocities"]
        assert len(steps) == seg["steps"]
        assert all(seg["t0_s"] <= row[0] <= seg["t1_s"] for row in steps)
        if steps:
            assert np.allclose(np.mean([row[1:] for row in steps], axis=0), seg["measured"], atol=1e-12)
    text = run(gait_tuner_cmd, ["simulate", "--params", "kidsize-omni-carpet4", "--surface", "carpet4",
                                "--commands", f], run_env)
    assert text.returncode == 0 and "tracking over" in text.stdout


@pytest.mark.parametrize("content, message", [
    ("", "empty"),
    ("time,vx,vy,wz\n0,0,0,0\n", "the header must be t,vx,vy,wz"),
    ("t,vx,vy,wz\n", "the header has no rows"),
    ("t,vx,vy,wz\n0,0.1,0\n", "line 2: expected 4 values"),
    ("t,vx,vy,wz\n0,a,0,0\n", "line 2: '0,a,0,0' is not four numbers"),
    ("t,vx,vy,wz\n0,0,0,0\n2,0,0,0\n1,0,0,0\n", "row 3: t = 1 s does not come after"),
    ("t,vx,vy,wz\n0,0,0,nan\n", "row 1: values must be finite"),
    ("t,vx,vy,wz\n0,0,0,0\n1e9,0,0,0\n", "row 2: t = 1e+09 s is beyond 600 s"),
])
def test_bad_stream_files_are_one_line(gait_tuner_cmd, run_env, tmp_path, content, message):
    f = tmp_path / "s.csv"
    f.write_text(content)
    r = run(gait_tuner_cmd, ["simulate", "--params", "tkux-table2", "--commands", f], run_env)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_stream_file_kinds_are_one_line(gait_tuner_cmd, run_env, tmp_path):
    import os
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    for path, message in ((tmp_path, "is a directory"), (tmp_path / "none.csv", "no such command stream file"),
                          (fifo, "is a FIFO")):
        r = run(gait_tuner_cmd, ["simulate", "--params", "tkux-table2", "--commands", path], run_env)
        assert r.returncode == 2 and message in r.stderr, r.stderr
    r = run(gait_tuner_cmd, ["simulate", "--params", "tkux-table2", "--commands", tmp_path / "x.csv",
                             "--command", "0.1,0,0"], run_env)
    assert r.returncode == 2


def test_robustness_walks_a_command(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["robustness", "--params", "kidsize-omni-carpet4", "--surface", "carpet4",
                             "--command", "0.2,0,0", "--rollouts", "2", "--pushes", "", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert "command 0.2,0,0" in out["drive"] and out["rollouts"] == 2
    r = run(gait_tuner_cmd, ["robustness", "--params", "cosine-setiono", "--command", "0,0.05,0",
                             "--rollouts", "2", "--pushes", ""], run_env)
    assert r.returncode == 2 and "forward and backward" in r.stderr


def test_a_stream_row_shorter_than_a_step_is_said_not_walked(tmp_path, gait_tuner_cmd, run_env):
    """A table plans one command per step from the row at its start: a row between two starts was
    never walked, and nothing said so."""
    stream = tmp_path / "short.csv"
    stream.write_text("t,vx,vy,wz\n0,0.1,0,0\n2.0,0.2,0,0\n2.05,0,0,0.5\n2.1,0.1,0,0\n")
    r = run_cli(gait_tuner_cmd, ["simulate", "--params", "kidsize-omni-carpet4", "--surface", "rigid",
                                         "--commands", str(stream)], run_env)
    assert r.returncode == 0, r.stderr
    assert "note: 2 row(s) of the stream last less than a step of this set and are not walked" in r.stderr
    assert "the rows at 2 s, 2.05 s" in r.stderr
    from gaits import CommandStream
    s = CommandStream([0.0, 1.0, 1.1], [[0.1, 0, 0], [0.2, 0, 0], [0.1, 0, 0]], tail=1.0)
    assert s.rows_not_walked([0.0, 0.6, 1.2, 1.8]) == [1] and s.rows_not_walked([0.0, 1.05]) == [2]
