"""Dynamixel Protocol 2.0 on the robot side (ours, from ROBOTIS' protocol description): the packet
codec, the control-table addresses the walk uses, and the bus driver the loop runs.

A packet is ``FF FF FD 00 | id | length (2, LE) | instruction | parameters | CRC-16 (2, LE)``, the
length counting the instruction, the parameters and the CRC; inside, every ``FF FF FD`` is stuffed
with a ``FD``; the CRC (polynomial 0x8005, initial 0) covers everything before it. A status packet
has the instruction 0x55 and an error byte before its parameters.

:class:`DynamixelBus` is the driver (``dynamixel-sdk``: ``PortHandler``, ``PacketHandler(2.0)``,
``GroupSyncRead`` of present velocity and position, 8 bytes from address 128, and
``GroupSyncWrite`` of goal positions, 4 bytes at 116), with the ids, units, directions and offsets
of the robot file. The boards besides the servos are the robot file's ``bus:`` (:data:`IMU_REGISTERS`,
:data:`SOLE_REGISTERS`, each a READ of one block):

* the IMU, ``gait-tuner`` (ours: id 200, nine little-endian float32 from address 0: roll, pitch, yaw
  [rad], gyro x, y, z [rad/s], accelerometer x, y, z [m/s^2]) or ``bitbots`` (Bit-Bots' IMU board,
  as their ``bitbots_ros_control`` reads it: ten float32 from address 36: gyro x, y, z, accelerometer
  x, y, z, orientation quaternion x, y, z, w; a zero quaternion is no reading yet); none at all when
  the file says ``imu: null``;
* the sole boards, ``bitfoot`` (Bit-Bots' BitFoot: four float32 from address 36, its load cells
  front left, front right, back left, back right, raw: the file's ``zero`` and
  ``newtons_per_unit`` make them newtons), read when the file's soles sense force.

A robot on several buses gives every port; :meth:`DynamixelBus.check` finds each device on the port
where it answers, and each tick reads and writes each port in turn.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..control import rpy_from_quat
from ..params import ParamError
from ..trajectory import JOINT_NAMES

__all__ = ["crc16", "stuff", "unstuff", "instruction_packet", "status_packet", "parse_packet", "Packet",
           "PING", "READ", "WRITE", "SYNC_READ", "SYNC_WRITE", "STATUS", "ADDR_GOAL_POSITION",
           "ADDR_PRESENT_VELOCITY", "ADDR_PRESENT_POSITION", "VELOCITY_UNIT", "IMU_ID", "IMU_BYTES",
           "IMU_REGISTERS", "SOLE_REGISTERS", "DynamixelBus", "BusError", "imu_reading", "imu_registers"]

PING, READ, WRITE, SYNC_READ, SYNC_WRITE, STATUS = 0x01, 0x02, 0x03, 0x82, 0x83, 0x55
ADDR_TORQUE_ENABLE = 64
ADDR_GOAL_POSITION = 116          # 4 bytes
ADDR_PRESENT_VELOCITY = 128       # 4 bytes, signed, units of VELOCITY_UNIT
ADDR_PRESENT_POSITION = 132       # 4 bytes
VELOCITY_UNIT = 0.229 * 2 * np.pi / 60     # [rad/s] per unit (0.229 rpm, X series)
IMU_ID = 200                      # ours: the IMU board on the bus
IMU_BYTES = 36                    # nine float32
#: (address, bytes) of the block an IMU board of each protocol is read from
IMU_REGISTERS = {"gait-tuner": (0, IMU_BYTES), "bitbots": (36, 40)}
#: (address, bytes) of a sole board's four cells
SOLE_REGISTERS = {"bitfoot": (36, 16)}
HEADER = b"\xff\xff\xfd\x00"

_CRC_TABLE = []
for _i in range(256):
    _c = _i << 8
    for _ in range(8):
        _c = ((_c << 1) ^ 0x8005) if _c & 0x8000 else (_c << 1)
    _CRC_TABLE.append(_c & 0xFFFF)


def crc16(data: bytes) -> int:
    """Protocol 2.0's CRC-16 (polynomial 0x8005, initial value 0, not reflected)."""
    crc = 0
    for b in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ b) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Byte stuffing of the instruction and parameters: FF FF FD -> FF FF FD FD."""
    return body.replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")


def unstuff(body: bytes) -> bytes:
    return body.replace(b"\xff\xff\xfd\xfd", b"\xff\xff\xfd")


def _packet(dxl_id: int, body: bytes) -> bytes:
    body = stuff(body)
    head = HEADER + bytes([dxl_id]) + struct.pack("<H", len(body) + 2)
    out = head + body
    return out + struct.pack("<H", crc16(out))


def instruction_packet(dxl_id: int, instruction: int, params: bytes = b"") -> bytes:
    return _packet(dxl_id, bytes([instruction]) + params)


def status_packet(dxl_id: int, params: bytes = b"", error: int = 0) -> bytes:
    return _packet(dxl_id, bytes([STATUS, error]) + params)


@dataclass(frozen=True)
class Packet:
    """A packet read from the bus: its id, instruction, (status: error,) parameters."""

    id: int
    instruction: int
    params: bytes
    error: int = 0


def parse_packet(buf: bytes) -> tuple[Packet | None, int]:
    """The first whole packet in ``buf`` and the bytes it used (skipping garbage before a header);
    (None, bytes to drop) when none is whole yet. A packet whose CRC does not match is dropped
    (its header skipped), as a servo ignores it."""
    start = buf.find(HEADER)
    if start < 0:
        return None, max(0, len(buf) - 3)
    if len(buf) < start + 7:
        return None, start
    length = struct.unpack_from("<H", buf, start + 5)[0]
    end = start + 7 + length
    if length < 3 or length > 1024:
        return None, start + 4
    if len(buf) < end:
        return None, start
    crc = struct.unpack_from("<H", buf, end - 2)[0]
    if crc16(buf[start:end - 2]) != crc:
        return None, start + 4
    body = unstuff(buf[start + 8:end - 2])
    inst = buf[start + 7]
    if inst == STATUS:
        return Packet(buf[start + 4], inst, body[1:], body[0] if body else 0), end
    return Packet(buf[start + 4], inst, body), end


class BusError(ParamError):
    """The bus is not what the robot file says (a servo that does not answer, the wrong baud rate,
    a packet it cannot read): one line naming the port, the id and what happened."""


class DynamixelBus:
    """The robot's servos, IMU and sole boards through ``dynamixel-sdk`` (module docstring), on one
    port or several (``port``: a path or a list of them). ``robot``: a
    :class:`gaits.robot.robot_file.RobotFile` (every driven joint has a servo id; its ``imu`` and ``soles``
    say which boards to read)."""

    def __init__(self, port: str | Sequence[str], robot: Any, baudrate: int = 1_000_000) -> None:
        try:
            import dynamixel_sdk as sdk
        except ImportError:
            raise BusError("the Dynamixel driver needs dynamixel-sdk: pip install dynamixel-sdk") from None
        names = [port] if isinstance(port, str) else list(port)
        if not names or len(set(names)) != len(names):
            raise BusError(f"--port {','.join(names)}: give each bus once")
        self.sdk, self.robot, self.baudrate = sdk, robot, int(baudrate)
        self.port_name = ",".join(names)
        self.joints = [(ours, j) for ours, j in robot.joints.items() if j.servo is not None]
        if len(self.joints) != len(robot.joints):
            missing = [o for o, j in robot.joints.items() if j.servo is None]
            raise BusError(f"{self.port_name}: the robot file gives no servo id to {', '.join(missing)}")
        gap = robot.sensing_gap()
        if gap is not None:
            raise BusError(f"{robot.robot}: {gap}")
        self.names, self.ports = names, []
        for name in names:
            handle = sdk.PortHandler(name)
            try:
                opened = handle.openPort() and handle.setBaudRate(self.baudrate)
            except Exception as exc:  # noqa: BLE001 - pyserial's errors are many kinds
                self.close()
                raise BusError(f"{name}: cannot open the bus ({' '.join(str(exc).split())})" + _why_gone(name)) from None
            self.ports.append(handle)
            if not opened:
                self.close()
                raise BusError(f"{name}: cannot open the bus at {self.baudrate} baud")
        self.packets = sdk.PacketHandler(2.0)
        self._by_id = {j.servo.id: (JOINT_NAMES.index(ours), j) for ours, j in self.joints}
        self.where = {dxl_id: 0 for dxl_id in robot.devices()}      # id -> port index, set by check()
        self._groups()

    def _groups(self) -> None:
        """One sync read and one sync write a port, over the servos found on it."""
        self._reads, self._writes = [], []
        for k, handle in enumerate(self.ports):
            ids = [j.servo.id for _, j in self.joints if self.where[j.servo.id] == k]
            if not ids:
                continue
            read = self.sdk.GroupSyncRead(handle, self.packets, ADDR_PRESENT_VELOCITY, 8)
            for sid in ids:
                read.addParam(sid)
            self._reads.append((read, ids))
            self._writes.append((self.sdk.GroupSyncWrite(handle, self.packets, ADDR_GOAL_POSITION, 4), set(ids)))

    def check(self, attempts: int = 3) -> None:
        """Find every device of the robot file (servos, the IMU, the sole boards) on the ports: each
        is pinged on each port, up to ``attempts`` times (a reply lost to noise on the bus, or late
        from a busy simulated one, is not a missing device), and used on the port where it answers
        (as Bit-Bots' driver finds a robot's servos on its four buses). One that never answers is
        one line naming it."""
        devices = self.robot.devices()
        silent = []
        for dxl_id in devices:
            for _ in range(attempts):
                found = next((k for k, handle in enumerate(self.ports)
                              if self.packets.ping(handle, dxl_id)[1] == self.sdk.COMM_SUCCESS), None)
                if found is not None:
                    self.where[dxl_id] = found
                    break
            else:
                silent.append(dxl_id)
        on = "" if len(self.ports) == 1 else f" on any of the {len(self.ports)} buses"
        if silent and len(silent) == len(devices):
            raise BusError(f"{self.port_name}: no device answers at {self.baudrate} baud (ids "
                           f"{', '.join(map(str, devices))}): is the bus at another baud rate, or powered off?")
        if silent:
            what = devices[silent[0]]
            raise BusError(f"{self.port_name}: id {silent[0]} ({what}) does not answer at {self.baudrate} baud{on}" +
                           (f" (and {len(silent) - 1} more)" if len(silent) > 1 else ""))
        self._groups()

    def read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray | None,
                            np.ndarray | None] | None:
        """(q, dq) in our convention [rad, rad/s], then (rpy, gyro, accel) with an IMU and the eight sole
        forces [N] with sole boards (None without); None when a device did not answer this tick, or
        a port is gone (the loop's watchdog counts it)."""
        try:
            return self._read_once()
        except Exception:  # noqa: BLE001 - a port gone (unplugged, closed) raises pyserial's or the OS's errors
            return None

    def _block(self, dxl_id: int, register: tuple[int, int]) -> bytes | None:
        addr, length = register
        data, result, _ = self.packets.readTxRx(self.ports[self.where[dxl_id]], dxl_id, addr, length)
        return bytes(data) if result == self.sdk.COMM_SUCCESS and len(data) == length else None

    def _read_once(self):
        ticks = {}
        dq = np.full(len(JOINT_NAMES), np.nan)
        for read, ids in self._reads:
            if read.txRxPacket() != self.sdk.COMM_SUCCESS:
                return None
            for sid in ids:
                if not read.isAvailable(sid, ADDR_PRESENT_VELOCITY, 8):
                    return None
                vel = read.getData(sid, ADDR_PRESENT_VELOCITY, 4)
                vel = vel - (1 << 32) if vel >= 1 << 31 else vel
                ticks[sid] = read.getData(sid, ADDR_PRESENT_POSITION, 4)
                k, j = self._by_id[sid]
                dq[k] = j.sign * j.servo.direction * vel * VELOCITY_UNIT
        q = self.robot.from_servos(ticks)
        rpy = gyro = accel = soles = None
        if self.robot.imu is not None:
            data = self._block(self.robot.imu.id, IMU_REGISTERS[self.robot.imu.protocol])
            got = None if data is None else imu_reading(self.robot.imu.protocol, data)
            if got is None:
                return None
            rpy, gyro, accel = got
        if self.robot.foot_sensors and self.robot.soles is not None:
            cells = []
            for board in self.robot.soles:
                data = self._block(board.id, SOLE_REGISTERS[self.robot.sole_protocol])
                if data is None:
                    return None
                cells.append(board.newtons(np.frombuffer(data, dtype="<f4").astype(float)))
            soles = np.concatenate(cells)
        return q, dq, rpy, gyro, accel, soles

    def write(self, q_ours: np.ndarray) -> bool:
        """Send our 20 targets [rad] as goal positions, one sync write a port; False if one failed."""
        goals = self.robot.to_servos(q_ours)
        ok = True
        for write, ids in self._writes:
            write.clearParam()
            for sid, pos in goals.items():
                if sid in ids:
                    write.addParam(sid, list(struct.pack("<i", int(pos))))
            try:
                ok &= write.txPacket() == self.sdk.COMM_SUCCESS
            except Exception:  # noqa: BLE001 - a port gone: the next read tells the watchdog
                ok = False
        return ok

    def torque(self, on: bool) -> None:
        """Torque on or off on every servo (the watchdog's last step: off)."""
        for _, j in self.joints:
            try:
                self.packets.write1ByteTxRx(self.ports[self.where[j.servo.id]], j.servo.id, ADDR_TORQUE_ENABLE,
                                            int(bool(on)))
            except Exception:  # noqa: BLE001 - a bus gone (unplugged, closed): nothing more to switch off
                return

    def close(self) -> None:
        for handle in self.ports:
            try:
                handle.closePort()
            except Exception:  # noqa: BLE001 - closing a port that is gone
                pass


def _why_gone(port: str) -> str:
    """What a port that cannot be opened most likely is: a link left to a pseudo-terminal that has
    gone (``gait-tuner bus serve`` ended: it waits ``--wait`` seconds for its client), or nothing."""
    import os
    if os.path.islink(port) and not os.path.exists(port):
        return ("; it is a link to a pseudo-terminal that is gone: the simulated bus it pointed to has ended "
                "(bus serve waits --wait seconds for its client, then stops): start it again")
    if not os.path.lexists(port):
        return "; no such device (a robot's bus is a serial device such as /dev/ttyUSB0)"
    return ""


def imu_reading(protocol: str, data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """An IMU board's registers -> (rpy [rad], gyro [rad/s], accel [m/s^2]); None for a reading the
    board gives before it has one (Bit-Bots' board: a zero quaternion after power-on)."""
    if protocol == "gait-tuner":
        v = np.array(struct.unpack("<9f", data), dtype=float)
        return v[0:3], v[3:6], v[6:9]
    v = np.array(struct.unpack("<10f", data), dtype=float)     # bitbots: gyro, accel, quaternion x y z w
    quat = np.array([v[9], v[6], v[7], v[8]])
    norm = float(np.linalg.norm(quat))
    if not np.isfinite(norm) or norm < 1e-6:
        return None
    return rpy_from_quat(quat / norm), v[0:3], v[3:6]


def imu_registers(protocol: str, rpy: np.ndarray, gyro: np.ndarray, accel: np.ndarray) -> bytes:
    """The registers an IMU board of ``protocol`` holds for these readings (the simulated bus's)."""
    if protocol == "gait-tuner":
        return struct.pack("<9f", *rpy, *gyro, *accel)
    r, p, y = (float(v) / 2 for v in rpy)           # Z-Y-X: q = qz(yaw) qy(pitch) qx(roll)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    w = cr * cp * cy + sr * sp * sy
    x = sr * cp * cy - cr * sp * sy
    yq = cr * sp * cy + sr * cp * sy
    z = cr * cp * sy - sr * sp * cy
    return struct.pack("<10f", *gyro, *accel, x, yq, z, w)
