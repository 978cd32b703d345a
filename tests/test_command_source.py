"""Where the robot's loop takes its walk command (gaits/robot/command_source.py): a function, a stream
file, a UDP/JSON socket on the loopback; and a controller on a robot without foot sensors
(gaits.control.WithoutReadings, a map's foot_sensors: false)."""

from __future__ import annotations

import json
import socket
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, run_in_process
from gaits import ParamError
from gaits.robot.command_source import FromStream, Scripted, UdpCommands, parse_udp_address
from gaits.control import Measurement, WithoutReadings

STREAM = ROOT / "examples" / "streams" / "match-carpet4.csv"
SET = ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"


def test_a_stream_holds_each_row_then_stops():
    src = FromStream(STREAM)
    rows = np.loadtxt(STREAM, delimiter=",", comments="#", skiprows=3)
    assert np.array_equal(src(rows[1, 0]), rows[1, 1:]) and np.array_equal(src(rows[1, 0] - 1e-3), rows[0, 1:])
    assert src.duration == rows[-1, 0] + 2.0 and np.array_equal(src(src.duration), np.zeros(3))
    assert np.array_equal(Scripted(lambda t: (t, 0, 0))(0.5), [0.5, 0, 0])


def test_udp_commands_newest_wins_bad_ones_counted_silence_stops():
    src = UdpCommands(port=0, timeout=0.5)
    try:
        assert src.host == "127.0.0.1"                       # the loopback unless named otherwise
        out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for msg in (b'{"vx": 0.1}', b"not json", b'{"vx": NaN}', b'{"speed": 1}', b'[1, 2]',
                    json.dumps({"vx": 0.2, "wz": -0.5}).encode()):
            out.sendto(msg, ("127.0.0.1", src.port))
        out.close()
        got = np.zeros(3)
        for _ in range(200):                                # the datagrams are on the loopback: no waiting on time
            got = src(1.0)
            if src.received + src.rejected == 6:
                break
        assert np.array_equal(got, [0.2, 0.0, -0.5]) and src.received == 2 and src.rejected == 4
        assert np.array_equal(src(1.5), [0.2, 0.0, -0.5])   # within the timeout: held
        assert np.array_equal(src(1.51), np.zeros(3))       # silent past it: a stop
    finally:
        src.close()


@pytest.mark.parametrize("text, words", [("abc", "expected PORT or HOST:PORT"), ("70000", "[1, 65535]"),
                                         ("host:", "expected PORT")])
def test_udp_address_mistakes_are_named(text, words):
    with pytest.raises(ParamError, match=words.replace("[", r"\[").replace("]", r"\]")):
        parse_udp_address(text)
    assert parse_udp_address("5005") == ("127.0.0.1", 5005) and parse_udp_address("0.0.0.0:7") == ("0.0.0.0", 7)


def test_the_loop_walks_a_stream_and_refuses_two_sources():
    r = subprocess.run([sys.executable, "-m", "gaits.robot.loop", str(SET), "--dry-run", "--commands", str(STREAM)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[-1].startswith("2100 ticks: ") and "ended stand" in r.stdout
    r = subprocess.run([sys.executable, "-m", "gaits.robot.loop", str(SET), "--dry-run", "--commands", str(STREAM),
                        "--udp", "5005"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and r.stderr.strip() == "robot_loop: error: give --commands or --udp, not both"


class _Sees:
    senses = frozenset({"q", "foot_force"})

    def step(self, m, command=None):
        return m


def test_without_readings_takes_them_out_of_what_the_controller_senses():
    c = WithoutReadings(_Sees(), ("foot_force",))
    assert c.senses == {"q"} and c.step(Measurement(0.0)) is not None
    with pytest.raises(ValueError, match="unknown readings"):
        WithoutReadings(_Sees(), ("sonar",))


def test_a_robot_without_foot_sensors_gives_its_controller_none(tmp_path):
    """A map's foot_sensors: false: the simulator's readings carry no foot_force; the robot file says so."""
    import test_urdf as U
    from gaits.robot.robot_file import load_robot_file
    from tuner.robots import load_robot
    from tuner.sim.rollout import Simulator
    from tuner.sim.sensors import SensorReader
    from tuner.sim.surfaces import load_surface
    path = U.workspace(tmp_path, U.mesh_urdf(), extra="foot_sensors: false\n")
    robot = load_robot(str(path))
    assert not robot.foot_sensors
    sim = Simulator(robot, load_surface("rigid"))
    assert SensorReader(sim, None).read(0.0).foot_force is None
    with_feet = Simulator(load_robot(str(U.workspace(tmp_path / "b", U.mesh_urdf()))), load_surface("rigid"))
    assert SensorReader(with_feet, None).read(0.0).foot_force.shape == (8,)
    out = tmp_path / "robot.yaml"
    r = run_in_process(['robot', 'export', str(path), '--out', str(out)])
    assert r.returncode == 0, r.stderr
    assert load_robot_file(out).foot_sensors is False
    bad = U.workspace(tmp_path / "c", U.mesh_urdf(), extra="foot_sensors: 0\n")
    from tuner.errors import UserError
    with pytest.raises(UserError, match="foot_sensors = 0: expected true"):
        load_robot(str(bad))
