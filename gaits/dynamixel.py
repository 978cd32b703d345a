"""Dynamixel Protocol 2.0 on the robot side (ours, from ROBOTIS' protocol description): the packet
codec, the control-table addresses the walk uses, and the bus driver the loop runs.

A packet is ``FF FF FD 00 | id | length (2, LE) | instruction | parameters | CRC-16 (2, LE)``, the
length counting the instruction, the parameters and the CRC; inside, every ``FF FF FD`` is stuffed
with a ``FD``; the CRC (polynomial 0x8005, initial 0) covers everything before it. A status packet
has the instruction 0x55 and an error byte before its parameters.

:class:`DynamixelBus` is the driver (``dynamixel-sdk``: ``PortHandler``, ``PacketHandler(2.0)``,
``GroupSyncRead`` of present velocity and position, 8 bytes from address 128, and
``GroupSyncWrite`` of goal positions, 4 bytes at 116), with the ids, units, directions and offsets
of the robot file. The IMU is a device on the same bus (ours: id :data:`IMU_ID`, nine little-endian
float32 from address 0: roll, pitch, yaw [rad], gyro x, y, z [rad/s], accelerometer x, y, z
[m/s^2]); a robot without one passes ``imu=False``. Foot force sensors are not read: the engine
walks on kinematics and the IMU alone (``senses`` without ``foot_force``).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from .params import ParamError
from .trajectory import JOINT_NAMES

__all__ = ["crc16", "stuff", "unstuff", "instruction_packet", "status_packet", "parse_packet", "Packet",
           "PING", "READ", "WRITE", "SYNC_READ", "SYNC_WRITE", "STATUS", "ADDR_GOAL_POSITION",
           "ADDR_PRESENT_VELOCITY", "ADDR_PRESENT_POSITION", "VELOCITY_UNIT", "IMU_ID", "IMU_BYTES",
           "DynamixelBus", "BusError"]

PING, READ, WRITE, SYNC_READ, SYNC_WRITE, STATUS = 0x01, 0x02, 0x03, 0x82, 0x83, 0x55
ADDR_TORQUE_ENABLE = 64
ADDR_GOAL_POSITION = 116          # 4 bytes
ADDR_PRESENT_VELOCITY = 128       # 4 bytes, signed, units of VELOCITY_UNIT
ADDR_PRESENT_POSITION = 132       # 4 bytes
VELOCITY_UNIT = 0.229 * 2 * np.pi / 60     # [rad/s] per unit (0.229 rpm, X series)
IMU_ID = 200                      # ours: the IMU board on the bus
IMU_BYTES = 36                    # nine float32
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
    """The robot's servos and IMU through ``dynamixel-sdk`` (module docstring). ``robot``: a
    :class:`gaits.robot_file.RobotFile` (every driven joint has a servo id)."""

    def __init__(self, port: str, robot: Any, baudrate: int = 1_000_000, imu: bool = True) -> None:
        try:
            import dynamixel_sdk as sdk
        except ImportError:
            raise BusError("the Dynamixel driver needs dynamixel-sdk: pip install dynamixel-sdk") from None
        self.sdk, self.robot, self.port_name, self.baudrate, self.imu = sdk, robot, port, int(baudrate), imu
        self.joints = [(ours, j) for ours, j in robot.joints.items() if j.servo is not None]
        if len(self.joints) != len(robot.joints):
            missing = [o for o, j in robot.joints.items() if j.servo is None]
            raise BusError(f"{port}: the robot file gives no servo id to {', '.join(missing)}")
        self.port = sdk.PortHandler(port)
        try:
            opened = self.port.openPort() and self.port.setBaudRate(self.baudrate)
        except Exception as exc:  # noqa: BLE001 - pyserial's errors are many kinds
            raise BusError(f"{port}: cannot open the bus ({' '.join(str(exc).split())})") from None
        if not opened:
            raise BusError(f"{port}: cannot open the bus at {self.baudrate} baud")
        self.packets = sdk.PacketHandler(2.0)
        self._read = sdk.GroupSyncRead(self.port, self.packets, ADDR_PRESENT_VELOCITY, 8)
        self._write = sdk.GroupSyncWrite(self.port, self.packets, ADDR_GOAL_POSITION, 4)
        for _, j in self.joints:
            self._read.addParam(j.servo.id)

    def check(self, attempts: int = 3) -> None:
        """Ping every servo (and the IMU), each up to ``attempts`` times (a reply lost to noise on
        the bus, or late from a busy simulated one, is not a missing servo): one that never answers
        is one line naming it."""
        ids = [j.servo.id for _, j in self.joints] + ([IMU_ID] if self.imu else [])
        silent = []
        for dxl_id in ids:
            for _ in range(attempts):
                _, result, _ = self.packets.ping(self.port, dxl_id)
                if result == self.sdk.COMM_SUCCESS:
                    break
            else:
                silent.append(dxl_id)
        if silent and len(silent) == len(ids):
            raise BusError(f"{self.port_name}: no device answers at {self.baudrate} baud (ids "
                           f"{', '.join(map(str, ids))}): is the bus at another baud rate, or powered off?")
        if silent:
            names = {j.servo.id: ours for ours, j in self.joints}
            raise BusError(f"{self.port_name}: id {silent[0]}" + (f" ({names[silent[0]]})" if silent[0] in names
                                                                 else " (the IMU)") +
                           f" does not answer at {self.baudrate} baud" +
                           (f" (and {len(silent) - 1} more)" if len(silent) > 1 else ""))

    def read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray | None] | None:
        """(q, dq) in our convention [rad, rad/s] and, with an IMU, (rpy, gyro, accel); None when the
        bus did not answer this tick, or is gone (the loop's watchdog counts it)."""
        try:
            return self._read_once()
        except Exception:  # noqa: BLE001 - a port gone (unplugged, closed) raises pyserial's or the OS's errors
            return None

    def _read_once(self):
        if self._read.txRxPacket() != self.sdk.COMM_SUCCESS:
            return None
        ticks = {}
        dq = np.full(len(JOINT_NAMES), np.nan)
        for ours, j in self.joints:
            sid = j.servo.id
            if not self._read.isAvailable(sid, ADDR_PRESENT_VELOCITY, 8):
                return None
            vel = self._read.getData(sid, ADDR_PRESENT_VELOCITY, 4)
            vel = vel - (1 << 32) if vel >= 1 << 31 else vel
            ticks[sid] = self._read.getData(sid, ADDR_PRESENT_POSITION, 4)
            dq[JOINT_NAMES.index(ours)] = j.sign * j.servo.direction * vel * VELOCITY_UNIT
        q = self.robot.from_servos(ticks)
        if not self.imu:
            return q, dq, None, None, None
        data, result, _ = self.packets.readTxRx(self.port, IMU_ID, 0, IMU_BYTES)
        if result != self.sdk.COMM_SUCCESS or len(data) != IMU_BYTES:
            return None
        v = np.array(struct.unpack("<9f", bytes(data)), dtype=float)
        return q, dq, v[0:3], v[3:6], v[6:9]

    def write(self, q_ours: np.ndarray) -> bool:
        """Send our 20 targets [rad] as goal positions in one sync write; False if it failed."""
        self._write.clearParam()
        for sid, pos in self.robot.to_servos(q_ours).items():
            self._write.addParam(sid, list(struct.pack("<i", int(pos))))
        try:
            return self._write.txPacket() == self.sdk.COMM_SUCCESS
        except Exception:  # noqa: BLE001 - a port gone: the next read tells the watchdog
            return False

    def torque(self, on: bool) -> None:
        """Torque on or off on every servo (the watchdog's last step: off)."""
        for _, j in self.joints:
            try:
                self.packets.write1ByteTxRx(self.port, j.servo.id, ADDR_TORQUE_ENABLE, int(bool(on)))
            except Exception:  # noqa: BLE001 - a bus gone (unplugged, closed): nothing more to switch off
                return

    def close(self) -> None:
        try:
            self.port.closePort()
        except Exception:  # noqa: BLE001 - closing a port that is gone
            pass
