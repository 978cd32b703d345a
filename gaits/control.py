"""What drives the joints: the controller interface, and the two controllers every table walk uses.

A controller runs on the robot's computer, so it is pure numpy and sees only what a kid-size
robot senses. Every control tick the loop (``tuner/sim/rollout.py`` in simulation,
``gaits/robot/loop.py`` on a robot) hands it a :class:`Measurement` and the current walk
command, and sends the joint targets it returns to the servos; after the walk it asks for
:class:`PlanRecord`, what the controller planned tick by tick (support foot, planned soles, ZMP
reference), which the metrics compare with what the robot did. The controller never sees the
simulator's ground truth (the free joint's pose, the CoM): those go to the recorder only.

Timing, the convention of every joint table the project writes: at tick i (time t_i = i dt) the
controller reads the measurement of t_i and returns the targets the servos should reach at
t_{i+1}; the servos move toward them during [t_i, t_{i+1}].

Joint convention: gait-tuner's names (:data:`gaits.JOINT_NAMES`) and signs; a controller returns
all 20 columns, and the loop sends those the robot has. ``Measurement.joint_names`` says which
joints the encoders report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .imu_stabiliser import StabiliserParams, stabiliser_corrections
from .trajectory import JOINT_NAMES, GaitTrajectory

__all__ = ["READINGS", "Measurement", "PlanRecord", "StartPose", "Controller", "TablePlayer", "Stabilised", "HoldPose",
           "Wrapped", "WithoutReadings", "innermost",
           "FOOT_FORCE_LABELS", "rpy_from_quat", "GRAVITY_ACCEL", "finite_readings"]

GRAVITY_ACCEL = 9.81  # [m/s^2] what a resting accelerometer reads, upward

#: The eight foot-force readings, in order: four sole quadrants per foot.
FOOT_FORCE_LABELS = ("l_toe_left", "l_toe_right", "l_heel_left", "l_heel_right",
                     "r_toe_left", "r_toe_right", "r_heel_left", "r_heel_right")


def rpy_from_quat(quat: np.ndarray) -> np.ndarray:
    """Z-Y-X Euler angles (roll, pitch, yaw) [rad] of orientation quaternions [w, x, y, z]: (4,) ->
    (3,), or (..., 4) -> (..., 3). The project's one conversion (the simulated IMU, the recorder).

    Pitch is positive for a forward lean, roll positive with the left side up, yaw
    counter-clockwise; the IMU filters of kid-size robots report these.
    """
    w, x, y, z = np.moveaxis(np.asarray(quat, dtype=float), -1, 0)
    roll = np.arctan2(2 * (y * z + w * x), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(-(2 * (x * z - w * y)), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=-1)


#: Every reading a :class:`Measurement` can carry; a controller names those it uses (``senses``).
READINGS = ("q", "dq", "imu_rpy", "gyro", "accel", "foot_force")


#: each of our 20 roles' column in ``JOINT_NAMES``
_ROLE = {name: i for i, name in enumerate(JOINT_NAMES)}


@dataclass(slots=True)
class Measurement:
    """What a kid-size robot senses at one control tick (SI units, gait-tuner's joint signs).

    ``q`` and ``dq`` are the encoders, columns ``joint_names``; ``imu_rpy`` the IMU's
    orientation (roll, pitch, yaw, see :func:`rpy_from_quat`); ``gyro`` the body rates about
    the IMU's x (roll), y (pitch), z (yaw) axes; ``accel`` its specific force (gravity
    included: +9.81 m/s^2 along z standing upright); ``foot_force`` the eight sole force
    readings (:data:`FOOT_FORCE_LABELS`, N). In simulation the randomisation's noise and
    latency are already applied (``tuner/sim/sensors.py``). A reading the controller does not
    use (its ``senses``) is None. A value is valid for its tick: copy an array to keep it.
    """

    t: float                                # [s] since the controller's reset
    q: np.ndarray | None = None             # (n,) [rad]
    dq: np.ndarray | None = None            # (n,) [rad/s]
    imu_rpy: np.ndarray | None = None       # (3,) [rad]
    gyro: np.ndarray | None = None          # (3,) [rad/s]
    accel: np.ndarray | None = None         # (3,) [m/s^2]
    foot_force: np.ndarray | None = None    # (8,) [N]
    joint_names: tuple[str, ...] = JOINT_NAMES

    def joint(self, name: str) -> float:
        """One encoder angle by our joint name [rad]."""
        return float(self.q[self.joint_names.index(name)])

    def in_our_order(self, values: np.ndarray) -> np.ndarray:
        """An encoder reading (angles or rates, columns ``joint_names``) in ``JOINT_NAMES`` order, 0
        for a joint not read (a robot's joints beyond the 20 roles left out)."""
        if self.joint_names == JOINT_NAMES:
            return values
        out = np.zeros(len(JOINT_NAMES))
        for name, v in zip(self.joint_names, values):
            if name in _ROLE:
                out[_ROLE[name]] = v
        return out


#: The length of each reading of a :class:`Measurement` (None: one per ``joint_names``).
_LENGTHS = {"q": None, "dq": None, "imu_rpy": 3, "gyro": 3, "accel": 3, "foot_force": len(FOOT_FORCE_LABELS)}


def finite_readings(m: Measurement) -> tuple[Measurement, tuple[str, ...]]:
    """(the measurement with every reading that holds a NaN or an infinity left out (None), the
    names of those left out). A robot's bus drops a frame, an IMU filter diverges for a tick: a
    controller that took such a reading would carry it into every later target (a NaN in a
    filter's state stays there), so it is a reading not taken this tick, and the controller says
    how many it dropped (ours). A reading of the wrong length is a wiring mistake, not a glitch:
    a ValueError naming it. Costs ~5 us a tick (one sum of squares per reading; one that is not
    finite marks the reading: a NaN, an infinity, or a value beyond 1e154)."""
    if not math.isfinite(m.t):
        raise ValueError(f"Measurement.t = {m.t!r}: expected a finite time [s]")
    n_joints = len(m.joint_names)
    sums = {}
    for name, n in _LENGTHS.items():
        v = getattr(m, name)
        if v is None:
            continue
        shape = v.shape if type(v) is np.ndarray else np.shape(v)
        if shape != ((n_joints if n is None else n),):
            raise ValueError(f"Measurement.{name} has shape {shape}, expected ({n_joints if n is None else n},)"
                             + (" (one per joint_names)" if n is None else ""))
        a = v if type(v) is np.ndarray else np.asarray(v, dtype=float)
        sums[name] = float(a.dot(a))                 # BLAS: no floating-point warning, 0.4 us
    if math.isfinite(sum(sums.values())):
        return m, ()
    dropped = tuple(name for name, total in sums.items() if not math.isfinite(total))
    if not dropped:                       # finite sums whose total overflowed: nothing to drop
        return m, ()
    kept = Measurement(m.t, **{name: (None if name in dropped else getattr(m, name)) for name in READINGS},
                       joint_names=m.joint_names)
    return kept, dropped


@dataclass(frozen=True)
class StartPose:
    """Where a controller wants the robot at t = 0: its joint pose and the pelvis's ground position."""

    q: np.ndarray                          # (20,) [rad] JOINT_NAMES (then the robot's extra joints, if it drives them)
    p_world_pelvis_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))   # [m]


@dataclass
class PlanRecord:
    """What a controller planned at every tick it ran (K ticks; the metrics' reference).

    ``support`` +1 left single support, -1 right, 0 double support; ``p_world_zmp_ref`` and the
    planned sole centres are in the controller's own world frame (the robot's start pose);
    ``walk_start`` the first planned single support [s]; ``cycle_time`` two steps [s];
    ``meta`` what else a metric may read (``steady``: the (t0, t1) window a velocity is
    measured over; ``commands``).
    """

    family: str
    support: np.ndarray            # (K,) int
    p_world_zmp_ref: np.ndarray    # (K, 2) [m]
    p_world_foot_l: np.ndarray     # (K, 2) [m]
    p_world_foot_r: np.ndarray     # (K, 2) [m]
    walk_start: float              # [s]
    cycle_time: float              # [s]
    zmp_source: str = "model"
    meta: dict = field(default_factory=dict)


@runtime_checkable
class Controller(Protocol):
    """The interface every controller implements (a class of a user's own included).

    * ``dt`` [s]: its control period; the loop refuses another.
    * ``senses`` (optional): the readings of :data:`READINGS` it uses; the others arrive as None
      (default: all of them). An open-loop table senses nothing.
    * ``duration`` [s] or None: how long its walk lasts on its own (a table's length); None:
      as long as the loop runs it.
    * ``start_pose()``: the pose the robot stands in at t = 0.
    * ``reset(m)``: called once with the first measurement (t = 0), before ``step``.
    * ``step(m, command)``: the joint targets (20,) [rad, JOINT_NAMES] for the next tick;
      ``command`` is the walk command (vx [m/s], vy [m/s], wz [rad/s]) of this tick, (3,),
      or None when the walk has none.
    * ``plan(n)``: the :class:`PlanRecord` of the first ``n`` ticks.
    * ``ahead(n)`` (optional, for a controller that senses nothing): the targets of ticks
      0..n-1 as one (n, 20) array, or None; the loop then takes them instead of calling
      ``step`` (a walk without a command stream), as :meth:`TablePlayer.ahead`.
    """

    dt: float
    duration: float | None

    def start_pose(self) -> StartPose: ...

    def reset(self, m: Measurement) -> None: ...

    def step(self, m: Measurement, command: np.ndarray | None) -> np.ndarray: ...

    def plan(self, n: int) -> PlanRecord: ...


class TablePlayer:
    """Plays a joint table planned in advance (a :class:`GaitTrajectory`): the open loop the papers
    describe. At tick i it returns row i + 1 (the targets for the next tick), whatever it senses;
    past the table's end it holds the last row. Commands are ignored: the table has them."""

    senses: frozenset[str] = frozenset()

    def __init__(self, traj: GaitTrajectory) -> None:
        if len(traj.t) < 2:
            raise ValueError("a joint table needs at least two samples")
        self.traj = traj
        self.dt = traj.dt
        self.duration = float(traj.t[-1])
        self._q = np.ascontiguousarray(traj.q_ref)
        self._last = len(traj.t) - 1
        walking = np.flatnonzero(traj.support != 0)
        self.walk_start = float(traj.t[walking[0]]) if len(walking) else 0.0
        self._i = 0

    def start_pose(self) -> StartPose:
        return StartPose(self._q[0].copy(), np.asarray(self.traj.p_world_pelvis[0, :2], dtype=float))

    def reset(self, m: Measurement) -> None:
        self._i = 0

    def step(self, m: Measurement, command: np.ndarray | None = None) -> np.ndarray:
        self._i += 1
        return self._q[min(self._i, self._last)]

    def ahead(self, n: int) -> np.ndarray | None:
        """The targets of ticks 0..n-1 at once, (n, 20) [rad]: row k is what ``step`` returns at
        tick k after ``reset`` (row 0, the start pose's), since the table ignores what it senses
        and the commands. A loop may take these instead of calling ``step`` each tick. None for
        a subclass whose ``step`` is its own (its targets are not known ahead)."""
        if type(self).step is not TablePlayer.step:
            return None
        return self._q[np.minimum(np.arange(n), self._last)]

    def plan(self, n: int) -> PlanRecord:
        tr = self.traj
        k = min(n, len(tr.t))
        pad = n - k

        def rows(a: np.ndarray) -> np.ndarray:
            a = np.asarray(a[:k])
            return np.concatenate([a, np.repeat(a[-1:], pad, axis=0)]) if pad else a
        meta: dict[str, Any] = {}
        for key in ("steady", "commands", "command", "step_starts", "stream"):
            if key in tr.meta:
                meta[key] = tr.meta[key]
        return PlanRecord(family=tr.family, support=rows(tr.support), p_world_zmp_ref=rows(tr.p_world_zmp_ref),
                          p_world_foot_l=rows(tr.p_world_foot_l[:, :2]), p_world_foot_r=rows(tr.p_world_foot_r[:, :2]),
                          walk_start=self.walk_start, cycle_time=float(tr.meta.get("cycle_time", 1.0)),
                          zmp_source=tr.zmp_source, meta=meta)


#: The joints each of the stabiliser's four corrections moves, both legs (gaits/imu_stabiliser.py).
_STAB_COLUMNS = tuple(tuple(JOINT_NAMES.index(f"{side}_{kind}") for side in "lr")
                      for kind in ("ankle_pitch", "hip_pitch", "ankle_roll", "hip_roll"))


class Stabilised:
    """Any controller with the IMU stabiliser (``gaits/imu_stabiliser.py``) added to its targets.

    Reads the IMU's pitch and roll and the gyro's pitch and roll rates of each measurement,
    and adds the four clipped PD corrections to both legs' ankle and hip pitch and roll targets.
    A tick whose IMU or gyro reading is missing or not finite (:func:`finite_readings`) keeps the
    last corrections (ours: dropping them to zero for one tick would jerk the legs).
    """

    def __init__(self, inner: Controller, params: StabiliserParams) -> None:
        self.inner = inner
        self.params = params
        self.dt = inner.dt
        self.duration = inner.duration
        self._out = np.zeros(len(JOINT_NAMES))
        self._corrections = np.zeros(4)
        self.senses = frozenset(getattr(inner, "senses", READINGS)) | {"imu_rpy", "gyro"}

    @property
    def walk_start(self) -> float:
        return getattr(self.inner, "walk_start", 0.0)

    def start_pose(self) -> StartPose:
        return self.inner.start_pose()

    def reset(self, m: Measurement) -> None:
        self._corrections = np.zeros(4)
        self.inner.reset(m)

    def step(self, m: Measurement, command: np.ndarray | None = None) -> np.ndarray:
        out = self._out
        out[:] = self.inner.step(m, command)
        if self.params.enabled:
            rpy, gyro = m.imu_rpy, m.gyro
            if (rpy is not None and gyro is not None
                    and math.isfinite(float(rpy[0] + rpy[1] + gyro[0] + gyro[1]))):
                self._corrections = stabiliser_corrections(self.params, rpy[1], rpy[0], gyro[1], gyro[0])
            for value, cols in zip(self._corrections, _STAB_COLUMNS):
                out[cols[0]] += value
                out[cols[1]] += value
        return out

    def plan(self, n: int) -> PlanRecord:
        return self.inner.plan(n)


class Wrapped:
    """A controller around another (``inner``): every call and attribute is the inner one's unless a
    subclass says otherwise (a recording, fewer readings)."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner

    def __getattr__(self, name: str) -> Any:
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def start_pose(self) -> StartPose:
        return self.inner.start_pose()

    def reset(self, m: Measurement) -> None:
        self.inner.reset(m)

    def step(self, m: Measurement, command: Any = None) -> np.ndarray:
        return self.inner.step(m, command)

    def plan(self, n: int) -> PlanRecord:
        return self.inner.plan(n)


def innermost(ctl: Any) -> Any:
    """The controller at the heart of wrapped ones (a stabiliser's, a residual's, a recording's
    ``inner``, all the way down): the engine whose mode and steps a loop reports."""
    while getattr(ctl, "__dict__", {}).get("inner") is not None:
        ctl = ctl.inner
    return ctl


class WithoutReadings(Wrapped):
    """A controller on a robot that lacks some sensors: it is given none of ``readings`` (they
    arrive as None, as for a reading it does not use), every other attribute is the wrapped one's.
    The walk engine then estimates from kinematics and the IMU (``gaits/engine``)."""

    def __init__(self, inner: Any, readings: Any) -> None:
        unknown = set(readings) - set(READINGS)
        if unknown:
            raise ValueError(f"unknown readings {sorted(unknown)}: a robot senses {', '.join(READINGS)}")
        super().__init__(inner)
        self.senses = frozenset(getattr(inner, "senses", READINGS)) - set(readings)


class HoldPose:
    """Holds one joint pose (20,) [rad] whatever it senses: a stand test, a landing experiment."""

    senses: frozenset[str] = frozenset()
    walk_start = 0.0

    def __init__(self, q: np.ndarray, dt: float, duration: float | None = None) -> None:
        self.q = np.array(q, dtype=float)
        if self.q.shape != (len(JOINT_NAMES),):
            raise ValueError(f"a pose has {len(JOINT_NAMES)} joint angles (JOINT_NAMES), got shape {self.q.shape}")
        self.dt = float(dt)
        self.duration = duration

    def start_pose(self) -> StartPose:
        return StartPose(self.q.copy())

    def reset(self, m: Measurement) -> None:
        pass

    def step(self, m: Measurement, command: np.ndarray | None = None) -> np.ndarray:
        return self.q

    def plan(self, n: int) -> PlanRecord:
        return PlanRecord("hold", np.zeros(n, dtype=int), np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2)),
                          walk_start=0.0, cycle_time=1.0)
