"""What drives the joints of a walk: one value, resolved once, that every verb walks the same way.

A :class:`Drive` holds a parameter set, its IMU stabiliser (from the gait file, unless switched
off), and what the walk is asked to do: the family's own walk, a ramped walk at one command, or
a command stream. :meth:`Drive.controller` builds the controller the loop runs;
:meth:`Drive.table` the joint table, for the verbs that write one. So ``simulate``, ``render``,
``view``, ``robustness``, ``compare`` and the studies cannot drop a part of a gait file.

A table walks a command stream *planned per step* (:meth:`CommandStream.per_step`): the open loop
of the papers, labelled so in :meth:`Drive.describe`.

A controller of the user's own (:class:`UserController`: a class implementing
``gaits.control.Controller``, built as ``cls(params, robot, dt)``, and the values of its
parameters) is a drive too, without a gait set: it walks online and has no joint table.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import signal
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from .command_stream import CommandStream
from .control import READINGS, Controller, Stabilised, TablePlayer
from .engine import EngineParams, ResidualParams, ResidualWalk, WalkEngine
from .online_table import OnlineTable
from .families import RobotGeometry, command_walk, family_of
from .gait_file import GaitFile
from .imu_stabiliser import StabiliserParams
from .params import GaitParams, ParamError
from .trajectory import JOINT_NAMES, GaitTrajectory
from .walk_command import WalkCommand

__all__ = ["Drive", "UserController", "TimeLimits", "time_limit", "TimeLimitExpired"]

#: steps a table may plan for a stream (a 10-minute stream at 0.3 s steps is 2000)
MAX_STREAM_STEPS = 5000
#: [s] how long an online controller walks when nothing else says (no stream, no duration given)
ONLINE_DURATION_S = 10.0


@dataclass(frozen=True)
class TimeLimits:
    """How long a controller of the user's own may run [s] (ours; the controller file's ``time_limit:``).

    ``tick``: one call of ``start_pose``, ``reset``, ``step`` or ``plan`` (a robot's tick is 10 ms:
    one second is a hundred ticks, a hung call, not a slow one); ``walk``: all its calls in one walk
    together; ``import``: importing its file. A call that passes its limit is stopped (SIGALRM, in
    the process's main thread: studies walk a user's controller on one thread) and is one line
    naming the controller, the call, the time and the limit."""

    tick: float = 1.0
    walk: float = 600.0
    import_: float = 30.0


class TimeLimitExpired(BaseException):
    """Raised into the user's code when its time is up (a BaseException: its ``except Exception``
    does not swallow it)."""


@contextlib.contextmanager
def time_limit(seconds: float | None, expired: Callable[[], Exception]) -> Iterator[None]:
    """Run the block for at most ``seconds`` (``ITIMER_REAL``; the main thread only: elsewhere, and
    for ``None``, nothing is limited); past it the block is interrupted and ``expired()`` raised."""
    if seconds is None or not hasattr(signal, "setitimer") \
            or threading.current_thread() is not threading.main_thread():
        yield
        return

    def ring(signum: int, frame: Any) -> None:
        raise TimeLimitExpired()
    previous = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, max(float(seconds), 1e-3))
    try:
        yield
    except TimeLimitExpired:
        raise expired() from None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@dataclass(frozen=True)
class UserController:
    """A controller class of the user's own and the values of its parameters.

    ``cls(params: dict, robot, dt)`` must return an object with the ``gaits.control.Controller``
    methods; ``ranges`` (name -> (low, high)) are the search ranges its file declares;
    ``source`` says where the class came from (``path.py:Class`` or ``module:Class``).
    """

    cls: Any
    params: Mapping[str, float]
    source: str
    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    limits: TimeLimits = TimeLimits()

    def with_params(self, values: Mapping[str, float]) -> "UserController":
        unknown = set(values) - set(self.params)
        if unknown:
            raise ParamError(f"controller {self.source}: unknown parameter(s) {', '.join(sorted(unknown))} "
                             f"(its parameters: {', '.join(self.params)})")
        return dataclasses.replace(self, params={**self.params, **values})

    def build(self, robot: RobotGeometry, dt: float) -> Controller:
        """The controller, behind :class:`UserCode` (an exception of its code names the code; what
        it builds is checked against the protocol: its methods, ``dt`` the control period, a
        ``duration`` that is a positive number or None, ``senses`` among the readings)."""
        ctl = UserCode(None, self.source, self.limits).call(self.cls, "its constructor", dict(self.params),
                                                            robot, dt)
        missing = [m for m in ("start_pose", "reset", "step", "plan") if not callable(getattr(ctl, m, None))]
        if missing or not hasattr(ctl, "dt"):
            raise ParamError(f"controller {self.source}: the object it builds lacks "
                             f"{', '.join(missing + ([] if hasattr(ctl, 'dt') else ['dt']))} "
                             f"(see gaits/control.py, Controller)")
        bad = f"controller {self.source}: the object it builds has"
        own_dt = ctl.dt
        if isinstance(own_dt, bool) or not isinstance(own_dt, (int, float)) or not math.isfinite(own_dt) \
                or abs(own_dt - dt) > 1e-9 * max(1.0, dt):
            raise ParamError(f"{bad} dt = {own_dt!r}: expected the control period it was built with, {dt:g} s "
                             f"(the loop calls step() every {dt:g} s)")
        duration = getattr(ctl, "duration", None)
        if duration is not None and (isinstance(duration, bool) or not isinstance(duration, (int, float))
                                     or not math.isfinite(duration) or duration <= 0):
            raise ParamError(f"{bad} duration = {duration!r}: expected a positive number of seconds, or None "
                             f"(it walks as long as it is run)")
        senses = getattr(ctl, "senses", None)
        if senses is not None:
            if isinstance(senses, str) or not all(isinstance(s, str) for s in senses):
                raise ParamError(f"{bad} senses = {senses!r}: expected names of readings ({', '.join(READINGS)})")
            unknown = [s for s in senses if s not in READINGS]
            if unknown:
                raise ParamError(f"{bad} senses naming {unknown[0]!r}: not a reading (readings: "
                                 f"{', '.join(READINGS)})")
        return UserCode(ctl, self.source, self.limits, tuple(getattr(robot, "extra_joints", ()) or ()))


class UserCode:
    """A controller of the user's own, behind the one adapter at that border: every attribute is
    the controller's, and an exception its code raises in ``start_pose``, ``reset``, ``step`` or
    ``plan`` becomes a :class:`ParamError` that names the controller, the method and the line of
    the user's code it came from (the command line prints it as one line, exit 2: a mistake in the
    user's code is not one of ours to report)."""

    def __init__(self, ctl: Any, source: str, limits: TimeLimits = TimeLimits(),
                 extra_joints: tuple[str, ...] = ()) -> None:
        self._ctl = ctl
        self.source = source
        self.limits = limits
        self.extra_joints = extra_joints        # the robot's joints beyond the 20 roles (its map's)
        self.spent = 0.0                       # [s] in its calls this walk (reset() starts a walk)

    def __getattr__(self, name: str) -> Any:
        if name == "_ctl":                     # not yet set (a copy being built): no recursion
            raise AttributeError(name)
        return getattr(self._ctl, name)

    def call(self, fn: Any, what: str | Callable[[], str], *args: Any) -> Any:
        """``fn(*args)`` under the time limits, its exceptions named; ``what`` names the call (a
        callable: built only when it is needed, so the per-tick ``step`` formats nothing)."""
        left = self.limits.walk - self.spent
        limit = min(self.limits.tick, left)

        def expired() -> ParamError:
            which = (f"its limit of {self.limits.tick:g} s a call" if limit == self.limits.tick else
                     f"its limit of {self.limits.walk:g} s a walk")
            label = what() if callable(what) else what
            return ParamError(f"controller {self.source}: {label} ran past {which} (time_limit in its file) "
                              f"and was stopped")
        if left <= 0:
            raise expired()
        t0 = time.perf_counter()
        try:
            with time_limit(limit, expired):
                return fn(*args)
        except ParamError:
            raise
        except Exception as exc:  # noqa: BLE001 - the user's code may raise anything
            raise self._named(exc, what() if callable(what) else what) from exc
        finally:
            self.spent += time.perf_counter() - t0

    def _named(self, exc: Exception, what: str) -> ParamError:
        """The error naming the innermost line of the controller's own file (else the innermost
        line outside gaits and the installed packages, else the innermost)."""
        frames = traceback.extract_tb(exc.__traceback__)
        own = self.source.rsplit(":", 1)[0]
        ours = Path(__file__).resolve().parent
        theirs = ([f for f in frames if f.filename == own]
                  or [f for f in frames if ours not in Path(f.filename).resolve().parents
                      and "-packages" not in f.filename] or frames)
        where = f" ({theirs[-1].filename}, line {theirs[-1].lineno})" if theirs else ""
        return ParamError(f"controller {self.source}: {what} raised {type(exc).__name__}: "
                          f"{' '.join(str(exc).split())}{where}")

    def start_pose(self) -> Any:
        self.spent = 0.0
        pose = self.call(self._ctl.start_pose, "start_pose()")
        q = getattr(pose, "q", None)
        n, extra = len(JOINT_NAMES), self.extra_joints
        if q is None or np.shape(q) not in ((n,), (n + len(extra),)):
            got = "None" if pose is None else (f"{np.shape(q)[0] if np.ndim(q) == 1 else np.shape(q)} angles"
                                               if q is not None else type(pose).__name__)
            more = f" (or {n + len(extra)}: then the robot's extra joints {', '.join(extra)})" if extra else ""
            raise ParamError(f"controller {self.source}: start_pose() returned {got}: expected "
                             f"gaits.control.StartPose(q) with {n} joint angles (JOINT_NAMES){more}")
        return pose

    def reset(self, m: Any) -> None:
        self.spent = 0.0
        self.call(self._ctl.reset, "reset()", m)

    def step(self, m: Any, command: Any = None) -> Any:
        q = self.call(self._ctl.step, lambda: f"step() at t = {m.t:.2f} s", m, command)
        if np.iscomplexobj(q):
            raise ParamError(f"controller {self.source}: step() at t = {m.t:.2f} s returned complex targets: "
                             f"expected real joint angles [rad]")
        return q

    def plan(self, n: int) -> Any:
        rec = self.call(self._ctl.plan, "plan()", n)
        if rec is None:
            raise ParamError(f"controller {self.source}: plan() returned None: expected a "
                             f"gaits.control.PlanRecord of what it planned over the walk's ticks")
        return rec


@dataclass(frozen=True)
class Drive:
    """A walk's parameter set, its stabiliser, and its command or command stream (module docstring);
    or a controller of the user's own (``user``, then ``params`` may be None)."""

    params: GaitParams | None
    stabiliser: StabiliserParams | None = None
    command: WalkCommand | None = None
    stream: CommandStream | None = None
    source: str = ""                       # where the set came from, for reports
    user: UserController | None = None
    engine: EngineParams | None = None     # the online walk engine drives the set (TLIPFM)
    residual: ResidualParams | None = None  # a trained correction on the engine's leg targets

    def __post_init__(self) -> None:
        if self.command is not None and self.stream is not None:
            raise ParamError("give a command or a command stream, not both")
        if self.params is None and self.user is None:
            raise ParamError("a drive needs a gait parameter set or a controller of your own")

    @classmethod
    def of(cls, gait_file: GaitFile, *, source: str = "", stabiliser: bool | None = None,
           command: WalkCommand | None = None, stream: CommandStream | None = None) -> "Drive":
        """The drive of a gait file: its stabiliser as the file says (``stabiliser=False`` switches it
        off; ``True`` requires one: a ParamError when the file has none)."""
        stab = gait_file.stabiliser
        if stabiliser is True and stab is None:
            raise ParamError(f"{source or 'the parameter set'} holds no stabiliser section")
        if stabiliser is False:
            stab = None
        return cls(gait_file.params, stab, command, stream, source, engine=gait_file.engine,
                   residual=gait_file.residual)

    @property
    def family(self) -> str:
        return "user" if self.user is not None else self.params.FAMILY

    @property
    def online(self) -> bool:
        """Whether the controller reads the walk command tick by tick (not from a table planned ahead)."""
        return self.user is not None or self.engine is not None

    def without_engine(self) -> "Drive":
        """The same set as a joint table (planned per step for a stream)."""
        return dataclasses.replace(self, engine=None, residual=None)

    def the_stream(self) -> CommandStream | None:
        """What an online controller reads: the stream, or a held command for :data:`ONLINE_DURATION_S`
        then a stop (the engine's own start and stop take the place of a table's ramp)."""
        if self.stream is not None:
            return self.stream
        if self.command is not None:
            return CommandStream.constant(self.command, ONLINE_DURATION_S)
        return None

    def run_options(self) -> dict:
        """What the loop needs besides the controller: the command stream an online controller reads
        (``commands``) and the walk's length (``duration``: the stream's, else :data:`ONLINE_DURATION_S`)."""
        if not self.online:
            return {}
        stream = self.the_stream()
        if stream is None:
            return {"duration": ONLINE_DURATION_S}
        return {"commands": stream, "duration": stream.duration}

    @property
    def closed_loop(self) -> bool:
        """Whether the walk reads the robot's sensors (the stabiliser)."""
        return self.stabiliser is not None and self.stabiliser.enabled

    def without_stabiliser(self) -> "Drive":
        return dataclasses.replace(self, stabiliser=None)

    def with_params(self, params: GaitParams) -> "Drive":
        return dataclasses.replace(self, params=params)

    def stream_commands(self) -> np.ndarray:
        """The per-step commands a table walks for the stream, ending with a stop step (n, 3)."""
        starts = self._stream_starts()
        return np.vstack([self.stream.per_step(starts), np.zeros((1, 3))])

    def _stream_starts(self) -> np.ndarray:
        fam = family_of(self.params)
        starts = fam.step_starts(self.params, MAX_STREAM_STEPS)
        n = int(np.sum(starts[:-1] < self.stream.duration))
        if n >= MAX_STREAM_STEPS:
            raise ParamError(f"the command stream lasts {self.stream.duration:g} s: more than "
                             f"{MAX_STREAM_STEPS} steps of this set")
        return starts[:n]

    def stream_rows_not_walked(self) -> list[int]:
        """A table walking a stream: the stream's rows no step of it starts in (shorter than a step,
        so never walked); an online walk reads every row at its tick: none."""
        if self.stream is None or self.online:
            return []
        return self.stream.rows_not_walked(self._stream_starts())

    def table(self, robot: RobotGeometry, dt: float) -> GaitTrajectory:
        """The joint table of this walk for a robot (``robot.leg``, ``robot.foot_size``)."""
        if self.user is not None:
            raise ParamError(f"controller {self.user.source} walks online: it has no joint table")
        fam = family_of(self.params)
        fam.check_stance(self.params, robot)
        if self.command is not None:
            return command_walk(self.params, robot, self.command, dt)
        if self.stream is not None:
            commands = self.stream_commands()
            traj = fam.walk(self.params, robot, dt, commands)
            traj.meta["stream"] = "planned per step"
            traj.meta["step_starts"] = fam.step_starts(self.params, len(commands)).tolist()
            return traj
        return fam.generate(self.params, robot.leg, dt)

    def key(self) -> tuple:
        """A hashable value that is equal for drives that walk the same (a cache key)."""
        stream = None if self.stream is None else (self.stream.t.tobytes(), self.stream.commands.tobytes(),
                                                   self.stream.tail)
        user = None if self.user is None else (self.user.source, tuple(sorted(self.user.params.items())))
        return (self.params, self.stabiliser, self.command, stream, user, self.engine, self.residual)

    def controller(self, robot: RobotGeometry, dt: float, table: GaitTrajectory | None = None) -> Controller:
        """The controller the loop runs: the table (``table``, or planned now), with the stabiliser
        around it when enabled."""
        if self.user is not None:
            ctl = self.user.build(robot, dt)
            return Stabilised(ctl, self.stabiliser) if self.closed_loop else ctl
        if self.engine is not None:
            fam = family_of(self.params)
            fam.check_stance(self.params, robot)
            limits = fam.step_limits(self.params, robot)
            if fam.engine == "feedback":
                ctl = WalkEngine(self.params, self.engine, robot, dt, limits)
                if self.residual is not None:
                    ctl = ResidualWalk(ctl, self.residual)
            else:
                ctl = OnlineTable(self.params, robot, dt, limits, preview=self.engine.preview_steps,
                                  idle=self.engine.idle)
            return Stabilised(ctl, self.stabiliser) if self.closed_loop else ctl
        ctl: Controller = TablePlayer(self.table(robot, dt) if table is None else table)
        if self.closed_loop:
            ctl = Stabilised(ctl, self.stabiliser)
        return ctl

    def describe(self) -> str:
        """One line: the set, how it is driven, and what it is asked to walk."""
        how = (f"controller {self.user.source}" if self.user is not None else
               ("the online walk engine" + (" with its trained residual" if self.residual is not None else "")
                if family_of(self.params).engine == "feedback"
                else "the online table (re-planned each step)") if self.engine is not None
               else "open-loop table") \
            + (" with the IMU stabiliser" if self.closed_loop else "")
        idle = self.engine is not None and self.command is None and self.stream is None
        what = (("no command: it steps in place" if self.engine.idle == "step" else
                 "no command: it stands where it started") if idle else
                "its own walk" if self.command is None and self.stream is None else
                (f"command {self.command} (vx m/s, vy m/s, wz rad/s, held {ONLINE_DURATION_S:g} s, then a stop)"
                 if self.online else f"command {self.command} (vx m/s, vy m/s, wz rad/s, ramped)")
                if self.command is not None else
                f"a command stream of {len(self.stream.t)} rows, "
                + ("read tick by tick" if self.online else "planned per step before the walk"))
        return f"{self.source or self.family}: {how}, {what}"
