"""A simulated Dynamixel bus (ours): the robot-side code talks real Protocol 2.0 packets to the
simulator, unchanged, through a pseudo-terminal.

:func:`serve` opens a pty pair a bus (the robot file's ``port`` of each device) and answers, on
each master side, what the devices on that bus would: PING (every servo id, the IMU, the sole
boards), READ of the IMU's registers in its protocol (ours: nine floats; Bit-Bots' board: ten, its
orientation a quaternion) and of each sole board's four cells (BitFoot, through the file's
calibration), SYNC_READ of present velocity and position (8 bytes from address 128), SYNC_WRITE of
goal positions (116), WRITE of torque enable (64). Each servo id is a simulated joint with the robot
file's units, direction and offset; the IMU's and the soles' readings are the simulator's (with its
noise and latency when a randomisation is given; the soles only where the robot file says they
sense force). The simulation runs in lockstep with the bus: a tick of physics for every tick's sync
writes of goal positions (one a bus with servos), so the walk is the same however fast the two
processes run; the first places the robot (the loop's start pose).

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
from gaits.robot.dynamixel import (ADDR_GOAL_POSITION, ADDR_PRESENT_VELOCITY, ADDR_TORQUE_ENABLE, IMU_REGISTERS,
                             PING, READ, SOLE_REGISTERS, SYNC_READ, SYNC_WRITE, VELOCITY_UNIT, WRITE, imu_registers,
                             parse_packet, status_packet)
from gaits.robot.robot_file import RobotFile, from_units
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
    writes next (a :class:`gaits.control.Controller`). ``masters``: one pty master a bus (the robot
    file's ports)."""

    def __init__(self, masters: int | list[int], robot: RobotFile, dt: float, baudrate: int, *, idle: float = 5.0,
                 duration: float = 600.0, wait: float | None = None) -> None:
        self.masters = [masters] if isinstance(masters, int) else list(masters)
        self.robot, self.dt, self.idle = robot, float(dt), float(idle)
        self.wait = FIRST_CLIENT_S if wait is None else float(wait)     # [s] for the client's first byte
        self.duration = float(duration)
        self.walk_start = 0.0
        self.speed = getattr(termios, f"B{baudrate}")
        self.ids = {j.servo.id: ours for ours, j in robot.joints.items() if j.servo is not None}
        # each device answers on its own bus only (the robot file's ports)
        self.on_port: list[set[int]] = [set() for _ in self.masters]
        for ours, j in robot.joints.items():
            if j.servo is not None:
                self.on_port[j.servo.port].add(j.servo.id)
        if robot.imu is not None:
            self.on_port[robot.imu.port].add(robot.imu.id)
        self.soles = {b.id: (side, b) for side, b in enumerate(robot.soles or ())} if robot.foot_sensors else {}
        for _, b in self.soles.values():
            self.on_port[b.port].add(b.id)
        self.servo_ports = [k for k, ids in enumerate(self.on_port) if ids & set(self.ids)]
        self.first = self.servo_ports[0] if self.servo_ports else 0
        self.senses = frozenset({"q", "dq", "imu_rpy", "gyro", "accel"} | ({"foot_force"} if self.soles else set()))
        self.state = _State()
        self.bufs = [b"" for _ in self.masters]
        self.ticks = 0
        self.ignored = 0                  # packets at the wrong baud rate, or for no device here
        self.bytes_on = [0 for _ in self.masters]   # on each wire, both ways: what a real bus would carry
        self._last = np.zeros(len(JOINT_NAMES))
        self.heard = 0.0                  # when the client was last heard (time.monotonic)
        self.client = False               # a client has been heard: ``idle`` counts from then on
        # A tick of the client's is a sync read of the servos, then (its reading taken) a sync write,
        # a bus after another on a robot with several. A client whose read failed (late or garbled: a
        # loaded machine) writes nothing that tick and reads again at the next: on a robot the servos
        # held their goal through it, so the simulated robot does too, one tick per read, and the
        # client's clock and the simulation's stay one (ours; before, the simulation waited for the
        # write and fell behind the recording's clock by each tick without one)
        self.started = False              # the start pose is set
        self.ticking = False              # ... and the client's first tick written: a second read ends a tick
        self.read_this_tick = False
        self.held = 0                     # ticks the client wrote nothing (the goals held)
        self._pending: list[Any] = []     # a read that began the next tick, answered there
        self._written: dict[int, int] = {}    # goals written this tick (servo id -> position)
        self._wrote: set[int] = set()         # ... on these buses

    @property
    def busiest_bytes(self) -> int:
        """Bytes on the busiest wire, both ways (several buses carry theirs at once)."""
        return max(self.bytes_on)

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
    def _end_tick(self) -> np.ndarray:
        q = self._targets(self._written)
        self._written, self._wrote = {}, set()
        return q

    def _goal(self) -> np.ndarray:
        """Answer packets until the tick's sync writes of goal positions have arrived (one a bus with
        servos); our 20 targets of them."""
        self.heard = time.monotonic()
        while True:
            if self._pending:
                packets: Any = [self._pending.pop(0)]
            else:
                packets = self._packets(self.heard, 0.3 if not self.state.torque else self.idle)
            for k, packet in packets:
                if packet.instruction == SYNC_READ and k == self.first and self.ticking and self.read_this_tick:
                    self._pending.append((k, packet))   # the client's next tick: this one passed, held
                    self.read_this_tick = False
                    self.held += not self._wrote
                    return self._end_tick()
                ticks = self._answer(k, packet)
                if packet.instruction == SYNC_READ and k == self.first:
                    self.read_this_tick = True
                if ticks is not None:
                    self._written.update(ticks)
                    self._wrote.add(k)
                    if self._wrote >= set(self.servo_ports):
                        self.read_this_tick = False
                        self.ticking = self.started       # reads before the first tick's write: the client settling
                        return self._end_tick()

    def _packets(self, since: float, idle: float):
        ready, _, _ = select.select(self.masters, [], [], 0.05)
        if not ready:
            if not self.client:           # no client yet: a person starting the loop in another shell
                if time.monotonic() - since > self.wait:
                    raise BusClosed(f"no client came in {self.wait:g} s")
                return
            if time.monotonic() - since > idle:
                raise BusClosed("the client turned the torque off" if not self.state.torque else
                                f"the client has been silent for {idle:g} s")
            return
        for master in ready:
            k = self.masters.index(master)
            try:
                chunk = os.read(master, 4096)
            except OSError:
                raise BusClosed("the client closed the bus") from None
            # heard: a client talking, even at another baud rate or in packets for no device here, is
            # not silent (a loaded machine's client retrying its pings must not find the bus gone)
            self.heard = time.monotonic()
            self.client = True
            if termios.tcgetattr(master)[4] != self.speed:
                self.ignored += 1         # another baud rate: a real servo hears noise, answers nothing
                continue
            self.bufs[k] += chunk
            self.bytes_on[k] += len(chunk)
            while True:
                packet, used = parse_packet(self.bufs[k])
                self.bufs[k] = self.bufs[k][used:]
                if packet is None:
                    break
                yield k, packet

    def _send(self, k: int, data: bytes) -> None:
        os.write(self.masters[k], data)
        self.bytes_on[k] += len(data)

    def _answer(self, k: int, p) -> dict[int, int] | None:
        here = self.on_port[k]
        m = self.state.m
        imu = self.robot.imu
        if p.instruction == PING and p.id in here:
            self._send(k, status_packet(p.id, struct.pack("<HB", MODEL, FIRMWARE)))
        elif p.instruction == READ and imu is not None and p.id == imu.id and p.id in here and \
                struct.unpack_from("<HH", p.params.ljust(4, b"\0")) == IMU_REGISTERS[imu.protocol]:
            z = np.zeros(3)
            self._send(k, status_packet(p.id, imu_registers(imu.protocol, *(
                (m.imu_rpy, m.gyro, m.accel) if m is not None and m.imu_rpy is not None else (z, z, z)))))
        elif p.instruction == READ and p.id in self.soles and p.id in here and \
                struct.unpack_from("<HH", p.params.ljust(4, b"\0")) == SOLE_REGISTERS[self.robot.sole_protocol]:
            side, board = self.soles[p.id]
            force = np.zeros(4) if m is None or m.foot_force is None else m.foot_force[4 * side:4 * side + 4]
            self._send(k, status_packet(p.id, np.asarray(board.raw(force), dtype="<f4").tobytes()))
        elif p.instruction == SYNC_READ and len(p.params) >= 4:
            addr, length = struct.unpack_from("<HH", p.params)
            if addr == ADDR_PRESENT_VELOCITY and length == 8:
                # the tick's angles in every servo's units once (not once a servo asked); the
                # encoders in our 20 roles' order (a robot maps fewer, or more: its extra joints)
                q = np.zeros(len(JOINT_NAMES)) if m is None else m.in_our_order(m.q)
                dq = None if m is None or m.dq is None else m.in_our_order(m.dq)
                positions = self.robot.to_servos(q)
                for sid in p.params[4:]:
                    if sid in self.ids and sid in here:
                        self._send(k, status_packet(sid, self._present(sid, positions[sid], dq)))
        elif p.instruction == SYNC_WRITE and len(p.params) >= 4:
            addr, length = struct.unpack_from("<HH", p.params)
            if addr == ADDR_GOAL_POSITION and length == 4:
                ticks = {}
                body = p.params[4:]
                for i in range(0, len(body) - 4, 5):
                    if body[i] in here:
                        ticks[body[i]] = struct.unpack_from("<i", body, i + 1)[0]
                return ticks
        elif p.instruction == WRITE and p.id in self.ids and p.id in here and len(p.params) >= 3:
            addr = struct.unpack_from("<H", p.params)[0]
            if addr == ADDR_TORQUE_ENABLE:
                self.state.torque = bool(p.params[2])
                self._send(k, status_packet(p.id))
        else:
            self.ignored += 1
        return None

    def _present(self, sid: int, pos: int, dq_ours: np.ndarray | None) -> bytes:
        """Present velocity and position (``pos``, its units) of servo ``sid`` from the tick's
        readings (8 bytes); ``dq_ours`` the encoders' rates in ``JOINT_NAMES`` order."""
        ours = self.ids[sid]
        j = self.robot.joints[ours]
        dq = 0.0 if dq_ours is None else float(dq_ours[JOINT_NAMES.index(ours)])
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
        self.start_xy: np.ndarray | None = None     # [m] the torso on the ground, first tick and last
        self.end_xy: np.ndarray | None = None
        self.ticks = 0

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
        xy = np.array(d.xpos[self.sim._torso][:2])
        if self.start_xy is None:
            self.start_xy = xy
        if self.t_fall is None:
            self.end_xy, self.ticks = xy, k + 1
            cos_tilt, height = self.sim.tilt_and_height(d)
            if self._z_min is None:
                self._z_min = self._ratio * height
            if cos_tilt < self._cos_tilt or height < self._z_min:
                self.t_fall = k * self.sim.control_period
        return True

    def travel(self) -> tuple[float, float] | None:
        """(how far the torso went on the ground [m], its mean speed [m/s]) until the end or the fall;
        None before a tick."""
        if self.start_xy is None or self.end_xy is None or self.ticks == 0:
            return None
        d = float(np.hypot(*(self.end_xy - self.start_xy)))
        return d, d / (self.ticks * self.sim.control_period)


def serve(sim: Any, robot: RobotFile, *, baudrate: int = 1_000_000, link: str | list[str] | None = None,
          idle: float = 5.0, wait: float | None = None,
          duration: float = 600.0, perturb: Any = None, ready: Any = None) -> dict[str, Any]:
    """Serve the robot of ``sim`` on new ptys (one a bus: the robot file's ports) until its client
    stops; ``link``: symbolic links to the ptys' paths, one a bus (fixed names for the client);
    ``ready(paths)`` is called once it listens. Returns what happened: ticks walked, why it ended,
    the trace's outcome, how far the torso went."""
    from ..errors import UserError
    links = [] if link is None else [link] if isinstance(link, str) else list(link)
    if any(not one for one in links):
        raise UserError(f"--link {','.join(links)!r}: an empty path; give one path a bus, comma-separated")
    if links and len(links) != robot.ports:
        raise UserError(f"--link {','.join(links)}: the robot's devices are on {robot.ports} bus(es) (their port: in "
                        f"the map), so give {robot.ports} link(s), one a bus")
    for one in links:                   # checked before the pty: a user's own file is never replaced
        if os.path.lexists(one) and not os.path.islink(one):
            raise UserError(f"--link {one}: a file of yours is there; give a path where nothing is (the bus "
                            f"makes a symbolic link to its pseudo-terminal there, and removes it at the end)")
        if not os.path.isdir(os.path.dirname(os.path.abspath(one))):
            raise UserError(f"--link {one}: its folder {os.path.dirname(os.path.abspath(one))} does not exist")
    if len(set(links)) != len(links):
        raise UserError(f"--link {','.join(links)}: give each bus its own path")
    ptys = [open_pty(baudrate) for _ in range(robot.ports)]
    for one, (_, _, path) in zip(links, ptys):
        if os.path.lexists(one):        # a link left by an earlier bus: ours to replace
            os.unlink(one)
        os.symlink(path, one)
    if ready is not None:
        ready(links or [path for _, _, path in ptys])
    bridge = BusBridge([master for master, _, _ in ptys], robot, sim.control_period, baudrate, idle=idle,
                       duration=duration, wait=wait)
    why = "the walk's duration ran out"
    outcome = None
    trace = None
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
        for master, slave, _ in ptys:
            os.close(master)
            os.close(slave)
        for one in links:
            if os.path.islink(one):
                os.unlink(one)
    if watch is not None and watch.t_fall is not None:
        outcome = f"fell at t = {watch.t_fall:.2f} s (the simulator's fall criteria; served on, lying, after it)"
    # a real bus is half duplex at ``baudrate``: 10 bits a byte (start, 8 data, stop), both ways in turn
    per_tick = bridge.busiest_bytes / max(bridge.ticks, 1)
    return {"ticks": bridge.ticks, "held": bridge.held, "ended": why, "outcome": outcome, "ignored": bridge.ignored,
            "bytes_per_tick": per_tick, "wire_ms_per_tick": 1000.0 * 10 * per_tick / baudrate,
            "travel": None if watch is None else watch.travel()}
