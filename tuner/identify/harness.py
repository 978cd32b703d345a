"""The robot hung in a harness by its torso: the servo model alone, for sweeps and identification.

A team identifies its servos on the robot hanging in a harness (the feet off the ground) while
the joints play a sweep (``gait-tuner excite``); :class:`Harness` is that robot in MuJoCo: the
robot's own model with its free joint removed (the torso fixed in the world, 1 m up, so no foot
reaches the floor), the same servo model as :class:`tuner.sim.rollout.Simulator` (a position
actuator per servo with its gain ``kp``, velocity feedback ``kv`` and torque limit; the joint's
armature, damping and friction loss), and the same command path, in the same order: the
targets rate-limited to the servo's speed and clipped to the joint's range, then the latency,
then the backlash dead band against the joint's position (``rollout.dead_band``).

Ours, for identification: the latency is a real number of seconds; a fraction of a tick
interpolates between the commands of the neighbouring ticks (a Catmull-Rom spline through them:
at whole ticks it is the simulator's queue exactly, and the command and its slope in the latency
are continuous across ticks), so that a fit can move it smoothly. Each servo's numbers are arrays
over the servo joints (:class:`ServoArrays`), so a fit can change them per joint or per group.

Joint angles in and out are gait-tuner's (``gaits.JOINT_NAMES`` signs, the held pose as zero for
arms and head), as in recordings; the MJCF's own frame only inside.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..robots.robot_model import RobotModel
from ..servos.law import FRICTION_ROW_MIN
from ..servos.motor import FRICTION_BACK_EMF, FRICTION_BASE, FRICTION_MAGIC, FRICTION_WIDTH
from ..sim.native_step import require as require_native_step
from ..sim.rollout import dead_band, rate_limited
from ..sim.scene import PREFIX, build_scene
from ..sim.surfaces import SURFACES

__all__ = ["Harness", "ServoArrays", "HANG_HEIGHT", "Sweep", "plan_sweep", "ENCODER_TICKS_LEAST"]

HANG_HEIGHT = 1.0       # [m] how far the torso is lifted above its standing place (ours: no foot reaches the floor)


@dataclass
class ServoArrays:
    """Every servo's numbers as arrays over the harness' servo joints (SI), plus the latency.

    kp [N m/rad], kv [N m s/rad], torque [N m] (the clamp), speed [rad/s] (the cap on the
    target's speed: inf where the law has none), armature [kg m^2], damping [N m s/rad] (the
    joint's), frictionloss [N m], backlash [rad] (the dead band's full width), back_emf [N m s/rad]
    (the motor's damping outside the clamp, ``tuner/servos/motor.py``; 0 for the pd law); latency [s];
    ``friction`` (n, ``FRICTION_WIDTH``): each servo's per-step friction term (``MotorServo.friction_term``:
    BAM's extended forms; a row of zeros where the friction loss and damping are the whole friction). A
    term's base and back-EMF columns are the ``frictionloss`` and ``back_emf`` above (written with them)."""

    kp: np.ndarray
    kv: np.ndarray
    torque: np.ndarray
    speed: np.ndarray
    armature: np.ndarray
    damping: np.ndarray
    frictionloss: np.ndarray
    backlash: np.ndarray
    back_emf: np.ndarray
    latency: float = 0.0
    friction: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.friction is None:
            self.friction = np.zeros((len(self.kp), FRICTION_WIDTH))

    def copy(self) -> "ServoArrays":
        return ServoArrays(**{f.name: (np.array(getattr(self, f.name), dtype=float) if f.name != "latency"
                                       else float(self.latency)) for f in dataclasses.fields(self)})

    def terms(self) -> np.ndarray:
        """The friction terms as the model holds them: each row's base and back-EMF the servo's."""
        u = np.array(self.friction, dtype=float)
        on = u[:, 0] == FRICTION_MAGIC
        u[on, FRICTION_BASE] = self.frictionloss[on]
        u[on, FRICTION_BACK_EMF] = self.back_emf[on]
        return u


class Harness:
    """One robot in its harness: the editable model (``spec``), its servo joints and the command path."""

    def __init__(self, robot: RobotModel) -> None:
        self.robot = robot
        spec, layout = build_scene(robot, SURFACES["rigid"])
        if layout.friction_terms:
            require_native_step(f"robot {robot.name!r} in its harness: a servo's extended friction")
        for j in list(spec.joints):
            if j.type == mujoco.mjtJoint.mjJNT_FREE:
                root = j.parent
                spec.delete(j)
                root.pos = [root.pos[0], root.pos[1], root.pos[2] + HANG_HEIGHT]
        # room for a friction term on every servo (a fit may give one to a servo whose law has none)
        spec.nuser_actuator = FRICTION_WIDTH
        for sn in list(spec.sensors):
            spec.delete(sn)
        for key in list(spec.keys):
            spec.delete(key)
        self.joint_names = layout.servo_joints                      # ours, in the servos' order
        self.theirs = tuple(robot.joint_map[n][0] for n in self.joint_names)
        for ours, theirs in zip(self.joint_names, self.theirs):
            spec.add_sensor(name=f"q/{ours}", type=mujoco.mjtSensor.mjSENS_JOINTPOS,
                            objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=theirs)
        self.held = layout.held_joints
        self.spec = spec
        self.n = len(self.joint_names)
        self.control_period = robot.sim.control_period
        self.nstep = int(round(robot.sim.control_period / robot.sim.timestep))
        model = spec.compile()
        self.model = model
        self._sign = np.array([robot.joint_map[j][1] for j in self.joint_names], dtype=float)
        self._offset = np.array([robot.pose.get(t, 0.0) for t in self.theirs])
        jid = [model.joint(t).id for t in self.theirs]
        self._qadr = np.array([model.jnt_qposadr[i] for i in jid])
        self._dofadr = np.array([model.jnt_dofadr[i] for i in jid])
        limited = model.jnt_limited[jid].astype(bool)
        self.q_lo = np.where(limited, model.jnt_range[jid, 0], -np.inf)     # MJCF frame
        self.q_hi = np.where(limited, model.jnt_range[jid, 1], np.inf)
        self._held_qadr = np.array([model.jnt_qposadr[model.joint(t).id] for t in self.held], dtype=int)
        self._held_pose = np.array([robot.pose.get(t, 0.0) for t in self.held])
        self._actuator = [spec.actuator(PREFIX + f"servo/{n}") for n in self.joint_names]
        self._joint = [spec.joint(t) for t in self.theirs]

    # --- frames -----------------------------------------------------------------------
    def to_robot(self, q: np.ndarray) -> np.ndarray:
        """gait-tuner's angles (..., n) of the servo joints -> the MJCF's."""
        return np.asarray(q, dtype=float) * self._sign + self._offset

    def from_robot(self, q: np.ndarray) -> np.ndarray:
        return (np.asarray(q, dtype=float) - self._offset) * self._sign

    def range_ours(self) -> tuple[np.ndarray, np.ndarray]:
        """Each servo joint's range in gait-tuner's frame (lo, hi) [rad] (+-inf where unlimited)."""
        a, b = self.from_robot(self.q_lo), self.from_robot(self.q_hi)
        with np.errstate(invalid="ignore"):
            return np.where(np.isnan(a), -np.inf, np.minimum(a, b)), np.where(np.isnan(b), np.inf, np.maximum(a, b))

    # --- servos -----------------------------------------------------------------------
    def servo_arrays(self) -> ServoArrays:
        """The robot's servos as its map gives them (the latency: the largest servo's, as the
        simulator takes it)."""
        s = [self.robot.servos[t] for t in self.theirs]
        p = [x.pieces() for x in s]
        terms = [x.friction_term() for x in s]
        return ServoArrays(**{f: np.array([getattr(x, f) for x in p]) for f in
                              ("kp", "kv", "torque", "armature", "damping", "frictionloss", "back_emf")},
                           speed=np.array([x.target_speed for x in p]), backlash=np.array([x.backlash for x in s]),
                           latency=max((x.latency for x in s), default=0.0),
                           friction=np.array([np.zeros(FRICTION_WIDTH) if u is None else u for u in terms]))

    def nominal_speed(self) -> np.ndarray:
        """[rad/s] each servo's fastest unloaded turn (the law's ``speed``: a motor's, or the pd cap)."""
        return np.array([self.robot.servos[t].speed for t in self.theirs])

    def write_spec(self, spec: mujoco.MjSpec, s: ServoArrays) -> None:
        """The parts of the servos that live in the model (gain, feedback, torque, the joint's
        armature, damping and friction loss, the per-step friction term) written into ``spec`` (this
        harness' or a copy)."""
        terms = s.terms()
        if np.any(terms[:, 0] == FRICTION_MAGIC):
            require_native_step(f"robot {self.robot.name!r} in its harness: a servo's extended friction")
        for i, (ours, theirs) in enumerate(zip(self.joint_names, self.theirs)):
            act = spec.actuator(PREFIX + f"servo/{ours}")
            act.gainprm[0] = s.kp[i]
            act.biasprm[1] = -s.kp[i]
            act.biasprm[2] = -s.kv[i]
            act.forcerange = [-s.torque[i], s.torque[i]]
            act.damping = [s.back_emf[i], 0.0, 0.0]
            termed = terms[i, 0] == FRICTION_MAGIC
            act.userdata = [float(x) for x in terms[i]]
            j = spec.joint(theirs)
            j.armature = s.armature[i]
            j.damping = [s.damping[i], 0.0, 0.0]
            # a servo with a per-step friction term keeps its friction row (servos.law.configure)
            j.frictionloss = max(s.frictionloss[i], FRICTION_ROW_MIN) if termed else s.frictionloss[i]

    def compile(self, s: ServoArrays) -> mujoco.MjModel:
        self.write_spec(self.spec, s)
        return self.spec.compile()

    # --- a sweep ------------------------------------------------------------------------
    def sent(self, targets: np.ndarray, s: ServoArrays, q0: np.ndarray | None = None) -> np.ndarray:
        """The commands (N, n) [MJCF frame] that reach the servos for targets (N, n) [ours], before
        the backlash: rate-limited to ``s.speed`` from row 0 (the start, held), clipped to the
        joint ranges, delayed by ``s.latency`` (fractions of a tick interpolated)."""
        t = self.to_robot(targets)
        c0 = t[0] if q0 is None else self.to_robot(q0)
        cmd = rate_limited(t, np.clip(c0, self.q_lo, self.q_hi), np.asarray(s.speed) * self.control_period,
                           self.q_lo, self.q_hi)
        lag = max(float(s.latency), 0.0) / self.control_period
        n_whole, u = int(math.floor(lag)), lag - math.floor(lag)
        if u == 0.0:
            return cmd[np.maximum(np.arange(len(cmd)) - n_whole, 0)]
        # between the commands of ticks k - n and k - n - 1: a Catmull-Rom spline through the ticks,
        # so that the delayed command and its slope in the latency are continuous across whole ticks
        k = np.arange(len(cmd))
        p0, p1, p2, p3 = (cmd[np.clip(k - n_whole + 1 - i, 0, len(cmd) - 1)] for i in range(4))
        return p1 + 0.5 * u * ((p2 - p0) + u * ((2 * p0 - 5 * p1 + 4 * p2 - p3) + u * (3 * (p1 - p2) + p3 - p0)))

    def run(self, model: mujoco.MjModel, targets: np.ndarray, s: ServoArrays, q0: np.ndarray | None = None,
            data: mujoco.MjData | None = None, state: bool = False, limits: dict | None = None):
        """Play ``targets`` (N, n) [rad, ours], one row per control tick (row k asked at tick k,
        acting over the tick that follows), from rest at ``q0`` (default: row 0). Returns the
        measured angles (N, n) [rad, ours] at the ticks (row 0: the start), and with ``state``
        also MuJoCo's full physics state at each tick (N, nstate). ``limits``, a dict, is filled
        with the ticks (n,) each servo's speed limit and its torque limit bound ("speed",
        "torque"): a limit that never binds cannot be read off the recording."""
        d = mujoco.MjData(model) if data is None else data
        targets = np.asarray(targets, dtype=float)
        start = targets[0] if q0 is None else np.asarray(q0, dtype=float)
        mujoco.mj_resetData(model, d)
        d.qpos[self._qadr] = np.clip(self.to_robot(start), self.q_lo, self.q_hi)
        d.qpos[self._held_qadr] = self._held_pose
        d.ctrl[:] = 0.0
        d.ctrl[self.n:self.n + len(self.held)] = self._held_pose
        mujoco.mj_forward(model, d)
        sent = self.sent(targets, s, start)
        half = np.asarray(s.backlash, dtype=float) / 2
        use_band = bool(np.any(half > 0))
        N = len(targets)
        out = np.empty((N, self.n))
        out[0] = d.qpos[self._qadr]
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
        states = None
        if state:
            states = np.empty((N, mujoco.mj_stateSize(model, full)))
            mujoco.mj_getState(model, d, states[0], full)
        qadr, n, nstep = self._qadr, self.n, self.nstep
        ctrl, qpos = d.ctrl, d.qpos
        at_torque = np.zeros(n, dtype=int)
        tau_lim = 0.999 * np.asarray(s.torque, dtype=float)
        for k in range(1, N):
            u = sent[k - 1]
            ctrl[:n] = dead_band(u, qpos[qadr], half) if use_band else u
            if limits is None:
                mujoco.mj_step(model, d, nstep=nstep)
            else:
                for _ in range(nstep):
                    mujoco.mj_step(model, d)
                    at_torque += np.abs(d.actuator_force[:n]) >= tau_lim
            out[k] = qpos[qadr]
            if states is not None:
                mujoco.mj_getState(model, d, states[k], full)
        if limits is not None:
            asked = np.clip(self.to_robot(targets), self.q_lo, self.q_hi)
            limits["torque"] = at_torque
            limits["speed"] = (np.abs(np.diff(asked, axis=0)) > np.asarray(s.speed) * self.control_period
                               * (1 + 1e-9)).sum(axis=0)
        q = self.from_robot(out)
        return (q, states) if state else q

    def probe(self, model: mujoco.MjModel, targets: np.ndarray, s: ServoArrays) -> tuple[np.ndarray, np.ndarray]:
        """What a sweep asks of the robot: the largest actuator torque per servo [N m] (a saturated
        servo reads its limit) and, per servo, whether its limb touches another part of the robot
        (a contact below the joint; a sweep must not knock the robot's feet or hands together)."""
        d = mujoco.MjData(model)
        targets = np.asarray(targets, dtype=float)
        mujoco.mj_resetData(model, d)
        d.qpos[self._qadr] = np.clip(self.to_robot(targets[0]), self.q_lo, self.q_hi)
        d.qpos[self._held_qadr] = self._held_pose
        d.ctrl[self.n:self.n + len(self.held)] = self._held_pose
        mujoco.mj_forward(model, d)
        sent = self.sent(targets, s)
        tau = np.zeros(self.n)
        bodies: set[int] = set()
        for k in range(1, len(targets)):
            d.ctrl[:self.n] = sent[k - 1]
            for _ in range(self.nstep):
                mujoco.mj_step(model, d)
                for c in d.contact[:d.ncon]:
                    bodies.update((int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])))
            np.maximum(tau, np.abs(d.actuator_force[:self.n]), out=tau)
        touching = np.zeros(self.n, dtype=bool)
        for i, t in enumerate(self.theirs):            # a joint whose body is the touching body or above it
            jb = int(model.jnt_bodyid[model.joint(t).id])
            for b in bodies:
                while b > 0 and b != jb:
                    b = int(model.body_parentid[b])
                touching[i] |= b == jb
        return tau, touching

def excitation(h: Harness, duration: float = 30.0, f0: float = 0.2, f1: float = 2.5, amplitude: float = 0.4,
               speed_margin: float = 0.6, torque_margin: float = 0.8, range_margin: float = 0.05,
               seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A joint sweep for the robot hanging in its harness (ours): every servo joint plays a chirp
    (a sine whose frequency rises from ``f0`` to ``f1`` [Hz] over ``duration`` [s], faded in and out
    over a second), each joint with its own phase, swinging ``amplitude`` [rad] (or half its range
    where that is narrower) about the held pose, moved inward as far as the swing needs. Kept inside every servo's limits: ``range_margin`` [rad]
    from each end of the joint's range, the peak speed at most ``speed_margin`` of the servo's,
    and, played on the harness with the map's servos, every torque below ``torque_margin`` of the
    servo's limit and no limb touching another (the robot's own contacts make a recording that
    no fit can follow, and knock its feet together): a joint over a limit, or above a touching
    part, plays a smaller amplitude, until none does. Returns (t (N,),
    targets (N, n) [rad, ours, columns ``h.joint_names``])."""
    if not (0 < f0 < f1) or duration <= 2.0:
        raise ValueError("excitation needs 0 < f0 < f1 and a duration over 2 s")
    dt = h.control_period
    t = np.arange(int(round(duration / dt)) + 1) * dt
    lo, hi = h.range_ours()
    lo_m, hi_m = lo + range_margin, hi - range_margin
    # the swing: ``amplitude``, or half the range where it is narrower; about the held pose moved
    # just far enough inward for the swing to fit (a knee that bends one way swings bent)
    room = np.minimum(amplitude, np.where(np.isfinite(hi_m - lo_m), (hi_m - lo_m) / 2, amplitude))
    room = np.maximum(room, 0.0)
    centre = np.clip(np.zeros(h.n), lo_m + room, hi_m - room)
    s = h.servo_arrays()
    k = (f1 - f0) / duration                                   # linear chirp: f(t) = f0 + k t
    phase = 2 * np.pi * (f0 * t + 0.5 * k * t ** 2)
    fade = np.clip(np.minimum(t, duration - t), 0.0, 1.0)
    offsets = np.random.default_rng(seed).uniform(0, 2 * np.pi, h.n)
    # the peak speed of A fade sin(phase): A 2 pi f1 (the fade's own slope adds A per second)
    a = np.minimum(room, speed_margin * h.nominal_speed() / (2 * np.pi * f1 + 1.0))
    model = h.compile(s)
    for _ in range(12):
        targets = centre + a * fade[:, None] * np.sin(phase[:, None] + offsets)
        tau, touching = h.probe(model, targets, s)
        over = tau > torque_margin * s.torque
        if not over.any() and not touching.any():
            return t, targets
        a = np.where(over | touching, a * 0.8, a)
    raise ValueError("no sweep keeps the servos under their torque limits and the limbs apart (a servo too weak "
                     "to move its own limb, or limbs that touch at the held pose?)")


def step_train(h: Harness, centre: np.ndarray, *, amplitude: float = 0.6, hold: float = 0.4, seed: int = 0,
               range_margin: float = 0.05) -> np.ndarray:
    """Large steps, one joint at a time (ours): from ``centre`` (the sweep's held pose, (n,) [rad,
    ours]) each servo joint in turn steps out by up to ``amplitude`` [rad] one way, then the other,
    then back, each target held ``hold`` [s], the others held still. A step well past the error at
    which the firmware's duty saturates (0.2 rad for an MX at P 32) drives the motor at full duty
    along its torque-speed line, which a sweep within its speed never reaches: what tells the stall
    torque from the back-EMF. One joint at a time, so no two limbs swing into each other; a step
    that touches another part (a hip rolling one foot into the other) or meets the joint's range is
    made smaller, down to none. ``seed`` draws each joint's step size in U(0.7, 1) of its room and
    which way it goes first. Returns targets (N, n)."""
    lo, hi = h.range_ours()
    rng = np.random.default_rng([seed, 5])
    share = rng.uniform(0.7, 1.0, h.n)
    first = rng.choice([-1.0, 1.0], h.n)
    room = {1.0: np.minimum(amplitude, np.maximum(hi - range_margin - centre, 0.0)),
            -1.0: np.minimum(amplitude, np.maximum(centre - (lo + range_margin), 0.0))}
    ticks = int(round(hold / h.control_period))
    s = h.servo_arrays()
    model = h.compile(s)
    rest = np.tile(centre, (ticks, 1))

    def step(i: int, size: float) -> np.ndarray:
        row = centre.copy()
        row[i] += size
        return np.tile(row, (ticks, 1))
    size = {}
    for i in range(h.n):
        for sign in (1.0, -1.0):
            a = sign * room[sign][i] * share[i]
            for _ in range(6):             # this step alone, from rest and back: no part may touch another
                if a == 0.0 or not h.probe(model, np.concatenate([rest, step(i, a), rest]), s)[1].any():
                    break
                a *= 0.6
            else:
                a = 0.0
            size[i, sign] = a
    rows = [rest]
    for i in range(h.n):
        for sign in (first[i], -first[i]):
            rows.append(step(i, size[i, sign]))
        rows.append(rest)
    targets = np.concatenate(rows)
    if h.probe(model, targets, s)[1].any():
        raise ValueError("no step train keeps the limbs apart (limbs that touch at the held pose?)")
    return targets


#: A swing the encoders cannot resolve identifies nothing: 3 ticks of a 4096-count encoder [rad] (ours).
ENCODER_TICKS_LEAST = 3 * 2 * math.pi / 4096


@dataclass(frozen=True)
class Sweep:
    """What ``excite`` writes: the sweep (``sweep_s`` [s]) and, after it, the step train, as targets
    [rad, our names and signs] on the control grid ``t`` [s]."""

    joint_names: tuple[str, ...]
    t: np.ndarray
    targets: np.ndarray
    sweep_s: float
    speed_share: float                       # the sweep's fastest target speed / the servo's nominal speed
    below_encoder: dict[str, float]          # joint -> its sweep's half swing [rad], under ENCODER_TICKS_LEAST

    def csv_text(self) -> str:
        """t, then target.<joint> per servo joint."""
        header = "t," + ",".join(f"target.{j}" for j in self.joint_names)
        rows = "\n".join(",".join([f"{self.t[k]:.4f}"] + [f"{v:.6f}" for v in self.targets[k]])
                         for k in range(len(self.t)))
        return header + "\n" + rows + "\n"

    def info(self) -> dict:
        """Its figures as ``excite --json`` gives them."""
        return {"seconds": float(self.t[-1]), "joints": list(self.joint_names),
                "amplitude_rad": dict(zip(self.joint_names, np.round((self.targets.max(0) - self.targets.min(0)) / 2,
                                                                     4).tolist())),
                "speed_share": self.speed_share, "sweep_s": self.sweep_s, "steps_s": float(self.t[-1]) - self.sweep_s,
                "below_encoder": list(self.below_encoder)}


def plan_sweep(h: Harness, *, duration: float, f_max: float, amplitude: float, steps: bool, step_size: float,
               seed: int) -> Sweep:
    """The sweep to play on the hanging robot (:func:`excitation`), then, with ``steps``, the step
    train (:func:`step_train`). ValueError when it cannot be made, or when no joint swings more than
    :data:`ENCODER_TICKS_LEAST` (the message says the largest amplitude the ranges allow)."""
    t, targets = excitation(h, duration=duration, f1=f_max, amplitude=amplitude, seed=seed)
    sweep_s = float(t[-1])
    if steps:
        targets = np.vstack([targets, step_train(h, targets[-1], amplitude=step_size, seed=seed)])
        t = np.arange(len(targets)) * h.control_period
    n_sweep = int(round(sweep_s / h.control_period)) + 1        # the sweep's rows (the steps jump, by design)
    half = (targets[:n_sweep].max(0) - targets[:n_sweep].min(0)) / 2
    least = ENCODER_TICKS_LEAST
    if np.all(half < least):
        lo, hi = h.range_ours()
        raise ValueError(f"the largest swing is {half.max() * 1000:.2f} mrad, below 3 encoder ticks "
                         f"({least * 1000:.1f} mrad at 4096 counts a turn): nothing could be identified from it; "
                         f"give --amplitude more (its range allows {float(np.max((hi - lo) / 2)):.3g} rad at most)")
    speed = np.abs(np.diff(targets[:n_sweep], axis=0)).max(axis=0) / h.control_period
    return Sweep(tuple(h.joint_names), t, targets, sweep_s, float(np.max(speed / h.nominal_speed())),
                 {j: float(a) for j, a in zip(h.joint_names, half) if a < least})


def record_sweep(h: Harness, targets: np.ndarray, s: ServoArrays, path, *, noise: float = 1e-3, seed: int = 0,
                 task: str = "sweep", notes: str = "") -> np.ndarray:
    """Play ``targets`` on the harness with servos ``s`` and write what a robot's loop would record
    (``gaits.robot.recorder``, simulated): per tick the encoders (with Gaussian ``noise`` [rad]) and the
    targets asked then, for the tick that follows (row k of ``targets``). Returns the measured angles (N, n) as recorded."""
    from gaits.control import Measurement
    from gaits.robot.recorder import Recorder, RecordingMeta
    model = h.compile(s)
    q = h.run(model, targets, s)
    q = q + np.random.default_rng(seed).normal(0.0, noise, q.shape) if noise > 0 else q
    meta = RecordingMeta(robot=h.robot.name, task=task, simulated=True, joints=list(h.joint_names),
                         target_joints=list(h.joint_names),
                         controller="joint sweep (gait-tuner excite), robot in a harness", notes=notes)
    with Recorder(path, meta, start_ns=0) as rec:
        for k in range(len(targets)):       # row k: read at tick k, and asked then for the tick after
            rec.record(Measurement(k * h.control_period, q=q[k], joint_names=h.joint_names), None, targets[k])
    return q


class HangingSim:
    """The harness as the simulated bus' simulator (``gait-tuner bus serve --hang``): a controller's
    targets (``gaits.JOINT_NAMES`` order) played tick by tick through the servo path, in lockstep;
    it reads the encoders and a level IMU (the torso is held). The latency in whole ticks, as the
    simulator takes it. Duck-types what :func:`tuner.sim.bus.serve` uses of a ``Simulator``."""

    def __init__(self, h: Harness, s: ServoArrays | None = None) -> None:
        from gaits import JOINT_NAMES
        self.h = h
        self.s = h.servo_arrays() if s is None else s
        self.control_period = h.control_period
        self.surface = type("Harness", (), {"name": "a harness"})()
        # the robot side's controllers drive our 20 roles; the robot's extra joints hold their pose
        names = tuple(JOINT_NAMES) + h.robot.extra_joints
        self._cols = np.array([names.index(j) for j in h.joint_names])
        self._n = len(names)
        self._roles = len(JOINT_NAMES)

    def run(self, controller, duration: float, perturb=None):
        from collections import deque

        from gaits.control import Measurement
        h, s = self.h, self.s
        model = h.compile(s)
        d = mujoco.MjData(model)
        q0 = h.robot.with_extras(controller.start_pose().q)[self._cols]
        mujoco.mj_resetData(model, d)
        d.qpos[h._qadr] = np.clip(h.to_robot(q0), h.q_lo, h.q_hi)
        d.qpos[h._held_qadr] = h._held_pose
        d.ctrl[h.n:h.n + len(h.held)] = h._held_pose
        mujoco.mj_forward(model, d)
        cmd = d.qpos[h._qadr].copy()
        step = np.asarray(s.speed) * h.control_period
        queue = deque(cmd.copy() for _ in range(int(round(s.latency / h.control_period))))
        half = np.asarray(s.backlash) / 2
        band = bool(np.any(half > 0))
        level = (np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 9.81]))

        def read(t: float) -> Measurement:
            q = np.zeros(self._n)
            dq = np.zeros(self._n)
            q[self._cols] = h.from_robot(d.qpos[h._qadr])
            dq[self._cols] = d.qvel[h._dofadr] * h._sign
            return Measurement(t, q=q[:self._roles], dq=dq[:self._roles], imu_rpy=level[0], gyro=level[1],
                               accel=level[2])
        controller.reset(read(0.0))
        for k in range(1, int(round(duration / h.control_period)) + 1):
            target = h.robot.with_extras(controller.step(read((k - 1) * h.control_period)))
            want = h.to_robot(target[self._cols])
            cmd = np.clip(cmd + np.clip(want - cmd, -step, step), h.q_lo, h.q_hi)
            queue.append(cmd.copy())
            out = queue.popleft()
            d.ctrl[:h.n] = dead_band(out, d.qpos[h._qadr], half) if band else out
            mujoco.mj_step(model, d, nstep=h.nstep)
        return type("HangingTrace", (), {"reason": "completed"})()
