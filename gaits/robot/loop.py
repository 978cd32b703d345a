"""The loop a team runs on its robot at the control rate: read the sensors, call the walk engine,
write the servo targets. It imports numpy and the engine (``gaits``: numpy and PyYAML) only.

    gait-tuner-loop GAIT.yaml --dry-run [--robot robot.yaml] [--record run.mcap]   # a stand-in robot, no hardware
    gait-tuner-loop POLICY.yaml --dry-run                 # a learned walk's policy file (gaits/policy.py)
    python examples/robot_loop.py GAIT.yaml --dry-run     # the same from a checkout

A policy file (its ``policy:`` section, its ONNX model beside it, its ``params:``) runs as the
simulator runs it (``gaits.policy.PolicyController``; onnxruntime, the ``onnx`` extra, runs the
model): the same observation from the same readings, the same targets.

Porting it: replace :class:`StandIn` by your robot's driver (the four methods it has), give it your
robot file (``gait-tuner robot export MAP --out robot.yaml``, then ``--robot robot.yaml``: the legs,
soles and each joint's servo id, units, direction and offset, nothing copied by hand), and take the
walk command from your behaviour: a function of time (:func:`behaviour` here: forward for 3 s, turning for
2 s, then stop), a command stream file (``--commands STREAM.csv``) or a UDP/JSON socket on the loopback
(``--udp 5005``; ``gaits/robot/command_source.py``). The engine
wants, each tick, the encoders in our joint convention (``gaits.JOINT_NAMES``, signs as
``gait-tuner robot check`` lists them), the IMU's roll, pitch, yaw [rad] and rates [rad/s], its
accelerometer [m/s^2] and the eight sole force readings [N] (left toe-left, toe-right, heel-left,
heel-right, then the right foot); it returns the 20 targets of the next tick [rad].

A reading that holds a NaN or an infinity (a garbled frame) is not taken: the engine predicts
from its model for that tick and counts it (``engine.dropped``, printed at the end); a reading of
the wrong length is a ValueError, a wiring mistake to fix before the robot walks.

The timing is the engine's: it assumes its ``dt``; a tick that overruns is reported, not skipped
(on a robot, read the clock and log overruns: the engine's p99 is ~1 ms in Python on a laptop
core, see ``benchmarks/bench_engine.py``).
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import signal
from typing import Any
import sys
import time

import numpy as np

import gaits
from gaits.files import FOLDER_REFUSED, PATH_PROBLEMS, FolderRefused
from gaits.control import Measurement, innermost

LEGS = {1: slice(gaits.JOINT_NAMES.index("l_hip_yaw"), gaits.JOINT_NAMES.index("l_hip_yaw") + 6),
        -1: slice(gaits.JOINT_NAMES.index("r_hip_yaw"), gaits.JOINT_NAMES.index("r_hip_yaw") + 6)}


class StandIn:
    """A robot that is not there: its servos reach each target by the next tick, its IMU is level
    and its soles carry the weight evenly. Replace it by your robot's driver."""

    def __init__(self, mass: float = 5.0) -> None:
        self.q = np.zeros(len(gaits.JOINT_NAMES))
        self.mass = mass

    def read_encoders(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions [rad] and velocities [rad/s] in our joint order and signs."""
        return self.q.copy(), np.zeros_like(self.q)

    def read_imu(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(roll, pitch, yaw) [rad], body rates [rad/s], specific force [m/s^2]."""
        return np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 9.81])

    def read_soles(self) -> np.ndarray:
        """The weight on the lower sole (both when within 2 mm), from the legs' kinematics."""
        z = [float(gaits.leg_fk(self.q[LEGS[side]], gaits.LegGeometry(), side)[0][2]) for side in (1, -1)]
        down = [zi < min(z) + 0.002 for zi in z]
        share = self.mass * 9.81 / (4 * sum(down))
        return np.concatenate([np.full(4, share if down[0] else 0.0), np.full(4, share if down[1] else 0.0)])

    def write_targets(self, q: np.ndarray) -> None:
        self.q = np.asarray(q, dtype=float).copy()


class RobotGeometry:
    """What the engine needs of the robot: its legs (``gaits.LegGeometry``) and sole size [m]."""

    def __init__(self, leg: gaits.LegGeometry, foot_size: tuple[float, float]) -> None:
        self.leg, self.foot_size = leg, foot_size


def behaviour(t: float) -> np.ndarray:
    """The walk command (vx [m/s], vy [m/s], wz [rad/s]) of time t: what a team's behaviour sends."""
    if t < 3.0:
        return np.array([0.15, 0.0, 0.0])
    if t < 5.0:
        return np.array([0.0, 0.0, 0.5])
    return np.zeros(3)


class SweepPlayer:
    """Plays a joint sweep (``gait-tuner excite``'s CSV: ``t``, then ``target.<joint>`` [rad] per
    joint, our names and signs) row by row on the robot hanging in a harness, so that the loop's
    recording (``--record``) is what ``gait-tuner identify servos`` fits. A joint the sweep does
    not name holds 0 (its held pose). :meth:`stop` (Ctrl-C) eases back to the first row over a
    second; at the end, or back there, its ``mode`` is "stand"."""

    senses = frozenset({"q", "dq"})

    def __init__(self, path: str, dt: float) -> None:
        import csv
        import io

        from gaits.files import MAX_BYTES, read_bytes_checked
        raw = read_bytes_checked(path, "sweep", MAX_BYTES["csv"], gaits.ParamError)   # no FIFO, no giant file
        try:
            rows = [r for r in csv.reader(io.StringIO(raw.decode("utf-8-sig"), newline="")) if r]
        except UnicodeDecodeError:
            raise gaits.ParamError(f"{path}: not a sweep (not text: a CSV of t,target.<joint>,... rows)") from None
        except csv.Error as exc:        # a cell over the csv module's limit, a NUL byte
            raise gaits.ParamError(f"{path}: not a sweep ({exc})") from None
        if len(rows) < 3 or rows[0][0].strip() != "t":
            raise gaits.ParamError(f"{path}: not a sweep (a header t,target.<joint>,... then rows)")
        names = [h.strip().removeprefix("target.") for h in rows[0][1:]]
        unknown = [n for n in names if n not in gaits.JOINT_NAMES]
        if unknown:
            raise gaits.ParamError(f"{path}: {unknown[0]!r} is not one of our joint names ({', '.join(gaits.JOINT_NAMES[:4])} ...)")
        try:
            data = np.array([[float(x) for x in r] for r in rows[1:]])
        except ValueError as exc:
            raise gaits.ParamError(f"{path}: a value that is not a number ({exc})") from None
        if data.shape[1] != len(names) + 1 or not np.all(np.isfinite(data)):
            raise gaits.ParamError(f"{path}: rows of {len(names) + 1} finite numbers expected")
        step = np.diff(data[:, 0])
        if np.any(np.abs(step - dt) > 1e-6):
            raise gaits.ParamError(f"{path}: its rows are not {dt * 1000:g} ms apart (the robot's control period)")
        self.rows = np.zeros((len(data), len(gaits.JOINT_NAMES)))
        for i, n in enumerate(names):
            self.rows[:, gaits.JOINT_NAMES.index(n)] = data[:, i + 1]
        self.dt = dt
        self.duration = len(data) * dt
        self.mode, self.steps_taken, self.dropped = "sweep", 0, {}
        self._k, self._stop_from, self._last = 0, None, self.rows[0]

    def start_pose(self) -> Any:
        from gaits.control import StartPose
        return StartPose(self.rows[0].copy(), np.zeros(2))

    def reset(self, m: Measurement) -> None:
        self._k, self._stop_from, self.mode = 0, None, "sweep"

    def stop(self) -> None:
        if self._stop_from is None:
            self._stop_from = (self._k, self._last.copy())

    def step(self, m: Measurement, command: Any = None) -> np.ndarray:
        if self._stop_from is not None:
            k0, q0 = self._stop_from
            a = min(1.0, (self._k - k0) * self.dt / 1.0)
            q = q0 + a * (self.rows[0] - q0)
            self.mode = "stand" if a >= 1.0 else "stopping"
        else:
            q = self.rows[min(self._k, len(self.rows) - 1)]
            if self._k >= len(self.rows) - 1:
                self.mode = "stand"
        self._k += 1
        self._last = q
        return q


class PolicyWalk:
    """A policy file read for the loop (:func:`gaits.policy.load_policy_file`): its spec, its
    model's path and where it came from."""

    def __init__(self, path: str, doc: Any = None) -> None:
        from gaits.policy import load_policy_file
        self.spec, self.model = load_policy_file(path, doc)
        self.source = str(path)


def load_walk(path: str) -> "gaits.GaitFile | PolicyWalk":
    """What the loop walks: a gait file with an engine section, or a policy file (a ``policy:``
    section), the file read once; every mistake one ParamError naming the file."""
    from pathlib import Path

    from gaits.files import complete_pending_writes
    from gaits.gait_file import gait_file_from_mapping, read_yaml
    complete_pending_writes(Path(path).parent)     # as load_gait_file: a killed group write finished first
    doc = read_yaml(path, "gait or policy")
    if isinstance(doc, dict) and "policy" in doc:
        return PolicyWalk(path, doc)
    return gait_file_from_mapping(doc, str(path))


def controller(gait: "gaits.GaitFile | PolicyWalk", geometry: Any, dt: float, source: str = ""):
    """(the engine, what the loop calls): the set's walk as the simulator builds it
    (:meth:`gaits.Drive.controller`: the engine, or a paper family's online table, with the set's
    trained residual and IMU stabiliser around it when it has them), and the engine inside; a policy
    as itself, its model opened and checked against its spec."""
    if isinstance(gait, PolicyWalk):
        from gaits.policy import PolicyController, onnx_runner
        run, n_in, n_out = onnx_runner(gait.model)
        policy = PolicyController(gait.spec, run, geometry, dt, (n_in, n_out), gait.source)
        return policy, policy
    walk = gaits.Drive.of(gait, source=source).controller(geometry, dt)
    return innermost(walk), walk


class _OneLine(argparse.ArgumentParser):
    """argparse whose refusals are one line and exit 2, as every other refusal of the loop's."""

    def error(self, message: str):
        print(f"robot_loop: error: {message} (see --help)", file=sys.stderr)
        raise SystemExit(2)


def _number(low: float, high: float, unit: str, *, integer: bool = False, low_open: bool = True):
    """An option's type: a finite number in (low, high] ([low, high] when not ``low_open``) [unit]:
    NaN, an infinity or one outside it is refused naming the range (a NaN tilt limit would never
    read a fall; a zero or negative --seconds ran no tick)."""
    def parse(text: str):
        try:
            v = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a {'whole number' if integer else 'number'}") from None
        if not math.isfinite(v) or (v <= low if low_open else v < low) or v > high:
            raise argparse.ArgumentTypeError(f"{text!r} is outside {'(' if low_open else '['}{low:g}, {high:g}] {unit}")
        return v
    return parse


#: errno values of a path that cannot be a file (the user's mistake) and of a full or read-only disk
_PATH_ERRNOS = {**PATH_PROBLEMS, errno.ENOENT: "no such file or folder", errno.EACCES: "permission denied"}
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG, errno.EIO}


def main(argv: list[str] | None = None) -> None:
    """The loop's command line (module docstring): every mistake of its input, a path it cannot
    write or a disk that fills is one line on stderr and an exit code (2: the input, 3: the
    system), never a traceback; Ctrl-C before the walk is 130."""
    try:
        _main(argv)
    except KeyboardInterrupt:
        print("robot_loop: interrupted", file=sys.stderr)
        raise SystemExit(130) from None
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        if exc.errno in _DISK_ERRNOS:
            print(f"robot_loop: error: {where}{exc.strerror or exc} (a recording being written there is kept "
                  f"as NAME.partial.mcap; an older one of the name was left as it was)", file=sys.stderr)
            raise SystemExit(3) from None
        why = FOLDER_REFUSED if isinstance(exc, FolderRefused) else _PATH_ERRNOS.get(exc.errno, exc.strerror or str(exc))
        print(f"robot_loop: error: {where}{why}", file=sys.stderr)
        raise SystemExit(2) from None
    except (gaits.ParamError, ValueError) as exc:      # a file that is not what it says (binary, broken)
        print(f"robot_loop: error: {' '.join(str(exc).split())[:400]}", file=sys.stderr)
        raise SystemExit(2) from None


def _main(argv: list[str] | None = None) -> None:
    ap = _OneLine(description=" ".join(__doc__.split("\n\n", 1)[0].split()))     # the first paragraph, whole
    ap.add_argument("gait", nargs="?", help="a gait file with an engine: section (e.g. "
                                            "studies/results/kidsize-engine-carpet4.yaml) or a policy file (its "
                                            "policy: section and ONNX model); not with --sweep")
    ap.add_argument("--sweep", help="play this joint sweep (gait-tuner excite's CSV) on the robot hanging in a "
                                    "harness instead of walking: record it (--record) to identify the servos")
    ap.add_argument("--dry-run", action="store_true", help="walk the stand-in robot (no hardware)")
    ap.add_argument("--seconds", type=_number(0.0, 86400.0, "s"), default=None,
                    help="how long [s] (default 8; a sweep: its length)")
    ap.add_argument("--robot", help="the robot file (gait-tuner robot export MAP --out robot.yaml): its legs, soles "
                                    "and servos; default: the built-in robot's geometry")
    ap.add_argument("--record", help="record every tick (what the engine read and asked) as an MCAP file "
                                     "(gaits/robot/recorder.py; needs the mcap package)")
    ap.add_argument("--port", help="the Dynamixel bus (a serial device, or `gait-tuner bus serve`'s pseudo-terminal): "
                                   "walk the robot on it (needs --robot and dynamixel-sdk); a robot on several "
                                   "buses: every one, comma-separated (each device is used where it answers)")
    ap.add_argument("--baud", type=_number(0, 10_000_000, "baud", integer=True), default=1_000_000,
                    help="the bus's baud rate")
    ap.add_argument("--watchdog", type=_number(0, 100_000, "ticks", integer=True), default=5,
                    help="ticks without readings before the safe stop")
    ap.add_argument("--max-tilt", type=_number(0.0, 90.0, "deg"), default=50.0,
                    help="torso tilt [deg] read as a fall: torque off")
    ap.add_argument("--commands", metavar="STREAM.csv", help="walk this command stream (t,vx,vy,wz CSV) instead of "
                                                          "the built-in behaviour; --seconds defaults to its length")
    ap.add_argument("--udp", metavar="[HOST:]PORT", help="take the walk command from UDP datagrams of JSON "
                                                      "{\"vx\": .., \"vy\": .., \"wz\": ..} (bound to 127.0.0.1 "
                                                      "unless HOST says otherwise); --seconds defaults to 600")
    ap.add_argument("--udp-timeout", type=_number(0.0, 3600.0, "s"), default=0.5,
                    help="seconds without a UDP command before a stop")
    args = ap.parse_args(argv)
    if (args.gait is None) == (args.sweep is None):
        print("robot_loop: error: give a gait file to walk, or --sweep SWEEP.csv to play (not both)", file=sys.stderr)
        raise SystemExit(2)
    if args.sweep is not None:
        raise SystemExit(run_sweep(args))
    try:
        source = command_source(args)
    except (OSError, gaits.ParamError) as exc:
        print(f"robot_loop: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    if args.seconds is None:
        args.seconds = getattr(source, "duration", None) or (600.0 if args.udp else 8.0)
    try:
        gait = load_walk(args.gait)
    except gaits.ParamError as exc:      # one line, exit 2: a wrong name or a broken file is not a crash
        hint = (f" (a shipped set is a file here: studies/results/{args.gait}.yaml)"
                if "/" not in args.gait and not args.gait.endswith((".yaml", ".yml")) else "")
        print(f"robot_loop: error: {exc}{hint}", file=sys.stderr)
        raise SystemExit(2) from None
    if not isinstance(gait, PolicyWalk) and gait.engine is None:
        print(f"robot_loop: error: {args.gait}: no engine: section (a table set is played from its joint table)",
              file=sys.stderr)
        raise SystemExit(2)
    if not args.dry_run and not args.port:
        raise SystemExit("give --port (the robot's bus) or --dry-run (the stand-in)")
    robot = StandIn()
    robot_file = _robot_file(args)
    if args.port:
        if robot_file is None:
            print("robot_loop: error: --port needs --robot (its servo ids, units and signs)", file=sys.stderr)
            raise SystemExit(2)
        raise SystemExit(run_on_bus(args, gait, robot_file, source=source))
    geometry = robot_file or RobotGeometry(gaits.LegGeometry(), (0.10, 0.055))
    engine, walk = controller(gait, geometry, 0.01, str(args.gait))
    recorder = None
    if args.record:
        from gaits.robot.recorder import Recorder, RecordingController, RecordingMeta
        recorder = Recorder(args.record, RecordingMeta(robot="stand-in", task="walk", simulated=True,
                                                       controller=f"{_kind(gait)}, {args.gait}",
                                                       notes=f"gait-tuner-loop --dry-run; commands from "
                                                             f"{source.describe()}"))
        walk = RecordingController(walk, recorder)
    robot.write_targets(walk.start_pose().q)
    overruns, t, costs, sent = 0, 0.0, [], {}

    def measure(t: float) -> Measurement:
        q, dq = robot.read_encoders()
        rpy, gyro, accel = robot.read_imu()
        soles = robot.read_soles() if robot_file is None or robot_file.foot_sensors else None
        return Measurement(t, q=q, dq=dq, imu_rpy=rpy, gyro=gyro, accel=accel, foot_force=soles)
    walk.reset(measure(0.0))
    while t < args.seconds:
        m = measure(t)
        t0 = time.perf_counter()
        q = walk.step(m, source(t))
        cost = time.perf_counter() - t0
        costs.append(cost)
        overruns += cost > engine.dt
        robot.write_targets(q)          # on a robot: the servo positions below, sent on the bus
        if robot_file is not None:
            sent = robot_file.to_servos(q)    # {servo id: position}: what a Dynamixel sync write sends
        t += engine.dt
    if recorder is not None:
        print(f"recorded {recorder.close()}")
    if robot_file is not None:
        print(f"robot {robot_file.robot}: {len(sent)} servo position(s) a tick from its robot file "
              f"({len(robot_file.joints) - len(sent)} joint(s) without a servo id)")
    c = np.array(costs) * 1000
    print(f"{len(c)} ticks: {_what_it_did(engine)}; controller median {np.median(c):.2f} ms, "
          f"p99 {np.percentile(c, 99):.2f} ms, {overruns} tick(s) over {engine.dt * 1000:.0f} ms")
    dropped = {name: n for name, n in getattr(engine, "dropped", {}).items() if n}
    if dropped:
        print("readings not finite, not taken (ticks): " + ", ".join(f"{k} {n}" for k, n in dropped.items()))


def _kind(gait: Any) -> str:
    return f"policy (its model {gait.model.name})" if isinstance(gait, PolicyWalk) else "walk engine"


def _what_it_did(engine: Any) -> str:
    """The end line's account of the walk: the engine's steps and its mode, a policy's calls."""
    if hasattr(engine, "steps_taken"):
        return f"{engine.steps_taken} steps, ended {engine.mode}"
    if hasattr(engine, "replans"):
        return f"{len(engine.step_starts)} steps of the online table, re-planned {engine.replans} time(s)"
    return f"{engine.calls} policy call(s)"


def command_source(args: Any) -> Any:
    """The walk command's source of ``--commands``, ``--udp`` or the built-in :func:`behaviour`
    (``gaits/robot/command_source.py``); a mistake is a ParamError (or OSError) naming it."""
    from gaits.robot.command_source import FromStream, Scripted, UdpCommands, parse_udp_address
    if args.commands and args.udp:
        raise gaits.ParamError("give --commands or --udp, not both")
    if args.commands:
        return FromStream(args.commands)
    if args.udp:
        host, port = parse_udp_address(args.udp)
        return UdpCommands(host, port, args.udp_timeout)
    return Scripted(behaviour)


def _robot_file(args: Any) -> Any:
    """The robot file of ``--robot`` (None without one); a bad one is one line, exit 2."""
    if not args.robot:
        return None
    from gaits.robot.robot_file import load_robot_file
    try:
        return load_robot_file(args.robot)
    except gaits.ParamError as exc:
        print(f"robot_loop: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None


def run_sweep(args: Any) -> int:
    """``--sweep``: the sweep played on the bus (``--port``, with ``--robot``) as the walk would be,
    the clock, watchdog and Ctrl-C the same; or with ``--dry-run`` on the stand-in robot."""
    robot_file = _robot_file(args)
    dt = robot_file.control_period if robot_file is not None else 0.01
    try:
        player = SweepPlayer(args.sweep, dt)
    except (OSError, gaits.ParamError) as exc:
        print(f"robot_loop: error: {exc}", file=sys.stderr)
        return 2
    if args.seconds is None:
        args.seconds = player.duration
    if args.port:
        if robot_file is None:
            print("robot_loop: error: --port needs --robot (its servo ids, units and signs)", file=sys.stderr)
            return 2
        return run_on_bus(args, None, robot_file, player)
    if not args.dry_run:
        print("robot_loop: error: give --port (the robot's bus) or --dry-run (the stand-in)", file=sys.stderr)
        return 2
    robot = StandIn()
    recorder = None
    walk: Any = player
    if args.record:
        from gaits.robot.recorder import Recorder, RecordingController, RecordingMeta
        recorder = Recorder(args.record, RecordingMeta(robot="stand-in", task="sweep", simulated=True,
                                                       controller=f"joint sweep {args.sweep}"))
        walk = RecordingController(player, recorder)
    robot.write_targets(player.start_pose().q)
    walk.reset(Measurement(0.0, q=robot.read_encoders()[0]))
    for k in range(int(round(args.seconds / dt))):
        q, dq = robot.read_encoders()
        robot.write_targets(walk.step(Measurement(k * dt, q=q, dq=dq)))
    if recorder is not None:
        print(f"recorded {recorder.close()}")
    print(f"{int(round(args.seconds / dt))} ticks of the sweep on the stand-in, ended {player.mode}")
    return 0


def run_on_bus(args: Any, gait: gaits.GaitFile | None, robot_file: Any, sweep: SweepPlayer | None = None,
               source: Any = None) -> int:
    """The loop on a Dynamixel bus (``--port``), as a robot runs it: a monotonic clock at the control
    rate (overruns counted, tick periods' percentiles printed); a watchdog (no readings for
    ``--watchdog`` ticks: the safe stop, the standing pose then torque off); a fall (a tilt past
    ``--max-tilt``: torque off at once); Ctrl-C: a zero command until the engine stands (at most
    3 s), then torque off. Each ending is one line saying why. Returns the exit code (0 a walk that
    ended as planned or was stopped, 3 a watchdog or a fall)."""
    from gaits.robot.dynamixel import BusError, DynamixelBus
    try:
        bus = DynamixelBus([p.strip() for p in args.port.split(",")], robot_file, args.baud)
        bus.check()
    except BusError as exc:
        print(f"robot_loop: error: {exc}", file=sys.stderr)
        return 2
    if sweep is not None:
        engine = walk = sweep
        task, what = "sweep", f"joint sweep {args.sweep}"
    else:
        engine, walk = controller(gait, robot_file, robot_file.control_period, str(args.gait))
        task, what = "walk", f"{_kind(gait)}, {args.gait}; commands from {source.describe()}"
    recorder = None
    if args.record:
        from gaits.robot.recorder import Recorder, RecordingController, RecordingMeta
        # a bus on pseudo-terminals is gait-tuner bus serve's (a real robot's is a serial device): such a
        # recording is of the simulator, and says so
        simulated = all(os.path.realpath(p).startswith("/dev/pts/") for p in bus.names)
        recorder = Recorder(args.record, RecordingMeta(robot=robot_file.robot, task=task, simulated=simulated,
                                                       joints=list(gaits.JOINT_NAMES), controller=what,
                                                       notes=f"bus {args.port}" + (
                                                           " (pseudo-terminals: the simulated bus, gait-tuner bus "
                                                           "serve)" if simulated else "")))
        walk = RecordingController(walk, recorder)
    dt = robot_file.control_period
    stand = walk.start_pose().q
    bus.write(stand)
    k, missing, costs, periods, overruns, code, why = 0, 0, [], [], 0, 0, "walked its time"
    unread = 0                                    # ticks without readings, over the whole walk
    n_ticks = int(round(args.seconds / dt))
    stop_at = None

    def measure(t: float) -> Measurement | None:
        got = bus.read()
        if got is None:
            return None
        q, dq, rpy, gyro, accel, soles = got
        return Measurement(t, q=q, dq=dq, imu_rpy=rpy, gyro=gyro, accel=accel, foot_force=soles)
    first, waited = None, time.monotonic()
    while first is None and time.monotonic() - waited < 5.0:    # the robot may still be taking its start pose
        first = measure(0.0)
    if first is None:
        print(f"robot_loop: error: {args.port}: no readings from the bus within 5 s of the start pose",
              file=sys.stderr)
        return 2
    walk.reset(first)
    clock = time.monotonic()
    last = clock
    # Ctrl-C is taken between ticks, never inside a bus transaction (a packet cut in half would
    # leave the port's stream out of step): the handler only counts, the tick reads the count
    interrupts = [0]
    previous = signal.signal(signal.SIGINT, lambda signum, frame: interrupts.__setitem__(0, interrupts[0] + 1))
    try:
        while True:
            t = k * dt
            if interrupts[0] >= 2:
                why = f"stopped by a second Ctrl-C at t = {t:.2f} s"
                break
            if interrupts[0] == 1 and stop_at is None:
                stop_at = t + 3.0
                if sweep is not None:
                    sweep.stop()                   # back to the sweep's first pose
            if k >= n_ticks and stop_at is None:
                break
            m = measure(t)
            if m is None:
                missing += 1
                unread += 1
                if missing >= args.watchdog:
                    why, code = (f"watchdog: no readings for {missing} ticks ({missing * dt * 1000:.0f} ms) at "
                                 f"t = {t:.2f} s: the safe stop (standing pose, torque off)"), 3
                    bus.write(stand)
                    break
            else:
                missing = 0
                tilt = max(abs(m.imu_rpy[0]), abs(m.imu_rpy[1])) * 180 / np.pi if m.imu_rpy is not None else 0
                if tilt > args.max_tilt:
                    why, code = f"fall detected at t = {t:.2f} s (tilt {tilt:.0f} deg): torque off", 3
                    break
                command = None if sweep is not None else np.zeros(3) if stop_at is not None else source(t)
                t0 = time.perf_counter()
                q = walk.step(m, command)
                costs.append(time.perf_counter() - t0)
                bus.write(q)
                standing = getattr(engine, "mode", None) == "stand"     # a policy has no standing mode
                if stop_at is not None and (standing or t >= stop_at):
                    why = f"stopped by Ctrl-C at t = {t:.2f} s, standing" if standing else \
                        f"stopped by Ctrl-C at t = {t:.2f} s, not standing after 3 s"
                    break
            k += 1
            clock += dt
            now = time.monotonic()
            if now > clock + dt:
                overruns += 1
                clock = now                       # late: the next tick from now, not a burst to catch up
            time.sleep(max(0.0, clock - now))
            periods.append(time.monotonic() - last)
            last = time.monotonic()
    finally:
        signal.signal(signal.SIGINT, previous)
        bus.torque(False)
        bus.close()
        if recorder is not None:
            print(f"recorded {recorder.close()}")
    c = np.array(costs) * 1000 if costs else np.zeros(1)
    p = np.array(periods) * 1000 if periods else np.zeros(1)
    print(f"{len(costs)} ticks on {args.port}: {_what_it_did(engine)}; controller median "
          f"{np.median(c):.2f} ms, p99 {np.percentile(c, 99):.2f} ms; tick period median {np.median(p):.1f} ms, "
          f"p99 {np.percentile(p, 99):.1f} ms, {overruns} overrun(s), {unread} tick(s) without readings")
    print(why)
    return code


if __name__ == "__main__":
    main()
