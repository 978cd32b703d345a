"""EROS and the cosine law walk online commands: their own tables re-planned at each step start."""

from __future__ import annotations

import numpy as np

import gaits
from gaits import CommandStream
from gaits.control import Measurement
from gaits.online_table import OnlineTable
from tuner.robots import load_robot
from tuner.sim.cache import simulator
from tuner.sim.metrics import tracking

ROBOT = load_robot("kidsize-pd")     # the papers' walks on round one's servos (the pd law)


def _controller(name: str) -> OnlineTable:
    p = gaits.load_baseline(name).params
    return OnlineTable(p, ROBOT, 0.01, gaits.family_of(p).step_limits(p, ROBOT))


def _targets(ctl: OnlineTable, commands) -> np.ndarray:
    ctl.start_pose()
    ctl.reset(Measurement(0.0))
    return np.array([ctl.step(Measurement(i * 0.01), c).copy() for i, c in enumerate(commands)])


def test_the_generators_are_causal_so_a_replan_continues_what_was_sent():
    """A command changed at tick k leaves every target before k as it was (the re-planned table
    agrees with the one it replaces up to the step start)."""
    for name in ("eros-x8-with", "cosine-setiono"):
        k = 450
        base = [np.array([0.03, 0.0, 0.0])] * 900
        other = base[:k] + [np.array([-0.02, 0.0, 0.0])] * (900 - k)
        a, b = _targets(_controller(name), base), _targets(_controller(name), other)
        assert np.array_equal(a[:k], b[:k]), name
        assert not np.allclose(a[k:], b[k:]), name
        assert np.max(np.abs(np.diff(b, axis=0))) < 0.2, name          # no jump at a re-plan


def test_eros_walks_an_online_stream_and_stands_after_it():
    ctl = _controller("eros-x8-with")
    stream = CommandStream([0.0, 4.0, 8.0], [[0.04, 0, 0], [0.0, 0, 0.15], [0, 0, 0]], tail=6.0)
    trace = simulator(ROBOT, "carpet4").run(ctl, commands=stream, duration=stream.duration)
    assert trace.completed and ctl.replans > 5
    tk = tracking(trace, stream, np.array(ctl.step_starts))
    fwd, turn = tk["segments"][0]["measured"], tk["segments"][1]["measured"]
    assert 0.03 < fwd[0] < 0.06 and turn[2] > 0.1
    assert not ctl._walking                                           # the walk ended standing


def test_a_gait_file_engine_section_walks_eros_online(tmp_path):
    import yaml
    doc = yaml.safe_load((gaits.baselines.BASELINE_DIR / "eros-x8-with.yaml").read_text())
    doc["engine"] = {"preview_steps": 2}
    path = tmp_path / "eros-online.yaml"
    path.write_text(yaml.safe_dump(doc))
    drive = gaits.Drive.of(gaits.load_gait_file(path))
    assert drive.online and "online table" in drive.describe()
    assert isinstance(drive.controller(ROBOT, 0.01), OnlineTable)
