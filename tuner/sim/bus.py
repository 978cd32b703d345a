"""A simulated Dynamixel bus (ours): the robot-side code talks real Protocol 2.0 packets to the
simulator, unchanged, through a pseudo-terminal.

:func:`serve` opens a pty pair and answers, on its master side, what the robot's servos and IMU
would: PING (every servo id of the robot file, and the IMU at ``gaits.dynamixel.IMU_ID``), READ of
the IMU's nine floats, SYNC_READ of present velocity and position (8 bytes from address 128),
SYNC_WRITE of goal positions (116), WRITE of torque enable (64). Each servo id is a simulated joint
with the robot file's units, direction and offset; the IMU's readings are the simulator's (with
its noise and latency when a randomisation is given). The simulation runs in lockstep with the
bus: a tick of physics for every sync write of goal positions (the loop's write of a tick), so
the walk is the same however fast the two processes run; the first sync write places the robot
(the loop's start pose). Foot sensors are not on the bus (a robot like the OP3 has none).

A client at another baud rate than the bus's gets no answer (as on a real bus); a packet whose CRC
does not match is ignored. The bus ends when its client has been silent for ``idle`` seconds
after it started, or has turned the torque off; before a client's first byte it waits up to ``wait``
seconds (``FIRST_CLIENT_S`` by default: a person starts the loop in another shell).
"""

from __future__ import annotations

import dataclasses
import math
import os
import select
import struct
import termios
import time
import tty
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Iterator

import numpy as np

from gaits.control import Measurement, PlanRecord, StartPose
from gaits.dynamixel import (ADDR_GOAL_POSITION, ADDR_PRESENT_VELOCITY, ADDR_TORQUE_ENABLE, IMU_BYTES, IMU_ID,
                             PING, READ, SYNC_READ, SYNC_WRITE, VELOCITY_UNIT, WRITE, parse_packet,
                             status_packet)
from gaits.robot_file import RobotFile, from_units
from gaits.trajectory import JOINT_NAMES

from .rollout import Simulator

__all__ = ["BusClosed", "BusBridge", "open_pty", "serve"]

#: model number and firmware a simulated servo answers a PING with (an XM430-W350's: 1020, 45)
MODEL, FIRMWARE = 1020, 45


class BusClosed(Exception):
    """The client went silent (or turned the torque off): the walk on the bus is over."""


def open_pty(baudrate: int) -> tuple[int, int, str]:
    """(master fd, slave fd, slave path) of a raw pseudo-terminal at ``baudrate``."""
    master, slave = os.openpty()
    tty.setraw(slave)
    attrs = termios.tcgetattr(slave)
    speed = getattr(termios, f"B{baudrate}")
    attrs[4] = attrs[5] = speed
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    return master, slave, os.ttyname(slave)


#: [s] how long the bus waits for its client's first byte (a person starting the loop by hand; ours)
FIRST_CLIENT_S = 300.0


@dataclass
class _State:
    m: Measurement | None = None
    torque: bool = True


class BusBridge:
    """The controller the simulator runs while a client drives the robot over the bus: each
    ``step`` publishes the tick's readings to the bus and returns the goal positions the client
    writes next (a :class:`gaits.control.Controller`)."""

    senses = frozenset({"q", "dq", "imu_rpy", "gyro", "accel"})

    def __init__(self, master: int, robot: RobotFile, dt: float, baudrate: int, *, idle: float = 5.0,
                 duration: float = 600.0, wait: float | None = None) -> None:
        self.master, self.robot, self.dt, self.idle = master, robot, float(dt), float(idle)
        self.wait = FIRST_CLIENT_S if wait is None else float(wait)     # [s] for the client's first byte
        self.duration = float(duration)
        self.walk_start = 0.0
        self.speed = getattr(termios, f"B{baudrate}")
        self.ids = {j.servo.id: ours for ours, j in robot.joints.items() if j.servo is not None}
        self.known = set(self.ids) | {IMU_ID}
        self.state = _State()
        self.buf = b""
        self.ticks = 0
        self.ignored = 0                  # packets at the wrong baud rate, or for no device here
        self.bytes_in = self.bytes_out = 0    # on the wire, both ways: what a real bus would carry
        self._last = np.zeros(len(JOINT_NAMES))
        self.heard = 0.0                  # when the client was last heard (time.monotonic)
        self.client = False               # a client has been heard: ``idle`` counts from then on
        # A tick of the client's is a sync read of the servos, then (its reading taken) a sync write.
        # A client whose read failed (late or garbled: a loaded machine) writes nothing that tick and
        # reads again at the next: on a robot the servos held their goal through it, so the
        # simulated robot does too, one tick per read, and the client's clock and the simulation's
        # stay one (ours; before, the simulation waited for the write and fell behind the
        # recording's clock by each tick without one)
        self.started = False              # the start pose is set
        self.ticking = False              # ... and the client's first tick written: a second read ends a tick
        self.read_this_tick = False
        self.held = 0                     # ticks the client wrote nothing (the goal held)
        self._pending: list[Any] = []     # a read that began the next tick, answered there

    # --- the controller protocol ----------------------------------------------------------
    def start_pose(self) -> StartPose:
        self._last = self._goal()
        self.started = True
        return StartPose(self._last)

    def reset(self, m: Measurement) -> None:
        self.state.m = m

    def step(self, m: Measurement, command: Any = None) -> np.ndarray:
        self.state.m = m
        self._last = self._goal()
        self.ticks += 1
        return self._last

    def plan(self, n: int) -> PlanRecord:
        # the client's plan is not on the bus: no steps planned, the walk's metrics of a stand
        return PlanRecord("bus", np.zeros(n, dtype=int), np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2)),
                          walk_start=self.walk_start, cycle_time=1.0)

    # --- the bus ---------------------------------------------------------------------------
    def _goal(self) -> np.ndarray:
        """Answer packets until a sync write of goal positions arrives; our 20 targets of it."""
        self.heard = time.monotonic()
        while True:
            if self._pending:
                packets: Any = [self._pending.pop(0)]
            else:
                packets = self._packets(self.heard, 0.3 if not self.state.torque else self.idle)
            for packet in packets:
                if packet.instruction == SYNC_READ and self.ticking and self.read_this_tick:
                    self._pending.append(packet)      # the client's next tick: this one passed, held
                    self.read_this_tick = False
                    self.held += 1
                    return self._last
                q = self._answer(packet)
                if packet.instruction == SYNC_READ:
                    self.read_this_tick = True
                if q is not None:
                    self.read_this_tick = False
                    self.ticking = self.started       # reads before the first tick's write: the client settling
                    return q

    def _packets(self, since: float, idle: float):
        ready, _, _ = select.select([self.master], [], [], 0.05)
        if not ready:
            if not self.client:           # no client yet: a person starting the loop in another shell
                if time.monotonic() - since > self.wait:
                    raise BusClosed(f"no client came in {self.wait:g} s")
                return
            if time.monotonic() - since > idle:
                raise BusClosed("the client turned the torque off" if not self.state.torque else
                                f"the client has been silent for {idle:g} s")
            return
        try:
            chunk = os.read(self.master, 4096)
        except OSError:
            raise BusClosed("the client closed the bus") from None
        # heard: a client talking, even at another baud rate or in packets for no device here, is not
        # silent (a loaded machine's client retrying its pings must not find the bus gone)
        self.heard = time.monotonic()
        self.client = True
        if termios.tcgetattr(self.master)[4] != self.speed:
            self.ignored += 1             # another baud rate: a real servo hears noise, answers nothing
            return
        self.buf += chunk
        self.bytes_in += len(chunk)
        while True:
            packet, used = parse_packet(self.buf)
            self.buf = self.buf[used:]
            if packet is None:
                return
            yield packet

    def _send(self, data: bytes) -> None:
        os.write(self.master, data)
        self.bytes_out += len(data)

    def _answer(self, p) -> np.ndarray | None:
        if p.instruction == PING and p.id in self.known:
            self._send(status_packet(p.id, struct.pack("<HB", MODEL, FIRMWARE)))
        elif p.instruction == READ and p.id == IMU_ID and len(p.params) == 4:
            m = self.state.m
            values = np.concatenate([m.imu_rpy, m.gyro, m.accel]) if m is not None else np.zeros(9)
            self._send(status_packet(IMU_ID, struct.pack("<9f", *values)[:IMU_BYTES]))
        elif p.instruction == SYNC_READ and len(p.params) >= 4:
            addr, length = struct.unpack_from("<HH", p.params)
            if addr == ADDR_PRESENT_VELOCITY and length == 8:
                for sid in p.params[4:]:
                    if sid in self.ids:
                        self._send(status_packet(sid, self._present(sid)))
        elif p.instruction == SYNC_WRITE and len(p.params) >= 4:
            addr, length = struct.unpack_from("<HH", p.params)
            if addr == ADDR_GOAL_POSITION and length == 4:
                ticks = {}
                body = p.params[4:]
                for k in range(0, len(body) - 4, 5):
                    ticks[body[k]] = struct.unpack_from("<i", body, k + 1)[0]
                return self._targets(ticks)
        elif p.instruction == WRITE and p.id in self.ids and len(p.params) >= 3:
            addr = struct.unpack_from("<H", p.params)[0]
            if addr == ADDR_TORQUE_ENABLE:
                self.state.torque = bool(p.params[2])
                self._send(status_packet(p.id))
        else:
            self.ignored += 1
        return None

    def _present(self, sid: int) -> bytes:
        """Present velocity and position of servo ``sid`` from the tick's readings (8 bytes)."""
        m, ours = self.state.m, self.ids[sid]
        j = self.robot.joints[ours]
        k = JOINT_NAMES.index(ours)
        q = np.zeros(len(JOINT_NAMES)) if m is None else m.q
        dq = 0.0 if m is None or m.dq is None else float(m.dq[k])
        pos = self.robot.to_servos(q)[sid]
        vel = int(round(j.sign * j.servo.direction * dq / VELOCITY_UNIT))
        return struct.pack("<ii", vel, pos)

    def _targets(self, ticks: dict[int, int]) -> np.ndarray:
        """Goal positions -> our 20 targets [rad] (a servo not written keeps its last target)."""
        q = self._last.copy()
        for sid, pos in ticks.items():
            ours = self.ids.get(sid)
            if ours is not None:
                j = self.robot.joints[ours]
                q[JOINT_NAMES.index(ours)] = j.sign * float(from_units(pos, j.servo))
        return q


class _FallWatch:
    """A robot that falls on a real bus lies there with its servos still answering, and the loop's
    own fall stop (its IMU's tilt) is what ends the walk: so the simulated robot is simulated on
    after a fall (the simulator's tilt and height checks off for the walk) and the first tick its
    torso passed the simulator's fall criteria is kept for the report (``t_fall`` [s])."""

    def __init__(self, sim: Simulator) -> None:
        self.sim = sim
        self.t_fall: float | None = None
        self._z_min: float | None = None

    @contextmanager
    def kept_on_the_bus(self) -> Iterator[None]:
        criteria = self.sim.fall
        self._cos_tilt = math.cos(criteria.max_tilt)
        self._ratio = criteria.min_height_ratio
        self.sim.fall = dataclasses.replace(criteria, max_tilt=math.pi)      # cos(pi) = -1: never below it
        try:
            yield
        finally:
            self.sim.fall = criteria

    def __call__(self, k: int, d: Any) -> bool:
        if self.t_fall is None:
            cos_tilt, height = self.sim.tilt_and_height(d)
            if self._z_min is None:
                self._z_min = self._ratio * height
            if cos_tilt < self._cos_tilt or height < self._z_min:
                self.t_fall = k * self.sim.control_period
        return True


def serve(sim: Any, robot: RobotFile, *, baudrate: int = 1_000_000, link: str | None = None, idle: float = 5.0,
          wait: float | None = None,
          duration: float = 600.0, perturb: Any = None, ready: Any = None) -> dict[str, Any]:
    """Serve the robot of ``sim`` on a new pty until its client stops; ``link``: a symbolic link to
    the pty's path (a fixed name for the client); ``ready(path)`` is called once it listens. Returns
    what happened: ticks walked, why it ended, the trace's outcome."""
    if link is not None:                # checked before the pty: a user's own file is never replaced
        from ..errors import UserError
        if os.path.lexists(link) and not os.path.islink(link):
            raise UserError(f"--link {link}: a file of yours is there; give a path where nothing is (the bus "
                            f"makes a symbolic link to its pseudo-terminal there, and removes it at the end)")
        if not os.path.isdir(os.path.dirname(os.path.abspath(link))):
            raise UserError(f"--link {link}: its folder {os.path.dirname(os.path.abspath(link))} does not exist")
    master, slave, path = open_pty(baudrate)
    if link is not None:
        if os.path.lexists(link):       # a link left by an earlier bus: ours to replace
            os.unlink(link)
        os.symlink(path, link)
    if ready is not None:
        ready(link or path)
    bridge = BusBridge(master, robot, sim.control_period, baudrate, idle=idle, duration=duration, wait=wait)
    why = "the walk's duration ran out"
    outcome = None
    watch = _FallWatch(sim) if isinstance(sim, Simulator) else None
    try:
        if watch is None:                 # a robot in its harness cannot fall
            trace = sim.run(bridge, duration=duration, perturb=perturb)
        else:
            with watch.kept_on_the_bus():
                trace = sim.run(bridge, duration=duration, perturb=perturb, height_check=False, on_tick=watch)
        outcome = getattr(trace, "reason", None)
    except BusClosed as exc:
        why = str(exc)
    finally:
        os.close(master)
        os.close(slave)
        if link is not None and os.path.islink(link):
            os.unlink(link)
    if watch is not None and watch.t_fall is not None:
        outcome = f"fell at t = {watch.t_fall:.2f} s (the simulator's fall criteria; served on, lying, after it)"
    # a real bus is half duplex at ``baudrate``: 10 bits a byte (start, 8 data, stop), both ways in turn
    per_tick = (bridge.bytes_in + bridge.bytes_out) / max(bridge.ticks, 1)
    return {"ticks": bridge.ticks, "held": bridge.held, "ended": why, "outcome": outcome, "ignored": bridge.ignored,
            "bytes_per_tick": per_tick, "wire_ms_per_tick": 1000.0 * 10 * per_tick / baudrate}
