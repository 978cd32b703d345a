"""The robot's servos identified from recordings, with MuJoCo's system identification toolbox.

``mujoco.sysid`` (the ``mujoco[sysid]`` extra; our one adapter to it) gives the parameters (a
``ParameterDict`` of bounded ``Parameter``s, the model-side ones written into the robot's MjSpec by
their modifiers and compiled by ``apply_param_modifiers``), the optimiser (``optimize``: MuJoCo's
box-bounded Levenberg-Marquardt, finite differences batched) and the confidence intervals
(``calculate_intervals``). What it has no piece for is ours: the rollout, because a servo's command
path (rate limit, latency, backlash dead band: :mod:`tuner.identify.harness`) runs between the
recording's targets and MuJoCo's controls, tick by tick.

What is fitted (ours): per joint group (hips, knees, ankles, arms, head; or per joint) the
position gain ``kp``, the joint's ``damping``, ``armature`` and ``frictionloss``, the servo's
``torque`` limit (a motor's stall torque), its ``back_emf`` (a dc-motor servo's damping outside the
clamp, kt^2 / R: with the stall torque it fixes kt and R) or ``speed`` (a pd servo's cap on its
target's speed), and the ``backlash`` (dead band width), and one ``latency`` for the robot (one
bus). A law's piece that does not exist (a pd servo's back-EMF, a motor's target cap) is not fitted. The velocity feedback ``kv`` is held at the map's value: it and the joint's
damping are one viscous torque on the same joint velocity, which no recording can tell apart.
Gains, damping, armature, friction and limits are fitted as factors of the map's values
(bounded 0.2-5x: a fit that wants more says so); the backlash in mrad and the latency in ticks.

A dc-motor servo's friction beyond Coulomb and viscous (BAM's extended forms, ``tuner/servos/motor.py``)
is fitted where asked (``--fit ...,stribeck,stribeck_speed,load_motor``: not by default, each
adds a rollout per unit to every Jacobian): the extra dry friction near rest ``stribeck`` [N m] and
its speed scale ``stribeck_speed`` [rad/s], and the dry friction per N m of the motor's own torque
``load_motor`` [-] (BAM's directional load term, M5), in absolute units from the map's values (none
for an M1 servo); the servo then runs them as a per-step term (BAM's M5 form, or the map's M6 with
its other terms kept) and is written so.

The residual: measured minus predicted joint angles at every tick after the first, over every
recording, in units of ``noise`` [rad] (the encoders' resolution; so a residual RMS of 1 is a fit
down to the sensor noise). A parameter is *identified* from the recordings when its 95 % interval
(``calculate_intervals``, which accounts for the others) is finite and narrow (:data:`NARROW`)
and, for a torque or speed limit, the limit binds somewhere in the recordings at the fitted value.
Estimates that move together (correlation past :data:`ENTANGLED`: what the recordings fix is
their combination) are named. One that
is not is named so: where the recordings do not move it at all it keeps the map's value (a
factor 1; the map's backlash and latency, none unless an earlier identification wrote them), where
they fix it loosely (a light head's gain, armature and damping: only their ratios show) it keeps
its fitted value. The residual reported is the one of what is written.
"""

from __future__ import annotations

import io
import logging
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..errors import UserError
from ..robots.robot_model import fine_group, joint_group
from ..servos.law import FRICTION_ROW_MIN
from ..servos.motor import (FRICTION_ALPHA, FRICTION_BACK_EMF, FRICTION_BASE, FRICTION_FLAGS, FRICTION_LOAD_MOTOR, FRICTION_MAGIC,
                            FRICTION_STRIBECK, FRICTION_STRIBECK_SPEED)
from .harness import Harness, ServoArrays

__all__ = ["JointLog", "ServoFit", "identify_servos", "FIT_GROUPS", "group_of", "SCALED", "EXTENDED", "FITTABLE", "unit_of"]

#: joint groups a fit shares parameters over (ours: a robot's servos are usually one model per group)
FIT_GROUPS = ("hips", "knees", "ankles", "arms", "head")
#: fields fitted as factors of the map's servo
SCALED = ("kp", "damping", "armature", "frictionloss", "torque", "back_emf", "speed")
FACTOR_BOUNDS = (0.2, 5.0)
#: the servo's limits: fitted in a second stage, kept where they lower the misfit by LIMIT_GAIN (ours)
LIMITS = ("torque", "speed")
LIMIT_GAIN = 0.02
LIMIT_MISFIT = 1.2         # ... and only tried where the first stage leaves a misfit over this many noises
#: the finite-difference step of the Jacobian, on parameters of order one (factors, mrad, ticks) (ours:
#: MuJoCo's constraint solver stops at a tolerance, so a step near the machine's precision differences noise)
FD_STEP = 1e-4
#: a joint whose residual stays over this many times the sensor noise is one the fit does not follow
FOLLOW_NOISE = 5.0
BACKLASH_MAX_MRAD = 60.0
LATENCY_MAX_TICKS = 8.0
#: a dc-motor servo's extended friction, fitted in absolute units (field -> unit, its term's column)
EXTENDED = {"stribeck": ("N m", FRICTION_STRIBECK), "stribeck_speed": ("rad/s", FRICTION_STRIBECK_SPEED),
            "load_motor": ("-", FRICTION_LOAD_MOTOR)}
#: their ranges (ours): the Stribeck friction up to a fifth of the stall torque (BAM's MX-64 and MX-106
#: have 2 %), its speed scale 0.05-10 rad/s (theirs 0.7-2.6), the load term up to 1 N m per N m (0.2-0.4)
STRIBECK_SHARE_MAX = 0.2
STRIBECK_SPEED_RANGE = (0.05, 10.0)
LOAD_MOTOR_MAX = 1.0
#: where the map's servo has none, the fit starts from a Stribeck friction of a quarter of its
#: Coulomb friction at 1 rad/s and a load term of 0.05 (ours: a start off zero, where the speed scale
#: would not move the residual at all)
EXTENDED_START = {"stribeck": 0.25, "stribeck_speed": 1.0, "load_motor": 0.05}


def _sysid():
    try:
        from mujoco import sysid
    except ImportError:
        sysid = None
    if sysid is None or not hasattr(sysid, "optimize"):
        raise UserError("identification needs MuJoCo's system identification toolbox: "
                        "pip install 'mujoco[sysid]'")
    return sysid


def optimize(sysid, params, residual_fn, *, max_iters: int, eps: float, trace=None):
    """``mujoco.sysid``'s box-bounded Levenberg-Marquardt from ``params``: (the fitted
    ParameterDict, its result). Its own log goes to ``trace`` (a text stream) or a buffer (ours: a
    progress bar says enough), absl's warnings held back while it runs."""
    absl = logging.getLogger("absl")
    level = absl.level
    absl.setLevel(logging.ERROR)
    try:
        return sysid.optimize(initial_params=params, residual_fn=residual_fn, optimizer="mujoco", verbose=False,
                              max_iters=max_iters, eps=eps, output=trace or io.StringIO())
    finally:
        absl.setLevel(level)


def group_of(ours: str) -> str:
    """The fit group of one of our joint names: the map's finer leg groups (hips, knees, ankles),
    else its group (arms, head)."""
    return fine_group(ours) or joint_group(ours)


@dataclass
class JointLog:
    """One recording's joints on the control period's grid: ``targets`` (N, n) what the controller
    asked at each tick, ``measured`` (N, n) the encoders at each tick [rad, gait-tuner's frame],
    columns ``joints`` (ours). ``name``: where it came from. ``valid`` (N,): the ticks whose angles
    were measured there (not interpolated across a gap in the recording); the fit compares only
    those (None: all)."""

    name: str
    dt: float
    joints: tuple[str, ...]
    targets: np.ndarray
    measured: np.ndarray
    valid: np.ndarray | None = None

    def weights(self) -> np.ndarray:
        """(N - 1, 1): 1 for each compared tick after the first, 0 for one in a gap."""
        v = np.ones(len(self.measured), dtype=bool) if self.valid is None else np.asarray(self.valid, dtype=bool)
        return v[1:, None].astype(float)

    def columns(self, names) -> tuple[np.ndarray, np.ndarray]:
        idx = [self.joints.index(n) for n in names]
        return self.targets[:, idx], self.measured[:, idx]


@dataclass
class ServoFit:
    """An identification's result: the servos per joint (``servos``, the harness' order), the
    parameters with their intervals, and the residuals before and after [rad RMS, per joint]."""

    servos: ServoArrays
    joints: tuple[str, ...]
    by: str                                    # "groups" or "joints"
    values: dict[str, float]                   # parameter -> fitted value (factor, mrad or ticks)
    intervals: dict[str, float]                # parameter -> 95 % half-width (inf: not identifiable)
    identifiable: dict[str, bool]
    rms_before: dict[str, float]               # joint -> RMS [rad]
    rms_after: dict[str, float]
    rollouts: int
    seconds: float
    iterations: int
    converged: bool
    recordings: list[str] = field(default_factory=list)
    entangled: list[list[str]] = field(default_factory=list)    # estimates that move together
    fitted: list[str] = field(default_factory=list)              # the parameters fitted (the others: the map's)
    loose: list[str] = field(default_factory=list)               # fitted, kept, but fixed only loosely
    at_least: list[str] = field(default_factory=list)            # limits kept as fitted: never bound there (a lower bound)
    on_bound: list[str] = field(default_factory=list)            # fitted values that end on their bounds
    sysid: dict = field(default_factory=dict)    # mujoco.sysid's own: initial and fitted ParameterDict, cov, half

    def unfollowed(self, noise: float) -> list[str]:
        """Joints the fit does not follow (ours: a residual RMS after the fit over ``FOLLOW_NOISE``
        times the sensor noise and over half the one before it): a recording the model cannot
        be fitted to there (a sign or name wrong, contacts), not a servo to identify."""
        return [j for j in self.joints if self.rms_after[j] > FOLLOW_NOISE * noise
                and self.rms_after[j] > 0.5 * self.rms_before[j]]

    @property
    def not_identifiable(self) -> list[str]:
        """Fitted parameters the recordings could not fix (they keep the map's value)."""
        return [k for k in self.fitted if not self.identifiable[k]]


def unit_of(name: str) -> str:
    """A fit parameter's unit: x (a factor of the map's), mrad, ticks, or an extended friction's."""
    field = name.rsplit(".", 1)[-1]
    if field in EXTENDED:
        return EXTENDED[field][0]
    return "mrad" if field == "backlash" else "ticks" if name == "latency" else "x"


#: what a fit can set: the scaled fields, the backlash, the latency and a motor's extended friction
FITTABLE = SCALED + ("backlash", "latency") + tuple(EXTENDED)
#: what it sets unless told: all but the extended friction
DEFAULT_FIT = SCALED + ("backlash", "latency")


def identify_servos(harness: Harness, logs: list[JointLog], *, by: str = "groups", noise: float = 1e-3,
                    max_iters: int = 40, threads: int | None = None, progress=None,
                    fit: tuple[str, ...] = DEFAULT_FIT, trace=None, budget=None) -> ServoFit:
    """Fit the harness robot's servos to ``logs`` (see the module's docstring). ``by``: "groups"
    (:data:`FIT_GROUPS`) or "joints". ``noise`` [rad]: the encoders' noise, the residual's unit.
    ``fit``: the fields fitted (:data:`FITTABLE`; default :data:`DEFAULT_FIT`); the others keep the
    map's values.
    ``progress(evaluations)`` is called after each batch of rollouts; ``budget(rollouts)``, once,
    with the most rollouts the fit can take (its iterations' Jacobians and a second stage: a
    progress bar's total, so it can say how long at most); ``trace`` (a text stream) gets the
    optimiser's iterations."""
    bad = [f for f in fit if f not in FITTABLE]
    if bad or not fit:
        raise UserError(f"--fit {','.join(fit)}: expected some of {', '.join(FITTABLE)}")
    sysid = _sysid()
    if by not in ("groups", "joints"):
        raise UserError(f"--by {by!r}: expected groups or joints")
    if not logs:
        raise UserError("no recordings to identify from")
    h = harness
    dt = h.control_period
    for log in logs:
        if abs(log.dt - dt) > 1e-9:
            raise UserError(f"{log.name}: its ticks are {log.dt * 1000:g} ms apart; the robot's control period "
                            f"is {dt * 1000:g} ms")
        missing = [j for j in h.joint_names if j not in log.joints]
        if missing:
            raise UserError(f"{log.name}: no measured and commanded angles for {', '.join(missing[:4])}"
                            f"{' ...' if len(missing) > 4 else ''}")
    data = [log.columns(h.joint_names) for log in logs]
    weights = [log.weights() for log in logs]
    moved = max(float(np.max(np.ptp(m, axis=0))) for _, m in data)
    if moved < 10 * noise:                 # a recording of a robot at rest: every fit would be noise
        raise UserError(f"nothing moved in the recordings: no joint's measured angle varies by more than "
                        f"{moved * 1000:.2f} mrad, within 10x the {noise * 1000:g} mrad sensor noise; record the sweep "
                        f"`gait-tuner excite` writes, played on the robot")
    base = h.servo_arrays()
    keys = [group_of(j) for j in h.joint_names] if by == "groups" else list(h.joint_names)
    units = list(dict.fromkeys(keys))                           # the fitted units, in order
    member = {u: np.array([k == u for k in keys]) for u in units}
    params = sysid.ParameterDict()
    termed, start_ext = _extended_terms(base, units, member, fit)
    h.write_spec(h.spec, base)             # every fit starts from the map's servos (an earlier fit edited the spec)

    def scale_modifier(unit: str, fname: str):
        cols = np.flatnonzero(member[unit])

        def modify(spec: mujoco.MjSpec, p) -> None:
            f = float(p.value[0])
            for i in cols:
                ours, theirs = h.joint_names[i], h.theirs[i]
                if fname in ("kp", "torque"):
                    act = spec.actuator(f"gt/servo/{ours}")
                    if fname == "kp":
                        act.gainprm[0] = base.kp[i] * f
                        act.biasprm[1] = -base.kp[i] * f
                    else:
                        act.forcerange = [-base.torque[i] * f, base.torque[i] * f]
                elif fname == "damping":
                    spec.joint(theirs).damping = [base.damping[i] * f, 0.0, 0.0]
                elif fname == "armature":
                    spec.joint(theirs).armature = base.armature[i] * f
                elif fname == "frictionloss":
                    has_term = _term_column(spec, ours, FRICTION_BASE, base.frictionloss[i] * f)
                    # a servo with a per-step friction term keeps its friction row (servos.law.configure)
                    spec.joint(theirs).frictionloss = max(base.frictionloss[i] * f, FRICTION_ROW_MIN) if has_term \
                        else base.frictionloss[i] * f
                elif fname == "back_emf":
                    spec.actuator(f"gt/servo/{ours}").damping = [base.back_emf[i] * f, 0.0, 0.0]
                    _term_column(spec, ours, FRICTION_BACK_EMF, base.back_emf[i] * f)
        return modify

    def term_modifier(unit: str, col: int):
        cols = np.flatnonzero(member[unit])

        def modify(spec: mujoco.MjSpec, p) -> None:
            for i in cols:
                _term_column(spec, h.joint_names[i], col, float(p.value[0]))
        return modify

    def absent(unit: str, fname: str) -> bool:
        """A piece the unit's servos do not have: a pd servo's back-EMF, a motor's target cap."""
        m = member[unit]
        if fname == "back_emf":
            return not np.any(base.back_emf[m] > 0)
        if fname == "speed":
            return not np.all(np.isfinite(base.speed[m]))
        return False

    lo, hi = FACTOR_BOUNDS
    mapped: dict[str, float] = {}          # the map's backlash [mrad] and latency [ticks]
    for u in units:
        for fname in SCALED:
            params.add(sysid.Parameter(f"{u}.{fname}", nominal=1.0, min_value=lo, max_value=hi,
                                       frozen=fname in LIMITS or fname not in fit or absent(u, fname),
                                       modifier=None if fname == "speed" else scale_modifier(u, fname)))
        b_map = float(np.mean(base.backlash[member[u]])) * 1000.0
        mapped[f"{u}.backlash"] = b_map
        params.add(sysid.Parameter(f"{u}.backlash", nominal=(b_map or 2.0) if "backlash" in fit else b_map,
                                   min_value=0.0, max_value=max(BACKLASH_MAX_MRAD, b_map), frozen="backlash" not in fit))
        for fname, (unit_name, col) in EXTENDED.items():
            key = f"{u}.{fname}"
            mapped[key] = start_ext[key]
            stall = float(np.mean(base.torque[member[u]]))
            lo_e, hi_e = {"stribeck": (0.0, STRIBECK_SHARE_MAX * stall), "stribeck_speed": STRIBECK_SPEED_RANGE,
                          "load_motor": (0.0, LOAD_MOTOR_MAX)}[fname]
            nominal = start_ext[key]
            if termed[u] and fname in fit and nominal <= 0.0:     # a start off zero (EXTENDED_START)
                nominal = EXTENDED_START[fname] * (float(np.mean(base.frictionloss[member[u]])) if fname == "stribeck"
                                                   else 1.0)
            params.add(sysid.Parameter(key, nominal=min(max(nominal, lo_e), hi_e), min_value=lo_e, max_value=hi_e,
                                       frozen=not (termed[u] and fname in fit),
                                       modifier=term_modifier(u, col) if termed[u] else None))
    mapped["latency"] = base.latency / dt
    params.add(sysid.Parameter("latency", nominal=(mapped["latency"] or 1.0) if "latency" in fit else mapped["latency"],
                               min_value=0.0, max_value=max(LATENCY_MAX_TICKS, mapped["latency"]),
                               frozen="latency" not in fit))

    def arrays(p) -> ServoArrays:
        s = base.copy()
        for u in units:
            m = member[u]
            s.speed[m] = base.speed[m] * float(p[f"{u}.speed"].value[0])
            s.backlash[m] = float(p[f"{u}.backlash"].value[0]) / 1000.0
            for fname in ("kp", "damping", "armature", "frictionloss", "torque", "back_emf"):
                getattr(s, fname)[m] = getattr(base, fname)[m] * float(p[f"{u}.{fname}"].value[0])
            if termed[u]:
                for fname, (_, col) in EXTENDED.items():
                    s.friction[m, col] = float(p[f"{u}.{fname}"].value[0])
        s.latency = float(p["latency"].value[0]) * dt
        return s

    if budget is not None:                 # each iteration: a Jacobian (one rollout per free parameter) and a step
        free = len(params.get_non_frozen_parameter_names())
        budget((max_iters + max(5, max_iters // 3) + 3) * (free + 2) * len(logs))
    n_threads = max(1, min(threads or os.cpu_count() or 1, 8))
    pool = ThreadPoolExecutor(n_threads) if n_threads > 1 else None
    counter = {"rollouts": 0}

    def one(model: mujoco.MjModel, s: ServoArrays) -> np.ndarray:
        out = []
        for (targets, measured), w in zip(data, weights):
            q = h.run(model, targets, s, q0=measured[0])
            out.append((w * (measured[1:] - q[1:]) / noise).ravel())
        return np.concatenate(out)

    def residual_fn(x: np.ndarray, p):
        cols = x.reshape(len(x), -1) if x.ndim > 1 else x.reshape(-1, 1)
        jobs = []
        for c in range(cols.shape[1]):
            p.update_from_vector(cols[:, c])
            model = sysid.apply_param_modifiers(p, h.spec)
            jobs.append((model, arrays(p)))
        rows = list(pool.map(lambda a: one(*a), jobs)) if pool is not None and len(jobs) > 1 else \
            [one(*a) for a in jobs]
        counter["rollouts"] += len(jobs) * len(data)
        if progress is not None:
            progress(counter["rollouts"])
        r = np.stack(rows, axis=1)
        return [r if x.ndim > 1 else r[:, 0]], None, None

    def solve(p, iters: int):
        opt, result = optimize(sysid, p, residual_fn, max_iters=iters, eps=FD_STEP, trace=trace)
        x = np.asarray(result.x, dtype=float)
        opt.update_from_vector(x)
        r = residual_fn(x, opt.copy())[0][0]
        return opt, result, r

    t0 = time.monotonic()
    initial = params.copy()
    try:
        r0 = residual_fn(params.as_vector(), params.copy())[0][0]
        # stage 1: the limits held at the map's; stage 2: the limits let go from there, kept only
        # where that lowers the misfit by LIMIT_GAIN (a limit that never binds changes nothing)
        opt, result, r1 = solve(params, max_iters)
        limits = [k for k in LIMITS if k in fit]
        if limits and np.sqrt(np.mean(r1 ** 2)) > LIMIT_MISFIT:
            free = opt.copy()
            for u in units:
                for k in limits:
                    free[f"{u}.{k}"].frozen = absent(u, k)
            opt2, result2, r2 = solve(free, max(5, max_iters // 3))
            if np.dot(r2, r2) < (1.0 - LIMIT_GAIN) * np.dot(r1, r1):
                opt, result, r1 = opt2, result2, r2
        fitted = opt
        names = fitted.get_non_frozen_parameter_names()
        J = np.asarray(result.jac)
        cov, half = sysid.calculate_intervals([r1], J)
        values = {n: float(fitted[n].value[0]) for n in fitted.keys()}
        intervals = {n: math.inf for n in fitted.keys()}
        intervals.update({n: float(w) for n, w in zip(names, half)})
        identifiable = {n: _narrow(n, values[n], w) for n, w in intervals.items()}
        # parameters whose estimates move together (reported; each one's interval already says how
        # well it is fixed on its own)
        apart = _entangled(names, cov, identifiable)
        # a limit is read off a recording only where it binds at the fitted value
        model = sysid.apply_param_modifiers(fitted, h.spec)
        binds = {"torque": np.zeros(h.n, int), "speed": np.zeros(h.n, int)}
        for targets, measured in data:
            lim: dict = {}
            h.run(model, targets, arrays(fitted), q0=measured[0], limits=lim)
            for k in binds:
                binds[k] += lim[k]
        total = sum(len(m) - 1 for _, m in data)
        asked = [n for n in values if n.rsplit(".", 1)[-1] in fit]
        for n in values:
            if n not in asked or fitted[n].frozen:    # not fitted: the map's value
                identifiable[n] = False
        for u in units:
            for k in LIMITS:
                if binds[k][member[u]].max() < max(3, 0.002 * total * (h.nstep if k == "torque" else 1)):
                    identifiable[f"{u}.{k}"] = False
        # what is written: a parameter the recordings do not move at all (an infinite interval, a
        # limit that never binds) keeps the map's value (a factor 1, no backlash, no latency); one
        # they fix only loosely keeps its fitted value (the recordings fix its combination with
        # others) and is named; the residual reported is the one of what is written
        kept = fitted.copy()
        for n, ok in identifiable.items():
            if not ok and (not math.isfinite(intervals[n]) or n.rsplit(".", 1)[-1] in LIMITS):
                kept[n].value[:] = 1.0 if unit_of(n) == "x" else min(max(mapped[n], float(np.ravel(kept[n].min_value)[0])),
                                                                    float(np.ravel(kept[n].max_value)[0]))
        # a limit a fit raised until it stopped binding says the servo gives at least that: where the
        # map's value would bind and misfit, the fitted one is kept (named: a lower bound)
        at_least = [n for n in values if n.rsplit(".", 1)[-1] in LIMITS and not identifiable[n]
                    and n in asked and not fitted[n].frozen and kept[n].value[0] != values[n]]
        if at_least:
            for n in kept.keys():
                kept[n].frozen = False
            r_reset = residual_fn(kept.as_vector(), kept.copy())[0][0]
            if np.dot(r_reset, r_reset) > (1.0 + LIMIT_GAIN) * np.dot(r1, r1):
                for n in at_least:
                    kept[n].value[:] = values[n]
            else:
                at_least = []
        loose = [n for n in asked if not identifiable[n] and kept[n].value[0] == values[n]
                 and math.isfinite(intervals[n]) and n not in at_least]
        # a fitted value that ends on its bound: the recordings want it beyond what the fit allows
        on_bound = [n for n in names if n in asked
                    and min(abs(values[n] - float(np.ravel(fitted[n].min_value)[0])),
                            abs(values[n] - float(np.ravel(fitted[n].max_value)[0]))) <= 1e-3 * max(1.0, abs(values[n]))]
        for n in kept.keys():
            kept[n].frozen = False
        r_kept = residual_fn(kept.as_vector(), kept.copy())[0][0]
        servos = arrays(kept)
    finally:
        if pool is not None:
            pool.shutdown()
    n_res = [len(m) - 1 for _, m in data]
    compared = max(1.0, float(sum(w.sum() for w in weights)))     # the ticks a residual counts

    def per_joint(r: np.ndarray) -> dict[str, float]:
        parts, o = [], 0
        for k in n_res:
            parts.append(r[o:o + k * h.n].reshape(k, h.n))
            o += k * h.n
        a = np.concatenate(parts)
        return {j: float(np.sqrt(np.sum(a[:, i] ** 2) / compared)) for i, j in enumerate(h.joint_names)}
    iters = len(result.extras.get("objective", [])) if getattr(result, "extras", None) else 0
    return ServoFit(servos=servos, joints=tuple(h.joint_names), by=by, values=values, intervals=intervals,
                    identifiable=identifiable, rms_before=per_joint(r0.reshape(-1) * noise),
                    rms_after=per_joint(r_kept.reshape(-1) * noise), rollouts=counter["rollouts"],
                    seconds=time.monotonic() - t0, iterations=iters,
                    converged=bool(np.all(np.isfinite(r_kept))),
                    recordings=[log.name for log in logs], entangled=apart, fitted=asked,
                    loose=loose, at_least=at_least, on_bound=on_bound, sysid={"initial": initial, "fitted": fitted, "cov": cov, "half": half})


#: how narrow a 95 % interval must be for a parameter to count as identified (ours): a factor to
#: within 10 % of its value, the backlash to within 1 mrad, the latency to within a quarter tick; a
#: Stribeck friction to 0.01 N m, its speed scale to 0.25 rad/s, the load term to 0.02 N m per N m
NARROW = {"x": 0.10, "mrad": 1.0, "ticks": 0.25, "N m": 0.01, "rad/s": 0.25, "-": 0.02}
#: estimates more correlated than this cannot be told apart (ours)
ENTANGLED = 0.995


def _narrow(name: str, value: float, half: float) -> bool:
    unit = unit_of(name)
    if not math.isfinite(half):
        return False
    return half < (NARROW["x"] * abs(value) if unit == "x" else NARROW[unit])


def _entangled(names: list[str], cov: np.ndarray, identifiable: dict[str, bool]) -> list[list[str]]:
    """Groups of parameters whose estimates correlate past :data:`ENTANGLED` (only among those that
    otherwise look identified)."""
    if cov.size == 0:
        return []
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(sd, sd)
    live = [i for i, n in enumerate(names) if identifiable[n]]
    groups: list[set[int]] = []
    for a in live:
        for b in live:
            if b <= a or not abs(corr[a, b]) > ENTANGLED:
                continue
            hit = [g for g in groups if a in g or b in g]
            merged = set().union(*hit, {a, b}) if hit else {a, b}
            groups = [g for g in groups if g not in hit] + [merged]
    return [[names[i] for i in sorted(g)] for g in groups]


def _extended_terms(base: ServoArrays, units: list[str], member: dict, fit: tuple[str, ...]
                    ) -> tuple[dict[str, bool], dict[str, float]]:
    """Where the fit asks for a motor's extended friction: which units run a per-step term (every
    servo of the unit a motor), each such servo's term set up in ``base`` (BAM's M5 flags added to
    the map's own: a Stribeck and a directional load part), and the map's values of the extended
    fields per unit (none where the map's servo has no term; a speed scale of 1 rad/s)."""
    asked = any(f in fit for f in EXTENDED)
    termed = {u: asked and bool(np.all(base.back_emf[member[u]] > 0)) for u in units}
    start: dict[str, float] = {}
    for u in units:
        rows = base.friction[member[u]]
        on = rows[:, 0] == FRICTION_MAGIC
        for f, (_, col) in EXTENDED.items():
            start[f"{u}.{f}"] = float(np.mean(np.where(on, rows[:, col], 0.0 if f != "stribeck_speed" else 1.0)))
        if not termed[u]:
            continue
        for i in np.flatnonzero(member[u]):
            row = base.friction[i]
            if row[0] != FRICTION_MAGIC:
                row[:] = 0.0
                # the Stribeck curve's shape held at alpha 1 (ours: an exponential fall with speed)
                row[0], row[FRICTION_STRIBECK_SPEED], row[FRICTION_ALPHA] = FRICTION_MAGIC, 1.0, 1.0
            row[FRICTION_FLAGS] = int(row[FRICTION_FLAGS]) | 1 | 2 | 4
    return termed, start


def _term_column(spec: mujoco.MjSpec, ours: str, col: int, value: float) -> bool:
    """Set one column of a servo's per-step friction term in ``spec``, where the servo has one
    (returns whether it has)."""
    act = spec.actuator(f"gt/servo/{ours}")
    u = list(act.userdata)
    if len(u) > col and u[0] == FRICTION_MAGIC:
        u[col] = float(value)
        act.userdata = u
        return True
    return False
