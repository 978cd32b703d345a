"""The robot side on a Dynamixel bus (gaits/robot/dynamixel.py, gaits/robot/loop.py) against the simulated bus
(tuner/sim/bus.py, `gait-tuner bus serve`): real Protocol 2.0 packets through dynamixel-sdk on a
pseudo-terminal, answered by MuJoCo in lockstep. Its packets, a walk, and every way the loop stops:
the watchdog, a fall, Ctrl-C, a servo missing, the wrong baud rate."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import ROOT, run_in_process
from gaits.robot.robot_file import load_robot_file
from gaits.robot.dynamixel import PING, STATUS, SYNC_WRITE, crc16, instruction_packet, parse_packet, status_packet

pytest.importorskip("dynamixel_sdk", reason="the Dynamixel driver's tests need dynamixel-sdk (the dev extra)")
MAP = ROOT / "examples" / "robots" / "kid3kg" / "kid3kg.yaml"
SET = ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"



def _served_as_read(loop_out: str, served_out: str, ticks: int) -> None:
    """The bus simulated one tick per tick of the loop's: each one the loop wrote, and each one whose
    reading failed (the loop read again without writing: the goals held), no more (not one that
    depends on how late a reply was)."""
    served = int(re.search(r"served (\d+) ticks", served_out).group(1))
    held = int(re.search(r"; (\d+) tick\(s\) the client read again", served_out).group(1)) \
        if "the client read again" in served_out else 0
    unread = int(re.search(r"(\d+) tick\(s\) without readings", loop_out).group(1))
    assert served - held == ticks and held <= unread, (loop_out, served_out)


def test_packets_as_the_protocol_writes_them():
    assert instruction_packet(1, PING).hex() == "fffffd0001030001194e"       # ROBOTIS' own example
    p, used = parse_packet(b"noise" + status_packet(7, b"\x01\x02", error=0) + b"tail")
    assert (p.id, p.instruction, p.params, p.error) == (7, STATUS, b"\x01\x02", 0) and used == 5 + 13
    stuffed = instruction_packet(3, SYNC_WRITE, b"\x74\x00\x04\x00\x03\xff\xff\xfd\x00")
    assert b"\xff\xff\xfd\xfd" in stuffed and parse_packet(stuffed)[0].params == b"\x74\x00\x04\x00\x03\xff\xff\xfd\x00"
    bad = bytearray(stuffed)
    bad[-1] ^= 0xFF                                                          # a garbled CRC: dropped
    assert parse_packet(bytes(bad))[0] is None and crc16(b"") == 0


@pytest.fixture
def robot_file(tmp_path):
    out = tmp_path / "robot.yaml"
    r = run_in_process(['robot', 'export', str(MAP), '--out', str(out)])
    assert r.returncode == 0, r.stderr
    return out


def _serve(tmp_path, *extra, robot=MAP, buses=1):
    links = [tmp_path / ("bus" if k == 0 else f"bus{k}") for k in range(buses)]
    p = subprocess.Popen([sys.executable, "-m", "tuner.cli", "bus", "serve", "--robot", str(robot), "--surface",
                          "carpet4", "--link", ",".join(map(str, links)), *extra], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    while not all(one.exists() for one in links) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(one.exists() for one in links), p.communicate(timeout=5)
    return p, ",".join(map(str, links))


def _two_buses(tmp_path):
    """kid3kg wired as Bit-Bots wire Wolfgang-OP: the legs on a second bus, Bit-Bots' IMU board
    (id 241) on it too, a BitFoot a sole on the first bus, raw cells calibrated by the map."""
    text = MAP.read_text().replace("mjcf: kid3kg.xml", f"mjcf: {MAP.parent / 'kid3kg.xml'}")
    for name in ("HipYaw", "HipRoll", "HipPitch", "Knee", "AnklePitch", "AnkleRoll"):
        for side in "LR":
            text = re.sub(rf"({name}_{side}: {{id: \d+)}}", r"\1, port: 1}", text)
    text = text.replace("soles: {protocol: bitfoot, left: 102, right: 101}",
                        "imu: {protocol: bitbots, port: 1}\n  soles: {protocol: bitfoot, left: {id: 102, zero: "
                        "[100, 100, 100, 100], newtons_per_unit: 0.5}, right: 101}")
    path = tmp_path / "two-buses.yaml"
    path.write_text(text)
    out = tmp_path / "robot2.yaml"
    r = run_in_process(['robot', 'export', str(path), '--out', str(out)])
    assert r.returncode == 0, r.stderr
    return path, out


def test_a_robot_on_two_buses_with_bitbots_boards_walks_through_them(tmp_path):
    from gaits.robot.recorder import read_recording
    robot_map, robot_file = _two_buses(tmp_path)
    rf = load_robot_file(robot_file)
    assert rf.ports == 2 and rf.imu.protocol == "bitbots" and rf.imu.id == 241 and rf.imu.port == 1
    assert rf.joints["l_knee"].servo.port == 1 and rf.joints["head_yaw"].servo.port == 0
    server, links = _serve(tmp_path, robot=robot_map, buses=2)
    # the loop is given the buses in the other order: it finds each device where it answers
    a, b = links.split(",")
    loop = _loop(robot_file, f"{b},{a}", "--seconds", "1", "--record", str(tmp_path / "walk.mcap"))
    (lo, le), (so, se) = _finish(loop, server)
    assert loop.returncode == 0, le
    ticks = int(re.search(r"(\d+) ticks on", lo).group(1))
    assert 0 < ticks <= 100 and "walked its time" in lo
    _served_as_read(lo, so, ticks)
    assert "IMU id 241 (bitbots), sole boards 102 left, 101 right (bitfoot)" in so
    rec = read_recording(tmp_path / "walk.mcap")
    force = rec.values("/feet/force", "force")
    assert np.mean(np.sum(force, axis=1)) == pytest.approx(rf.mass * 9.81, rel=0.1)     # calibrated back to N
    rpy = np.array([[r["roll"], r["pitch"]] for r in rec.channels["/imu/orientation"][1]])
    assert np.max(np.abs(rpy)) < 0.2 and np.max(np.abs(rpy)) > 0           # the quaternion read back as angles


def test_links_a_bus_at_a_time(tmp_path):
    robot_map, _ = _two_buses(tmp_path)
    r = run_in_process(["bus", "serve", "--robot", str(robot_map), "--surface", "carpet4", "--link",
                        str(tmp_path / "one"), "--wait", "1"])
    assert r.returncode == 2 and "the robot's devices are on 2 bus(es)" in r.stderr and \
        len(r.stderr.strip().splitlines()) == 1, r.stderr
    r = run_in_process(["bus", "serve", "--robot", str(robot_map), "--surface", "carpet4", "--link",
                        f"{tmp_path / 'one'},", "--wait", "1"])
    assert r.returncode == 2 and "an empty path" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def _loop(robot_file, link, *extra, **kw):
    """The loop on the bus; a watchdog of 3 s unless the test sets one (the server is another
    process: on a loaded machine it may answer a tick late, which is not what these tests are of)."""
    if "--watchdog" not in extra:
        extra = extra + ("--watchdog", "300")
    return subprocess.Popen([sys.executable, str(ROOT / "examples" / "robot_loop.py"), str(SET), "--robot",
                             str(robot_file), "--port", str(link), *extra], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _finish(*procs):
    out = []
    for p in procs:
        try:
            out.append(p.communicate(timeout=120))
        finally:
            if p.poll() is None:
                p.kill()
    return out


def test_the_loop_walks_the_simulated_robot_through_the_bus(tmp_path, robot_file):
    from gaits.robot.recorder import read_recording
    server, link = _serve(tmp_path)
    loop = _loop(robot_file, link, "--seconds", "2", "--record", str(tmp_path / "walk.mcap"))
    (lo, le), (so, se) = _finish(loop, server)
    assert loop.returncode == 0, le
    # every tick the loop read is a tick of physics and a recorded row (200 when no reading was
    # late: a loaded machine may make the server miss a tick's read, which the loop then skips, and
    # the simulation holds the goals through it)
    ticks = int(re.search(r"(\d+) ticks on", lo).group(1))
    assert 0 < ticks <= 200 and "walked its time" in lo
    _served_as_read(lo, so, ticks)
    assert "the client turned the torque off" in so, so + se
    rec = read_recording(tmp_path / "walk.mcap")
    # on the simulated bus (pseudo-terminals): the recording is of the simulator, and says so
    assert len(rec.times("/joints/target")) == ticks and rec.meta.simulated and "the simulated bus" in rec.meta.notes
    # the sole boards on the bus: what the loop read carries the robot's weight (on average over the
    # walk: the torso starts and ends at rest), each sole in turn
    force = rec.values("/feet/force", "force")
    assert force.shape == (ticks, 8) and np.all(force >= 0)
    weight = load_robot_file(robot_file).mass * 9.81
    assert np.mean(np.sum(force, axis=1)) == pytest.approx(weight, rel=0.1)
    assert np.min(np.sum(force[:, :4], axis=1)) < 0.2 * weight and np.min(np.sum(force[:, 4:], axis=1)) < 0.2 * weight


def test_the_watchdog_stops_to_the_safe_pose_when_the_bus_goes_silent(tmp_path, robot_file):
    server, link = _serve(tmp_path, "--duration", "0.5")          # the bus ends after 0.5 s of walking
    loop = _loop(robot_file, link, "--seconds", "5", "--watchdog", "5")
    (lo, le), (so, se) = _finish(loop, server)
    assert loop.returncode == 3, lo + le
    assert lo.strip().splitlines()[-1].startswith("watchdog: no readings for 5 ticks (50 ms)"), lo
    # the server ends as the walk's duration says, not in an internal error (its plan record was short)
    assert server.returncode == 0 and "ended: the walk's duration ran out; the walk: completed" in so, so + se


def test_a_robot_that_falls_stays_on_the_bus_and_the_loop_sees_the_fall(tmp_path, robot_file):
    """A 20 N s push mid-walk throws the robot down: as on a real bus its servos still answer, the
    loop's own fall stop (its IMU's tilt) ends the walk, and the server says when it fell."""
    push = tmp_path / "push.yaml"
    push.write_text("push: 20\n")
    server, link = _serve(tmp_path, "--duration", "3", "--randomisation", str(push))
    # the loop's fall stop past the simulator's 50 deg: the simulator has seen the fall when the loop
    # stops (at the same 50 deg, which of the two saw it first depends on the loop's pace, a wall clock's)
    loop = _loop(robot_file, link, "--seconds", "5", "--max-tilt", "70")
    (lo, le), (so, se) = _finish(loop, server)
    assert loop.returncode == 3 and "fall detected at t = " in lo.strip().splitlines()[-1], lo + le
    assert server.returncode == 0 and "the walk: fell at t = " in so and "the client turned the torque off" in so, \
        so + se


def test_a_fall_turns_the_torque_off(tmp_path, robot_file):
    server, link = _serve(tmp_path)
    loop = _loop(robot_file, link, "--seconds", "5", "--max-tilt", "0.5")     # any tilt reads as a fall
    (lo, le), (so, _) = _finish(loop, server)
    assert loop.returncode == 3 and "fall detected at t = " in lo.strip().splitlines()[-1], lo + le
    assert "the client turned the torque off" in so


def test_ctrl_c_stops_to_standing(tmp_path, robot_file):
    server, link = _serve(tmp_path)
    loop = _loop(robot_file, link, "--seconds", "30", "--record", str(tmp_path / "r.mcap"))
    deadline = time.monotonic() + 60
    # the loop walks once its recording is open (written beside its name until it closes)
    while not (tmp_path / "r.partial.mcap").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(1.0)
    loop.send_signal(signal.SIGINT)
    (lo, le), _ = _finish(loop, server)
    assert loop.returncode == 0, lo + le
    assert "stopped by Ctrl-C at t = " in lo and "Traceback" not in le, lo + le
    # stopped by Ctrl-C, the recording is whole and in place
    assert (tmp_path / "r.mcap").exists() and not (tmp_path / "r.partial.mcap").exists()


@pytest.mark.parametrize("edit, args, words", [
    ("id", (), "id 99 (l_knee) does not answer at 1000000 baud"),
    (None, ("--baud", "57600"), "no device answers at 57600 baud"),
])
def test_a_bus_that_is_not_the_robot_file_is_one_line(tmp_path, robot_file, edit, args, words):
    if edit == "id":
        robot_file.write_text(robot_file.read_text().replace("servo: {id: 4,", "servo: {id: 99,"))
    server, link = _serve(tmp_path, "--idle", "2")
    loop = _loop(robot_file, link, "--seconds", "1", *args)
    (lo, le), _ = _finish(loop, server)
    assert loop.returncode == 2 and len(le.strip().splitlines()) == 1 and words in le, le


def test_a_sweep_through_the_bus_on_the_hanging_robot_identifies_its_servos(tmp_path, robot_file):
    """The team's afternoon, on the simulated robot: `excite`, the loop plays the sweep through real
    packets on the robot hanging in its harness (`bus serve --hang`) and records it, and `identify
    servos` reads the map's own servos back (gain factor 1, no latency) from that recording."""
    import json
    sweep = tmp_path / "sweep.csv"
    r = run_in_process(['excite', '--robot', str(MAP), '--out', str(sweep), '--duration', '5', '--no-steps'])
    assert r.returncode == 0, r.stderr
    link = tmp_path / "bus"
    server = subprocess.Popen([sys.executable, "-m", "tuner.cli", "bus", "serve", "--robot", str(MAP), "--hang",
                               "--link", str(link)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              start_new_session=True)
    deadline = time.monotonic() + 120
    while not link.exists() and server.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert link.exists(), server.communicate(timeout=5)
    loop = subprocess.Popen([sys.executable, str(ROOT / "examples" / "robot_loop.py"), "--sweep", str(sweep),
                             "--robot", str(robot_file), "--port", str(link), "--record", str(tmp_path / "s.mcap"),
                             "--watchdog", "300"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    (lo, le), (so, se) = _finish(loop, server)
    assert loop.returncode == 0, le
    ticks = int(re.search(r"(\d+) ticks on", lo).group(1))
    _served_as_read(lo, so, ticks)
    assert "on a harness" in so, so + se
    r = run_in_process(['identify', 'servos', '--robot', str(MAP), '--recording', str(tmp_path / 's.mcap'),
                        '--out', str(tmp_path / 'fit'), '--fit', 'kp,latency', '--max-iters', '3', '--json'])
    assert r.returncode == 0, r.stderr
    p = json.loads(r.stdout)["parameters"]
    assert all(abs(p[f"{g}.kp"]["value"] - 1) < 0.03 for g in ("hips", "knees", "ankles", "arms")), p
    assert p["latency"]["value"] < 0.2


def test_a_sweep_that_is_not_one_is_one_line(tmp_path, robot_file):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,target.l_tail\n0,0\n0.01,0\n0.02,0\n")
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "robot_loop.py"), "--sweep", str(bad), "--dry-run"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "'l_tail' is not one of our joint names" in r.stderr and \
        len(r.stderr.strip().splitlines()) == 1, r.stderr
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "robot_loop.py"), str(SET), "--sweep", str(bad),
                        "--dry-run"], capture_output=True, text=True)
    assert r.returncode == 2 and "not both" in r.stderr


def test_a_randomised_walk_of_a_stream_through_the_bus(tmp_path, robot_file):
    """`bus serve --randomisation default --seed S --walk I` perturbs the robot as robustness's rollout
    I of seed S; the loop walks a stream file (--commands); the server says what the packets cost on a
    real wire."""
    stream = tmp_path / "s.csv"
    stream.write_text("t,vx,vy,wz\n0,0.1,0,0\n0.5,0,0,0.3\n")
    server, link = _serve(tmp_path, "--randomisation", "default", "--seed", "1", "--walk", "3")
    loop = _loop(robot_file, link, "--commands", str(stream))
    (lo, le), (so, se) = _finish(loop, server)
    assert loop.returncode == 0, lo + le
    ticks = int(re.search(r"(\d+) ticks on", lo).group(1))
    assert 0 < ticks <= 250 and "walked its time" in lo        # the stream's 0.5 s and its 2 s tail
    assert "randomised: seed 1, walk 3" in so, so + se
    wire = re.search(r"on the wire: (\d+) bytes a tick, ([\d.]+) ms at 1000000 baud", so)
    # a tick: a sync read of 20 servos and their 20 replies, the IMU's read and reply, a sync write
    assert wire and 500 < int(wire.group(1)) < 700 and float(wire.group(2)) == pytest.approx(
        int(wire.group(1)) * 10 / 1000, abs=0.01), so


def test_garbled_replies_end_in_the_safe_stop(tmp_path, robot_file):
    """A bus whose replies arrive garbled after 50 good ticks (a CRC that does not match): no
    reading is taken; the watchdog stops to the standing pose, torque off on every servo, one line."""
    import os
    import struct
    import threading

    from gaits.robot.dynamixel import PING, READ, SYNC_READ, WRITE, parse_packet, status_packet
    from tuner.sim.bus import open_pty
    master, slave, path = open_pty(1_000_000)
    stop = threading.Event()
    torque_off, reads = [], []

    def fake_bus():
        buf = b""
        while not stop.is_set():
            import select
            if not select.select([master], [], [], 0.05)[0]:
                continue
            try:
                buf += os.read(master, 4096)
            except OSError:
                return
            while True:
                p, used = parse_packet(buf)
                buf = buf[used:]
                if p is None:
                    break
                if p.instruction == PING:
                    os.write(master, status_packet(p.id, b"\xfc\x03\x2d"))
                elif p.instruction in (SYNC_READ, READ):
                    reads.append(p.instruction)
                    if p.instruction == SYNC_READ:
                        replies = [status_packet(sid, struct.pack("<ii", 0, 2048)) for sid in p.params[4:]]
                    else:
                        replies = [status_packet(p.id, struct.pack("<9f", 0, 0, 0, 0, 0, 0, 0, 0, 9.81))]
                    if len(reads) > 100:                      # after 50 ticks, every reply's CRC garbled
                        replies = [r[:-1] + bytes([r[-1] ^ 0xFF]) for r in replies]
                    os.write(master, b"".join(replies))
                elif p.instruction == WRITE:
                    torque_off.append(p.id)
                    os.write(master, status_packet(p.id))
    th = threading.Thread(target=fake_bus, daemon=True)
    th.start()
    try:
        loop = _loop(robot_file, path, "--seconds", "3", "--watchdog", "5")
        (lo, le), = _finish(loop)
    finally:
        stop.set()
        th.join(timeout=5)
        os.close(master)
        os.close(slave)
    assert loop.returncode == 3, lo + le
    said = lo.strip().splitlines()[-1]
    assert said.startswith("watchdog: no readings for 5 ticks (50 ms)") and "torque off" in said, lo + le
    assert sorted(set(torque_off)) == sorted(range(1, 21)) or len(set(torque_off)) == 20, torque_off


def test_duplicate_servo_ids_in_a_robot_file_are_one_line(tmp_path, robot_file):
    robot_file.write_text(robot_file.read_text().replace("servo: {id: 4,", "servo: {id: 3,"))
    loop = _loop(robot_file, tmp_path / "no-bus", "--seconds", "1")
    (lo, le), = _finish(loop)
    assert loop.returncode == 2 and len(le.strip().splitlines()) == 1, le
    assert "servo id 3 given to" in le, le


def test_a_link_onto_a_users_file_or_into_no_folder_is_one_line(tmp_path, capsys):
    """`bus serve --link PATH`: a file of the user's there is kept and named (it was deleted); a
    folder that does not exist is one line (it was an internal error)."""
    from tuner.cli import main
    mine = tmp_path / "notes.txt"
    mine.write_text("mine")
    assert main(["bus", "serve", "--robot", str(MAP), "--link", str(mine), "--idle", "0.5"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "a file of yours is there" in err and mine.read_text() == "mine"
    assert main(["bus", "serve", "--robot", str(MAP), "--link", str(tmp_path / "nope" / "bus"), "--idle", "0.5"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "does not exist" in err


def test_seed_or_walk_without_a_randomisation_is_one_line(capsys):
    """`bus serve --walk 5` / `--seed 7` without --randomisation were ignored without a word."""
    from tuner.cli import main
    for extra in (["--walk", "5"], ["--seed", "7"]):
        assert main(["bus", "serve", "--robot", str(MAP), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "give --randomisation default" in err, err


def test_the_bus_waits_for_its_first_client_then_counts_silence_from_it(robot_file, monkeypatch):
    """A person starts the loop in a second shell: before a client's first byte the bus waits
    FIRST_CLIENT_S, not --idle; once heard, --idle counts (here with no client: it says so)."""
    import os
    import tuner.sim.bus as bus
    from gaits.robot.robot_file import load_robot_file
    monkeypatch.setattr(bus, "FIRST_CLIENT_S", 0.4)
    master, slave, _ = bus.open_pty(1_000_000)
    try:
        bridge = bus.BusBridge(master, load_robot_file(robot_file), 0.01, 1_000_000, idle=0.05)
        with pytest.raises(bus.BusClosed, match=r"no client came in 0\.4 s"):
            bridge.start_pose()
        bridge.client = True                  # heard once: then silence ends it after --idle
        with pytest.raises(bus.BusClosed, match=r"silent for 0\.05 s"):
            bridge.start_pose()
    finally:
        os.close(master)
        os.close(slave)


def test_a_bus_that_has_ended_or_is_not_there_says_so(tmp_path, robot_file):
    """The loop's 'cannot open the bus' did not say the simulated bus had given up (it waits
    --wait seconds for its client): a link to a pseudo-terminal that is gone says so; a path
    that is nothing says what a bus is."""
    gone = tmp_path / "bus"
    gone.symlink_to("/dev/pts/does-not-exist")
    for port, words in ((gone, "a link to a pseudo-terminal that is gone: the simulated bus it pointed to has ended"),
                        (tmp_path / "ttyNOPE", "no such device")):
        r = subprocess.run([sys.executable, str(ROOT / "examples" / "robot_loop.py"), str(SET), "--robot",
                            str(robot_file), "--port", str(port)], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and words in r.stderr, r.stderr
