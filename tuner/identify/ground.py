"""The ground identified from walking recordings, with the servos held at their identified values.

The simulated walk replays the recording's walk: the joint targets its controller asked, tick by
tick, through the robot's servo model (rate limit, latency, backlash from the robot map, which an
identification of the servos has written) on a candidate surface, from the recording's first
asked pose placed on the ground (a joint measured further from it than the encoders' noise allows
starts where it was measured: a learned walk's first action is no start pose). What the replay's sensors read is compared with what the robot's
read, tick by tick: torso roll and pitch, the gyro and the encoders, each in units of its sensor
noise (so a residual RMS of 1 is a fit down to the noise).

Ours, measured on replays (docs/identification.md): the accelerometer and the sole forces are not
in the fitted residual. At a foot strike they jump with the contact layer's drag gate (a sole
corner's damper switched on at a depth, per physics step), so a 0.1 % change of the layer's time
constant moves them by several noises while roll, pitch, gyro and encoders move smoothly; they
are compared after the fit instead (their peaks at foot strike, and the step period), and the
finite-difference step of the fit is 2 % for the same reason. And a replay is open loop: past a
few seconds the smallest differences (what the servo identification left, the fit's own) grow
into a different walk (on the benchmark's kid3kg, 1 noise of encoder residual over the first
3 s, 12-40 after 4-6 s, with servos identified to within 1-10 %), so each recording is fitted
over its first :data:`HORIZON` seconds: record several short walks rather than one long one.

What is fitted, as factors of the starting surface's values (bounded 0.3-3x): on the contact
layer its time constant (stiffness), damping ratio, friction and drag; on the blade layer its
modulus, damping, shear and friction; on a rigid floor its friction. ``mujoco.sysid`` gives the
parameters, the optimiser and the intervals; the model is our simulator's, built per candidate.
Friction is read only where the recording slips (a loaded sole sliding faster than
:data:`SLIP_SPEED` in the replay of the fitted ground, for :data:`MIN_SLIPS` ticks): else the fit
says it cannot tell it and keeps the starting value.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from gaits import JOINT_NAMES
from gaits.control import PlanRecord, StartPose

from ..errors import UserError
from ..robots.robot_model import RobotModel
from .servos import ENTANGLED, _sysid, optimize
from ..sim.ground import kind_of
from ..sim.randomisation import Randomisation
from ..sim.rollout import Simulator
from ..sim.surfaces import Surface

__all__ = ["WalkLog", "GroundFit", "identify_ground", "ground_fields", "Replay", "replay", "walk_statistics",
           "NOISE", "read_walk_logs", "walk_logs", "channel_rms"]

#: the sensor noise of each fitted channel (the randomisation's defaults): roll and pitch [rad],
#: gyro [rad/s], encoders [rad]
_DEFAULTS = Randomisation()
NOISE = {"rpy": math.radians(_DEFAULTS.imu_noise_deg), "gyro": _DEFAULTS.gyro_noise, "q": _DEFAULTS.encoder_noise}
FACTOR_BOUNDS = (0.3, 3.0)
FD_STEP = 0.02
NARROW = 0.15            # a factor is identified when its 95 % interval is within 15 % of it (ours)
GRID_SPAN = 2.0          # the first grid: the two main fields from half to twice the start (ours)
GRID_POINTS = 7
SLIP_SPEED = 0.05        # [m/s] a loaded sole sliding faster than this slips (ours)
MIN_SLIPS = 3            # ticks of slipping the recordings need for friction to be read (ours)
HORIZON = 3.0            # [s] of each recording the replays are fitted over (ours: see the module docstring)
START_NOISES = 5.0       # a joint starts at its measured angle where that is this many noises from the asked (ours)


def ground_fields(s: Surface) -> tuple[str, ...]:
    """The surface fields a walk can tell (see the module docstring), the two main ones first: its
    kind of ground's (``tuner/sim/ground/``)."""
    return kind_of(s).fit_fields()


@dataclass
class WalkLog:
    """One walking recording on the control period's grid: ``targets`` (N, 20) what the controller
    asked at each tick (``gaits.JOINT_NAMES`` order), and what the robot read then: ``rpy`` (N, 3),
    ``gyro`` (N, 3), ``accel`` (N, 3) or None, ``q`` (N, n) the encoders of ``joints``."""

    name: str
    dt: float
    targets: np.ndarray
    joints: tuple[str, ...]
    q: np.ndarray
    rpy: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray | None = None


    def first(self, seconds: float) -> "WalkLog":
        """The log's first ``seconds`` (all of it when shorter)."""
        n = min(len(self.targets), int(round(seconds / self.dt)) + 1)
        cut = {k: (v[:n] if v is not None else None) for k, v in
               (("targets", self.targets), ("q", self.q), ("rpy", self.rpy), ("gyro", self.gyro), ("accel", self.accel))}
        return dataclasses.replace(self, **cut)


class Replay:
    """A controller that asks what a recording's controller asked, tick by tick, and keeps what it
    is given to read (the simulated sensors, clean)."""

    senses = frozenset({"q", "imu_rpy", "gyro", "accel"})

    def __init__(self, targets: np.ndarray, dt: float, start: np.ndarray | None = None) -> None:
        self.targets = np.asarray(targets, dtype=float)
        self.dt = dt
        self.start = self.targets[0].copy() if start is None else np.asarray(start, dtype=float)
        self.duration = len(self.targets) * dt          # a reading at each of the targets' ticks
        self.read: list = []
        self._k = 0

    def start_pose(self) -> StartPose:
        return StartPose(self.start.copy(), np.zeros(2))

    def reset(self, m) -> None:
        self._k = 0
        self.read = []

    def step(self, m, command=None) -> np.ndarray:
        self.read.append((m.imu_rpy.copy(), m.gyro.copy(), None if m.accel is None else m.accel.copy(),
                          m.q.copy()))
        q = self.targets[min(self._k, len(self.targets) - 1)]
        self._k += 1
        return q

    def plan(self, n: int) -> PlanRecord:
        z = np.zeros((n, 2))
        return PlanRecord("replay", np.zeros(n, dtype=int), z, z, z, 0.0, 1.0)


def replay(robot: RobotModel, surface: Surface, log: WalkLog) -> dict[str, np.ndarray]:
    """The recording's walk replayed on ``surface``: per tick the simulated rpy, gyro, accel and
    encoders (rows as the log's; a replay that falls holds its last reading), and ``fell``."""
    sim = Simulator(robot, surface)
    # the walk starts where the robot stood: the first asked pose (an engine's is its start pose, to
    # the bit), but a joint whose first measured angle is further from it than START_NOISES of the
    # encoders' noise starts there (a learned walk's first action is no start pose: Wolfgang-OP's is
    # up to 0.33 rad from it) (ours)
    start = np.array(log.targets[0], dtype=float)
    for col, j in enumerate(log.joints):
        if j in JOINT_NAMES:
            i = JOINT_NAMES.index(j)
            if abs(log.q[0, col] - start[i]) > START_NOISES * NOISE["q"]:
                start[i] = log.q[0, col]
    rep = Replay(log.targets, log.dt, start)
    trace = sim.run(rep, duration=rep.duration, height_check=True)
    n = len(log.targets)
    got = rep.read[:n]
    rows = got + [got[-1]] * (n - len(got))
    cols = [sim.joint_names.index(j) for j in log.joints]
    # slips: a loaded sole (its four quadrants carrying over a fifth of the weight) whose centre moves
    # horizontally faster than SLIP_SPEED
    weight = float(sim.model.body_subtreemass[sim.model.body(robot.torso).id]) * 9.81
    slips = 0
    for side, p_sole in enumerate((trace.p_sole_l, trace.p_sole_r)):
        loaded = trace.force[1:, 4 * side:4 * side + 4].sum(axis=1) > 0.2 * weight
        speed = np.linalg.norm(np.diff(p_sole[:, :2], axis=0), axis=1) / log.dt
        slips += int(np.sum(loaded & (speed > SLIP_SPEED)))
    out = {"slips": np.array(slips), "rpy": np.array([r[0] for r in rows]), "gyro": np.array([r[1] for r in rows]),
           "accel": np.array([r[2] for r in rows]) if rows[0][2] is not None else None,
           "q": np.array([r[3][cols] for r in rows]), "fell": np.array(trace.fell)}
    return out


def residual_of(sim: dict, log: WalkLog) -> np.ndarray:
    """Measured minus replayed, each in units of its sensor noise: roll, pitch, gyro, encoders."""
    return np.concatenate([((log.rpy[:, :2] - sim["rpy"][:, :2]) / NOISE["rpy"]).ravel(),
                           ((log.gyro - sim["gyro"]) / NOISE["gyro"]).ravel(),
                           ((log.q - sim["q"]) / NOISE["q"]).ravel()])


def walk_statistics(rpy: np.ndarray, accel: np.ndarray | None, dt: float) -> dict[str, float]:
    """What a team compares between a robot's walk and the simulator's (ours): torso pitch and roll
    RMS [deg] about their means, the roll's main frequency and the step period it implies (one
    step per half roll cycle) [s], the pitch spectrum's main frequency [Hz], and the
    accelerometer's mean peak per step [m/s^2] (the largest |a| within each step period)."""
    out: dict[str, float] = {}
    roll, pitch = rpy[:, 0], rpy[:, 1]
    out["pitch_rms_deg"] = float(np.degrees(np.std(pitch)))
    out["roll_rms_deg"] = float(np.degrees(np.std(roll)))
    n = len(roll)
    f = np.fft.rfftfreq(n, dt)
    band = (f > 0.3) & (f < 10.0)
    for name, sig in (("roll", roll), ("pitch", pitch)):
        spec = np.abs(np.fft.rfft(sig - sig.mean()))
        out[f"{name}_freq_hz"] = float(f[band][np.argmax(spec[band])]) if band.any() else math.nan
    out["step_period_s"] = 0.5 / out["roll_freq_hz"] if out["roll_freq_hz"] > 0 else math.nan
    if accel is not None and math.isfinite(out["step_period_s"]):
        w = max(1, int(round(out["step_period_s"] / dt)))
        mag = np.linalg.norm(accel, axis=1)
        peaks = [mag[i:i + w].max() for i in range(0, n - w + 1, w)]
        out["accel_peak_mps2"] = float(np.mean(peaks)) if peaks else math.nan
    return out


@dataclass
class GroundFit:
    """An identification of the ground: the surface fitted, its parameters with 95 % intervals,
    the residual per channel before and after (RMS in noise units), the statistics of the
    recordings and of the replays before and after."""

    surface: Surface
    start: Surface
    values: dict[str, float]               # field -> fitted factor of the start's value
    intervals: dict[str, float]
    identifiable: dict[str, bool]
    entangled: list[list[str]]
    rms_before: dict[str, float]           # channel -> RMS [noise units]
    rms_after: dict[str, float]
    stats: dict[str, dict[str, float]]     # "recorded", "before", "after" -> statistics (first recording)
    rollouts: int
    seconds: float
    recordings: list[str] = field(default_factory=list)
    slips: int = 0                         # ticks a loaded sole slid in the replays of the fitted ground
    sysid: dict = field(default_factory=dict)    # mujoco.sysid's own: initial and fitted ParameterDict, cov, half

    @property
    def not_identifiable(self) -> list[str]:
        return [k for k, ok in self.identifiable.items() if not ok]

    @property
    def converged(self) -> bool:
        """Every channel's residual finite after the fit, their sum no larger than the start's (to 1e-4):
        a fit that matches the recordings no better than the start did is not written (ours)."""
        if not all(np.isfinite(v) for v in self.rms_after.values()):
            return False
        return sum(self.rms_after.values()) <= sum(self.rms_before.values()) * 1.0001

    def to_json(self) -> dict:
        """The fit as ``identify ground --json`` gives it (an interval with no bound: null)."""
        return {"values": self.values,
                "intervals": {k: (v if np.isfinite(v) else None) for k, v in self.intervals.items()},
                "identifiable": self.identifiable, "rms_before": self.rms_before, "rms_after": self.rms_after,
                "replays": self.rollouts}


def _channels(r: np.ndarray, log: WalkLog) -> dict[str, float]:
    n = len(log.targets)
    a = 2 * n
    b = a + 3 * n
    return {"roll+pitch": float(np.sqrt(np.mean(r[:a] ** 2))), "gyro": float(np.sqrt(np.mean(r[a:b] ** 2))),
            "encoders": float(np.sqrt(np.mean(r[b:] ** 2)))}


def channel_rms(r: np.ndarray, logs: list[WalkLog]) -> dict[str, float]:
    """The RMS per channel (roll and pitch, gyro, encoders) [noise units] of a residual over
    ``logs`` (:func:`residual_of`'s, the logs one after the other)."""
    out: dict[str, list[float]] = {}
    o = 0
    for log in logs:
        n = len(log.targets) * (5 + len(log.joints))
        for k, v in _channels(r[o:o + n], log).items():
            out.setdefault(k, []).append(v ** 2)
        o += n
    return {k: float(np.sqrt(np.mean(v))) for k, v in out.items()}


def identify_ground(robot: RobotModel, start: Surface, logs: list[WalkLog], *, max_iters: int = 25,
                    threads: int | None = None, progress=None, horizon: float = HORIZON,
                    trace=None) -> GroundFit:
    """Fit ``start``'s :func:`ground_fields` to the walks in ``logs`` (the module's docstring), each
    over its first ``horizon`` seconds; ``trace`` (a text stream) gets the optimiser's iterations."""
    sysid = _sysid()
    if not logs:
        raise UserError("no recordings to identify from")
    logs = [log.first(horizon) for log in logs]
    for log in logs:
        if abs(log.dt - robot.sim.control_period) > 1e-9:
            raise UserError(f"{log.name}: its ticks are {log.dt * 1000:g} ms apart; the robot's control period "
                            f"is {robot.sim.control_period * 1000:g} ms")
    fields_ = ground_fields(start)
    params = sysid.ParameterDict()
    lo, hi = FACTOR_BOUNDS
    for f in fields_:
        params.add(sysid.Parameter(f, nominal=1.0, min_value=lo, max_value=hi))

    def surface_of(p) -> Surface:
        kw = {f: getattr(start, f) * float(p[f].value[0]) for f in fields_}
        if "layer_dampratio" in kw:
            kw["layer_dampratio"] = min(max(kw["layer_dampratio"], 0.1), 5.0)
        return dataclasses.replace(start, **kw)

    n_threads = max(1, min(threads or os.cpu_count() or 1, 8))
    pool = ThreadPoolExecutor(n_threads) if n_threads > 1 else None
    counter = {"rollouts": 0}

    def one(surface: Surface) -> np.ndarray:
        return np.concatenate([residual_of(replay(robot, surface, log), log) for log in logs])

    def residual_fn(x: np.ndarray, p):
        cols = x.reshape(len(x), -1) if x.ndim > 1 else x.reshape(-1, 1)
        surfaces = []
        for c in range(cols.shape[1]):
            p.update_from_vector(cols[:, c])
            surfaces.append(surface_of(p))
        rows = list(pool.map(one, surfaces)) if pool is not None and len(surfaces) > 1 else [one(s) for s in surfaces]
        counter["rollouts"] += len(surfaces) * len(logs)
        if progress is not None:
            progress(counter["rollouts"])
        r = np.stack(rows, axis=1)
        return [r if x.ndim > 1 else r[:, 0]], None, None

    t0 = time.monotonic()
    initial = params.copy()
    try:
        r0 = residual_fn(params.as_vector(), params.copy())[0][0]
        # the misfit is rough at small scales (module docstring): first the two main fields on a
        # coarse grid, then a finer one about its best, then the optimiser from there (ours)
        main = list(range(min(2, len(fields_))))
        best_x, best_c = params.as_vector().copy(), float(np.dot(r0, r0))
        for span, n in ((GRID_SPAN, GRID_POINTS), (GRID_SPAN ** 0.25, GRID_POINTS - 2)):
            axes = [best_x[i] * np.geomspace(1 / span, span, n) for i in main]
            mesh = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(main))
            cand = np.repeat(best_x[:, None], len(mesh), axis=1)
            cand[main, :] = np.clip(mesh.T, lo, hi)
            r = residual_fn(cand, params.copy())[0][0]
            costs = np.einsum("ij,ij->j", r, r)
            j = int(np.argmin(costs))
            if costs[j] < best_c:
                best_c, best_x = float(costs[j]), cand[:, j].copy()
        params.update_from_vector(best_x)
        opt, result = optimize(sysid, params, residual_fn, max_iters=max_iters, eps=FD_STEP, trace=trace)
        x = np.asarray(result.x, dtype=float)
        opt.update_from_vector(x)
        r1 = residual_fn(x, opt.copy())[0][0]
        cov, half = sysid.calculate_intervals([r1], np.asarray(result.jac))
    finally:
        if pool is not None:
            pool.shutdown()
    values = {f: float(v) for f, v in zip(fields_, x)}
    intervals = {f: float(w) for f, w in zip(fields_, half)}
    identifiable = {f: bool(math.isfinite(intervals[f]) and intervals[f] < NARROW * abs(values[f])) for f in fields_}
    entangled: list[list[str]] = []
    if cov.size:
        sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
        corr = cov / np.outer(sd, sd)
        for i in range(len(fields_)):
            for j in range(i + 1, len(fields_)):
                if abs(corr[i, j]) > ENTANGLED:
                    entangled.append([fields_[i], fields_[j]])
    slips = 0
    if "friction" in identifiable:
        best = opt.copy()
        slips = sum(int(replay(robot, surface_of(best), log)["slips"]) for log in logs)
        if slips < MIN_SLIPS:
            identifiable["friction"] = False
    kept = opt.copy()
    for f, ok in identifiable.items():
        if not ok:
            kept[f].value[:] = 1.0
    fitted = surface_of(kept)
    r_kept = one(fitted) if any(not ok for ok in identifiable.values()) else r1

    log0 = logs[0]
    stats = {"recorded": walk_statistics(log0.rpy, log0.accel, log0.dt)}
    for key, s in (("before", start), ("after", fitted)):
        sim = replay(robot, s, log0)
        stats[key] = walk_statistics(sim["rpy"], sim["accel"], log0.dt)
    fitted = dataclasses.replace(fitted, name=f"{start.name}-identified")
    return GroundFit(surface=fitted, start=start, values=values, intervals=intervals, identifiable=identifiable,
                     entangled=entangled, rms_before=channel_rms(r0, logs), rms_after=channel_rms(r_kept, logs), stats=stats,
                     rollouts=counter["rollouts"], seconds=time.monotonic() - t0,
                     recordings=[log.name for log in logs], slips=slips,
                     sysid={"initial": initial, "fitted": opt, "cov": cov, "half": half})


def walk_log(name: str, dt: float, t_targets_q, rpy, gyro, accel, joints) -> WalkLog:
    """A :class:`WalkLog` from a recording on the grid: targets of the recording's joints are put in
    ``gaits.JOINT_NAMES`` order (a joint the recording lacks asks 0, the held pose)."""
    _, targets, q = t_targets_q
    full = np.zeros((len(targets), len(JOINT_NAMES)))
    for i, j in enumerate(joints):
        if j in JOINT_NAMES:                   # a robot's extra joint: held at its pose in the replay
            full[:, JOINT_NAMES.index(j)] = targets[:, i]
    return WalkLog(name, dt, full, tuple(joints), q, rpy, gyro, accel)


def read_walk_logs(paths, robot: RobotModel, topics=None) -> tuple[list[WalkLog], list[str]]:
    """Walking recordings read onto the robot's control period (:func:`walk_logs`); a recording
    that cannot serve is one line (UserError)."""
    from .field_recordings import RecordingError, read_field_recording
    read = []
    for path in paths:
        try:
            read.append((path, read_field_recording(path, topics=topics, robot_joints=robot.joint_map)))
        except RecordingError as exc:
            raise UserError(str(exc)) from None
    return walk_logs(read, robot)


def walk_logs(read, robot: RobotModel) -> tuple[list[WalkLog], list[str]]:
    """Recordings already read (``(path, FieldRecording)`` pairs) as walks on the robot's control
    period (:func:`walk_log`), and the notes of their gaps (three a file at most); one that cannot
    serve is one line (UserError)."""
    from .field_recordings import RecordingError
    dt = robot.sim.control_period
    logs, notes = [], []
    for path, rec in read:
        try:
            joints = [j for j in rec.joints if j in robot.joint_map]
            grid = rec.on_grid(dt, joints)
            imu = rec.imu_on_grid(grid[0], rec.grid_start)
        except RecordingError as exc:
            raise UserError(str(exc)) from None
        notes += [f"{path}: {gap}" for gap in rec.gaps[:3]]
        logs.append(walk_log(str(path), dt, grid, imu["rpy"], imu["gyro"], imu["accel"], joints))
    return logs, notes
