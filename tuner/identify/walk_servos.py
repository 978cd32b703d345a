"""What a walk tells of the robot's servos, fitted from walking recordings (no harness).

A team has walks from its games, rarely a sweep of the robot hanging. A walk's contacts carry the
legs, so the harness' model (the torso held, no foot touching: :mod:`tuner.identify.servos`) cannot
be fitted to it. The walk's own replay can (:func:`tuner.identify.ground.replay`: the recording's
joint targets, tick by tick, through the robot's servos, on the surface it walked on, open loop from
the first measured pose), and what it compares (torso roll and pitch, gyro, encoders, each in its
sensor noise) moves with a few of the servos' numbers. An open-loop replay drifts from the walk as it
goes (a learned walk's feedback is not in it: on Wolfgang-OP's, 3 s of replay drift to 100 noises),
so the horizon grows: half a second first, then 1 and 2 s and the first ``horizon`` seconds
(:data:`HORIZON_STAGES`), each from the last one's estimates, a longer one kept only while its
replays stay within :data:`ACCEPT_NOISES` of the recordings (the report says which horizon).

* the **latency** (command to servo, one for the robot): the whole walk's timing moves with it. The
  simulator queues commands in whole control ticks, so it is read by trying each of 0 to
  :data:`LATENCY_MAX_TICKS` ticks (a longer horizon, the counts next to a shorter one's); it is
  identified when no other count tried comes within the misfit's 95 % band (``chi2`` of one degree
  of freedom, 3.84, on the residual scaled to its own variance);
* the legs' **position gain** ``kp`` per group (hips, knees, ankles): how far a loaded leg gives under
  the robot's weight shows in every stance.

What a walk cannot tell, and is kept from the map (say so; fit it on a sweep hanging, ``gait-tuner
excite``): the damping (measured, docs/servos.md: fitted beside the gains on a 3 s walk it came out
27 % off on the hips with a 95 % interval of 5 %, moving with the ankles'; the residual was at the
noise either way), the armature and the dry friction (the contacts and the surface's own damping
hide them), the torque and speed limits (a walk that saturates its servos falls), the backlash, and
the arms' and head's servos (they barely move). The ground is held at the surface named (``identify
ground`` fits it, with the servos held): fit the servos on a sweep or on rigid-floor walks first.

Ours throughout (the fields, the horizon, the latency band); ``mujoco.sysid`` gives the optimiser and
the intervals, as for the harness fit.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..errors import UserError
from ..robots.robot_model import RobotModel
from ..servos import MotorServo
from ..sim.surfaces import Surface
from .ground import HORIZON, WalkLog, channel_rms, replay, residual_of
from .servos import LATENCY_MAX_TICKS, NARROW, _entangled, _sysid, group_of, optimize

__all__ = ["WalkServoFit", "identify_servos_from_walks", "WALK_GROUPS", "WALK_FIELDS", "NOT_FROM_A_WALK",
           "LATENCY_BAND", "scaled_gain", "walk_servo_overlay"]

#: the servo groups and fields a walk is fitted for (ours: see the module docstring)
WALK_GROUPS = ("hips", "knees", "ankles")
WALK_FIELDS = ("kp",)
#: what a walk cannot tell (kept from the map)
NOT_FROM_A_WALK = ("damping", "armature", "frictionloss", "torque", "speed", "back_emf", "backlash",
                   "the arms' and head's servos")
FACTOR_BOUNDS = (0.2, 5.0)
#: the finite-difference step of the Jacobian: 2 %, as the ground's (a replay's misfit is rough at
#: smaller scales: contacts switch)
FD_STEP = 0.02
#: a latency count is within the 95 % band when its misfit exceeds the best one's by less than this
#: many times the residual's variance (chi2, one degree of freedom)
LATENCY_BAND = 3.84
#: the horizons a fit grows through [s], and how close a replay must stay to the recordings to keep
#: a longer one (every channel's RMS, in sensor noises) (ours: on Wolfgang-OP's learned walk a 3 s
#: replay drifts to 100 noises even from the true servos' neighbourhood, 0.5 s keeps it at the noise)
HORIZON_STAGES = (0.5, 1.0, 2.0)
ACCEPT_NOISES = 2.0


@dataclass
class WalkServoFit:
    """What a walk identified: the robot with its servos fitted (``robot``), per parameter
    (``hips.kp``... factors of the map's) its value, 95 % interval and whether the walks fixed it,
    the latency in whole ticks with each count's misfit, and the residual per channel before and
    after [RMS in sensor noises]."""

    robot: RobotModel
    values: dict[str, float]
    intervals: dict[str, float]
    identifiable: dict[str, bool]
    latency_ticks: int
    latency_misfit: dict[int, float]          # ticks -> sum of squared residuals
    latency_identified: bool
    rms_before: dict[str, float]
    rms_after: dict[str, float]
    rollouts: int
    seconds: float
    recordings: list[str] = field(default_factory=list)
    entangled: list[list[str]] = field(default_factory=list)
    groups: dict[str, tuple[str, ...]] = field(default_factory=dict)   # fitted group -> its servos (theirs)
    horizon: float = HORIZON                  # [s] of each recording the kept fit replays

    @property
    def converged(self) -> bool:
        """Every channel finite after the fit and the sum no larger than before (to 1e-4)."""
        if not all(np.isfinite(v) for v in self.rms_after.values()):
            return False
        return sum(self.rms_after.values()) <= sum(self.rms_before.values()) * 1.0001


def scaled_gain(servo, kp: float):
    """``servo`` with its position gain scaled by ``kp`` (a motor's through its P register:
    ``MotorServo.with_pieces``)."""
    if isinstance(servo, MotorServo):
        return servo.with_pieces(kp=servo.kp * kp)
    return servo.replace(kp=servo.kp * kp)


def identify_servos_from_walks(robot: RobotModel, surface: Surface, logs: list[WalkLog], *, max_iters: int = 20,
                               threads: int | None = None, progress=None, horizon: float = HORIZON,
                               trace=None) -> WalkServoFit:
    """Fit what the walks in ``logs`` tell of ``robot``'s servos (the module's docstring) on
    ``surface``, each recording over its first seconds, up to ``horizon`` (the horizon grows while
    the replays follow: the module's docstring). ``progress(replays)`` after each batch; ``trace`` (a
    text stream) gets the optimiser's iterations."""
    sysid = _sysid()
    if not logs:
        raise UserError("no recordings to identify from")
    dt = robot.sim.control_period
    for log in logs:
        if abs(log.dt - dt) > 1e-9:
            raise UserError(f"{log.name}: its ticks are {log.dt * 1000:g} ms apart; the robot's control period "
                            f"is {dt * 1000:g} ms")
    groups: dict[str, tuple[str, ...]] = {}
    for ours, (theirs, _sign) in robot.joint_map.items():
        g = group_of(ours)
        if g in WALK_GROUPS and theirs in robot.servos:
            groups.setdefault(g, tuple())
            groups[g] += (theirs,)
    groups = {g: groups[g] for g in WALK_GROUPS if g in groups}
    if not groups:
        raise UserError(f"robot {robot.name!r}: no leg servos to identify from a walk")
    names = [f"{g}.{f}" for g in groups for f in WALK_FIELDS]
    lo, hi = FACTOR_BOUNDS

    def candidate(x: np.ndarray, ticks: int) -> RobotModel:
        v = dict(zip(names, x))
        servos = dict(robot.servos)
        for g, joints in groups.items():
            for t in joints:
                servos[t] = scaled_gain(robot.servos[t], v[f"{g}.kp"])
        servos = {t: s.replace(latency=ticks * dt) for t, s in servos.items()}
        return dataclasses.replace(robot, servos=servos)

    n_threads = max(1, min(threads or os.cpu_count() or 1, 8))
    pool = ThreadPoolExecutor(n_threads) if n_threads > 1 else None
    counter = {"rollouts": 0}

    def residuals(robots: list[RobotModel], cut: list[WalkLog]) -> list[np.ndarray]:
        def one(r: RobotModel) -> np.ndarray:
            return np.concatenate([residual_of(replay(r, surface, log), log) for log in cut])
        rows = list(pool.map(one, robots)) if pool is not None and len(robots) > 1 else [one(r) for r in robots]
        counter["rollouts"] += len(robots) * len(cut)
        if progress is not None:
            progress(counter["rollouts"])
        return rows

    def stage(cut: list[WalkLog], x0: np.ndarray, around: int | None = None) -> dict:
        """One horizon's fit from ``x0``: the latency scanned (every count, or the counts next to
        ``around``, a shorter horizon's), the gains by Levenberg-Marquardt, the latency again at the
        fitted gains."""
        counts = range(int(LATENCY_MAX_TICKS) + 1) if around is None else \
            range(max(0, around - 1), min(int(LATENCY_MAX_TICKS), around + 1) + 1)

        def scan(x: np.ndarray) -> dict[int, float]:
            rows = residuals([candidate(x, k) for k in counts], cut)
            return {k: float(np.dot(r, r)) for k, r in zip(counts, rows)}
        misfit = scan(x0)
        state = {"ticks": min(misfit, key=misfit.get)}
        params = sysid.ParameterDict()
        for n, v in zip(names, x0):
            params.add(sysid.Parameter(n, nominal=float(v), min_value=lo, max_value=hi))

        def residual_fn(xv: np.ndarray, p):
            cols = xv.reshape(len(xv), -1) if xv.ndim > 1 else xv.reshape(-1, 1)
            r = np.stack(residuals([candidate(cols[:, c], state["ticks"]) for c in range(cols.shape[1])], cut), axis=1)
            return [r if xv.ndim > 1 else r[:, 0]], None, None

        opt, result = optimize(sysid, params, residual_fn, max_iters=max_iters, eps=FD_STEP, trace=trace)
        x = np.clip(np.asarray(result.x, dtype=float), lo, hi)
        misfit = scan(x)
        state["ticks"] = ticks = min(misfit, key=misfit.get)
        r1 = residual_fn(x, opt.copy())[0][0]
        cov, half = sysid.calculate_intervals([r1], np.asarray(result.jac))
        return {"x": x, "ticks": ticks, "misfit": misfit, "r1": r1, "cov": cov, "half": half, "logs": cut,
                "rms": channel_rms(r1, cut)}

    t0 = time.monotonic()
    try:
        # an open-loop replay drifts from the recorded walk as it goes (a learned walk's feedback is
        # not replayed): the horizon grows from half a second, each stage from the last one's
        # estimates, and a longer one is kept only while its replays stay within ACCEPT_NOISES of
        # the recordings (ours)
        longest = min(horizon, max((len(log.targets) - 1) * log.dt for log in logs))
        steps = [h for h in HORIZON_STAGES if h < longest - 1e-9] + [longest]
        best = None
        for h in steps:
            got = stage([log.first(h) for log in logs], np.ones(len(names)) if best is None else best["x"],
                        None if best is None else best["ticks"])
            if best is not None and max(got["rms"].values()) > ACCEPT_NOISES:
                break
            best, used = got, h
            if max(got["rms"].values()) > ACCEPT_NOISES:
                break                      # the shortest horizon already drifts: reported as it is
        cut = best["logs"]
        mapped = int(round(max((s.latency for s in robot.servos.values()), default=0.0) / dt))
        r0 = residuals([candidate(np.ones(len(names)), mapped)], cut)[0]
        x, ticks, misfit, r1 = best["x"], best["ticks"], best["misfit"], best["r1"]
        values = {n: float(v) for n, v in zip(names, x)}
        intervals = {n: float(w) for n, w in zip(names, best["half"])}
        identifiable = {n: bool(math.isfinite(intervals[n]) and intervals[n] < NARROW["x"] * abs(values[n]))
                        for n in names}
        entangled = _entangled(names, best["cov"], identifiable)
        # the latency's band: the residual scaled to its own variance at the best count
        variance = misfit[ticks] / max(1, len(r1) - len(names) - 1)
        band = [k for k, c in misfit.items() if k == ticks or c - misfit[ticks] < LATENCY_BAND * variance]
        # what is written: a gain or a latency the walks did not fix keeps the map's
        kept = np.array([values[n] if identifiable[n] else 1.0 for n in names])
        kept_ticks = ticks if band == [ticks] else mapped
        fitted = candidate(kept, kept_ticks)
        r_kept = r1 if all(identifiable.values()) and kept_ticks == ticks else residuals([fitted], cut)[0]
    finally:
        if pool is not None:
            pool.shutdown()
    return WalkServoFit(robot=fitted, values=values, intervals=intervals, identifiable=identifiable,
                        latency_ticks=ticks, latency_misfit=misfit, latency_identified=band == [ticks],
                        rms_before=channel_rms(r0, cut), rms_after=channel_rms(r_kept, cut),
                        rollouts=counter["rollouts"], seconds=time.monotonic() - t0,
                        recordings=[log.name for log in logs], entangled=entangled, groups=groups, horizon=used)


def walk_servo_overlay(fit: WalkServoFit, robot: RobotModel) -> dict[str, dict]:
    """The map's ``servo:`` entries a walk's fit sets: per leg group the gain it identified (a
    motor's P register, a pd servo's kp; a group whose servos differ, per joint by our name), and
    the latency (on each leg group: the simulator takes the largest)."""
    ours_of = {theirs: ours for ours, (theirs, _s) in robot.joint_map.items()}
    out: dict[str, dict] = {}
    for g, joints in fit.groups.items():
        entry: dict[str, dict] = {}
        if fit.identifiable.get(f"{g}.kp"):
            for t in joints:
                s = fit.robot.servos[t]
                f, v = ("p_gain", s.p_gain) if isinstance(s, MotorServo) else ("kp", s.kp)
                entry.setdefault(f, {})[t] = float(f"{v:.6g}")
        flat: dict = {}
        for f, per in entry.items():
            vals = list(per.values())
            if all(math.isclose(v, vals[0], rel_tol=1e-9) for v in vals):
                flat[f] = vals[0]
            else:
                for t, v in per.items():
                    out.setdefault(ours_of[t], {})[f] = v
        if fit.latency_identified:
            flat["latency"] = float(f"{fit.latency_ticks * robot.sim.control_period:.6g}")
        if flat:
            out[g] = flat
    return out
