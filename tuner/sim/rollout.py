"""MuJoCo walking rollouts: a controller drives position servos -> a trace of what the robot did.

This is the only module that steps physics. A :class:`Simulator` is built once per (robot,
surface) and runs many rollouts. :meth:`Simulator.run` is the closed loop, per control tick
(10 ms by default):

1. the sensor reader (``sensors.py``) makes the controller's :class:`gaits.control.Measurement`
   from the state (encoders, IMU, sole forces; noise and latency from the perturbation);
2. the controller (``gaits/control.py``: a table player, the stabiliser around any controller,
   a walk engine, or a user's own) returns joint targets for the next tick;
3. the plant: targets rate-limited to the servos' speed and clipped to the joint ranges, held
   back by the command latency and the backlash dead band, sent to the position actuators
   (torque-limited); the grass drag gated to the sole corners inside the blades (inside MuJoCo's
   step where the C callback could be built, ``native_step.py``; else here); pushes;
4. MuJoCo advances by ``nstep`` physics steps in one call;
5. the recorder keeps the sensor vector (ground truth included, for the metrics only) and the
   loop checks for a fall or a diverging simulation.

:meth:`Simulator.rollout` plays a joint table (the open loop the papers describe) through it.
When nothing in a walk reads its state before MuJoCo does (a controller that senses nothing and
knows its targets ahead, no backlash, no blade layer, no hook; the contact layer's drag gate runs
inside MuJoCo's step, ``native_step.c``, where it could be compiled), its servo commands are all
known at the start, and MuJoCo's native rollout runs it in chunks, each judged by the same checks
after it: bit for bit the tick loop's walk (tested), without its per-tick Python.

Sensors in the model: an IMU site on the torso (orientation, position), the whole-body CoM,
each sole centre, four touch sensors per sole (toe-left, toe-right, heel-left, heel-right
quadrants, the quantity the TLIPFM paper measured with four force sensors per sole; the
measured ZMP is their centre of pressure), and each servo's position, velocity and torque.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass, field

import mujoco
import mujoco.rollout
import numpy as np

from gaits import JOINT_NAMES, GaitTrajectory, StabiliserParams
from gaits.control import Controller, HoldPose, PlanRecord, Stabilised, TablePlayer, rpy_from_quat

from ..errors import UserError
from .centre_of_pressure import centre_of_pressure
from .randomisation import Perturbation
from .sensors import SensorReader
from ..robots import RobotModel, SimOptions
from ..servos import MotorServo
from .native_step import require as require_native_step
from .scene import (BOTTLE_2019, CORNERS, IMU_SITE_POS, Bottle, add_pendulum, build_scene,
                    fall_height_at_com)
from .surfaces import Surface

__all__ = ["FallCriteria", "OUTCOMES", "Trace", "Simulator", "dead_band"]

#: Control ticks per call of MuJoCo's native rollout (ours): each call costs ~10 us besides the
#: physics, and a walk that falls inside a chunk is simulated to the chunk's end (at most 0.2 s
#: of 10 ms ticks) before the check finds it.
NATIVE_CHUNK = 20
_ROLLOUT = mujoco.rollout.Rollout(nthread=0)       # runs on the calling thread: no pool


@dataclass(frozen=True)
class FallCriteria:
    """When a rollout counts as a fall (and stops early), and which states no kid-size robot
    reaches (a blow-up of the simulation that MuJoCo did not flag: the walk is "impossible")."""

    max_tilt: float = math.radians(50.0)   # [rad] torso tilt from upright (pitch and roll together)
    min_height_ratio: float = 0.6          # torso below this fraction of its starting height
    max_speed: float = 10.0                # [m/s] torso speed (a falling 50 cm robot reaches ~3)
    max_spin: float = 60.0                 # [rad/s] torso angular speed
    max_height: float = 1.5                # [m] torso height (three times a kid-size robot's)

#: How a rollout can end; only "completed" (and "stopped", a live walk ended by its viewer) survive.
OUTCOMES = ("completed", "fell", "diverged", "impossible", "stopped")


@dataclass
class Trace:
    """What the robot did, one row per control tick up to the end or the fall (SI units)."""

    t: np.ndarray               # (K,) [s]
    pitch: np.ndarray           # (K,) [rad] torso pitch, forward lean positive
    roll: np.ndarray            # (K,) [rad] torso roll about x (left side up positive)
    p_torso: np.ndarray         # (K, 3) [m] IMU site
    p_com: np.ndarray           # (K, 3) [m] whole-body CoM
    p_sole_l: np.ndarray        # (K, 3) [m]
    p_sole_r: np.ndarray        # (K, 3) [m]
    force: np.ndarray           # (K, 8) [N] touch sensors: left toe-l, toe-r, heel-l, heel-r, then right
    p_touch: np.ndarray         # (K, 8, 3) [m] touch-site centres at the sole
    zmp: np.ndarray             # (K, 2) [m] measured ZMP (centre of pressure), NaN when unloaded
    zmp_ref: np.ndarray         # (K, 2) [m] the gait's ZMP reference
    zmp_local: np.ndarray       # (K, 2) [m] measured ZMP relative to the actual support foot
    zmp_ref_local: np.ndarray   # (K, 2) [m] reference relative to the planned support foot
    support: np.ndarray         # (K,) the gait's planned support phase
    q: np.ndarray               # (K, n) [rad] joint positions, gait-tuner joint order and signs
    q_cmd: np.ndarray           # (K, n) [rad] commanded (rate-limited) targets
    q_ref: np.ndarray           # (K, n) [rad] the gait's targets
    tau: np.ndarray             # (K, n) [N m] actuator torques
    joint_names: tuple[str, ...]
    fell: bool
    t_fall: float | None
    p_fall: np.ndarray | None
    reason: str                 # "completed", "fell at ...", "diverged: ...", "impossible: ..."
    walk_start: float           # [s] first planned single support
    cycle_time: float           # [s] one gait cycle (two steps), for the +- amplitude
    meta: dict = field(default_factory=dict)
    q_sent: np.ndarray | None = None   # (K, n) [rad] targets the servos received (after latency, backlash)
    yaw: np.ndarray | None = None      # (K,) [rad] torso heading, unwrapped (counter-clockwise positive)
    qpos: np.ndarray | None = None     # (K, nq) MuJoCo qpos per tick, when the rollout recorded it
    outcome: str = "completed"         # one of OUTCOMES

    @property
    def completed(self) -> bool:
        return self.reason == "completed"

    @property
    def survived(self) -> bool:
        """It ended standing: completed (or stopped by a live viewer). A fall, a diverged or an
        impossible simulation never survives."""
        return self.outcome in ("completed", "stopped")


def dead_band(target: np.ndarray, q: np.ndarray, half_width: np.ndarray) -> np.ndarray:
    """Backlash as a dead band: the target a servo acts on when errors below ``half_width`` [rad]
    move nothing and larger ones move it by what exceeds the band (shapes (n,))."""
    e = target - q
    return q + np.sign(e) * np.maximum(np.abs(e) - half_width, 0.0)


def rate_limited(target: np.ndarray, c0: np.ndarray, step: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The servo commands (N, n) the rollout's rate limiter makes of known targets (N, n): from
    ``c0``, each tick c += clip(target - c, -step, step), then c clipped to [lo, hi]; row 0 is
    ``c0``. Bit for bit the tick loop's arithmetic, without its loop where it cannot matter: when
    the previous command equals the previous target and the new target is within ``step`` of it,
    inside [lo, hi] and within a factor 2 of it (Sterbenz's lemma: the difference is exact, so
    c + (target - c) is the target exactly), the command is the target; the other ticks (a limit
    binding, a sign change, a command catching up) run the recursion, element by element."""
    out = np.array(target, dtype=float)
    out[0] = c0
    prev, cur = target[:-1], target[1:]
    exact = (cur == prev) | ((cur >= 0.5 * prev) & (cur <= 2.0 * prev)) | ((cur <= 0.5 * prev) & (cur >= 2.0 * prev))
    easy = exact & (np.abs(cur - prev) <= step) & (cur >= lo) & (cur <= hi)     # row i: tick i + 1
    n = len(out)
    for j in range(out.shape[1]):
        hard = np.flatnonzero(~easy[:, j]) + 1
        col, m, s, lo_j, hi_j = out[:, j], target[:, j], step[j], lo[j], hi[j]
        k = 1 if c0[j] != m[0] else (int(hard[0]) if hard.size else n)
        while k < n:
            c = col[k - 1]
            while k < n:
                c = min(max(c + min(max(m[k] - c, -s), s), lo_j), hi_j)
                col[k] = c
                k += 1
                if c == m[k - 1] and (k == n or easy[k - 1, j]):
                    break
            i = int(np.searchsorted(hard, k))
            k = int(hard[i]) if i < hard.size else n
    return out


class Simulator:
    """One compiled MuJoCo model of a robot on a surface, reused across rollouts."""

    def __init__(self, robot: RobotModel, surface: Surface, *, control_period: float | None = None,
                 timestep: float | None = None, fall: FallCriteria | None = None,
                 pendulum: float | None = None, bottle: Bottle = BOTTLE_2019, native_gate: bool = True) -> None:
        """``pendulum`` [m]: add the push-recovery challenge's pendulum on a rope this long, with
        ``bottle`` on it (``scene.add_pendulum``; ``tuner/challenge/rules.py`` swings it). ``native_gate``: on a
        contact-layer grass, gate the drag dampers in MuJoCo's step (``native_step.py``) when the
        callback can be installed; False keeps the Python gate (the same walk to the bit, slower)."""
        self.robot = robot
        self.surface = surface
        opts = robot.sim
        if control_period is not None or timestep is not None:
            opts = SimOptions(control_period=opts.control_period if control_period is None else control_period,
                              timestep=opts.timestep if timestep is None else timestep,
                              max_tilt_deg=opts.max_tilt_deg, min_height_ratio=opts.min_height_ratio)
            robot = dataclasses.replace(robot, sim=opts)
        self.fall = fall if fall is not None else FallCriteria(math.radians(opts.max_tilt_deg), opts.min_height_ratio)
        self.control_period = opts.control_period
        self.nstep = int(round(opts.control_period / opts.timestep))
        spec, self.layout = build_scene(robot, surface)
        if pendulum is not None:
            add_pendulum(spec, pendulum, bottle)
        self.rope = pendulum
        self.bottle = bottle
        self.spec = spec
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._index()
        m = self.model
        self._nominal = {name: getattr(m, name).copy() for name in
                         ("body_mass", "body_subtreemass", "body_inertia", "body_ipos", "actuator_gainprm", "actuator_biasprm",
                          "actuator_forcerange", "actuator_damping", "actuator_user", "dof_damping", "dof_frictionloss",
                          "geom_friction", "geom_margin", "geom_solref", "geom_solimp")}
        self._nominal_gravity = m.opt.gravity.copy()
        #: the surface's kind of ground (``tuner/sim/ground/``), on the sole corners; each corner stands
        #: for a quarter of its sole; a contact layer's drag gate in MuJoCo's step where it can be
        self.ground = self.layout.ground
        area = np.repeat([robot.foot_size_of(i)[0] * robot.foot_size_of(i)[1] / 4 for i in range(2)], 4)
        self.ground.bind(m, area, self.control_period, self._sole_corners, native=native_gate)
        if self.layout.friction_terms:          # a servo's extended friction runs only there
            require_native_step(f"robot {robot.name!r}: a servo's extended friction (friction_model m2-m6)")

    def _index(self) -> None:
        m, r, lay = self.model, self.robot, self.layout
        self.joint_names = lay.servo_joints
        o, blocks = 0, {}
        for name, width in lay.sensors:
            blocks[name] = slice(o, o + width)
            o += width
        assert o == m.nsensordata, (o, m.nsensordata)
        self._s_quat, self._s_pos, self._s_com = blocks["quat"], blocks["pos"], blocks["com"]
        self._s_sole, self._s_touch, self._s_touchpos = blocks["sole"], blocks["touch"], blocks["touchpos"]
        self._s_q, self._s_dq, self._s_tau = blocks["q"], blocks["dq"], blocks["tau"]
        self._s_fall = blocks["fall"]
        # the fall checks' two numbers in the sensor vector: the torso's z axis' z, and its height
        self._s_tilt, self._s_height = self._s_fall.start + 2, self._s_fall.start + 5
        self._imu_offset = np.array(IMU_SITE_POS, dtype=float)
        self._torso = m.body(r.torso).id
        self._low_origin = fall_height_at_com(r)         # the fall check's height is the torso's CoM
        self._feet = np.array([m.body(f).id for f in r.feet])
        theirs = [r.joint_map[j][0] for j in self.joint_names]
        self._sign = np.array([r.joint_map[j][1] for j in self.joint_names], dtype=float)
        # non-leg joints move about their held pose (the gait's arm and head columns are offsets)
        self._offset = np.array([r.pose.get(t, 0.0) for t in theirs])
        self._qadr = np.array([m.jnt_qposadr[m.joint(t).id] for t in theirs])
        held = lay.held_joints
        self._held_qadr = np.array([m.jnt_qposadr[m.joint(t).id] for t in held], dtype=int)
        self._held_pose = np.array([r.pose.get(t, 0.0) for t in held])
        jr = np.array([m.jnt_range[m.joint(t).id] for t in theirs])
        limited = np.array([m.jnt_limited[m.joint(t).id] for t in theirs], bool)
        self._q_lo = np.where(limited, jr[:, 0], -np.inf)
        self._q_hi = np.where(limited, jr[:, 1], np.inf)
        #: [rad/s] each servo joint's nominal speed, the fastest it turns unloaded (``joint_names`` order)
        self.servo_speed = np.array([r.servos[t].speed for t in theirs])
        # the cap on how fast a target may move (the pd law's; a firmware's profile speed; else none):
        # a randomisation scales the played one
        self._max_step = np.array([r.servos[t].target_speed for t in theirs]) * self.control_period
        # an identified servo's latency (one queue: the largest, in whole ticks) and dead band
        self._latency = int(round(max((r.servos[t].latency for t in theirs), default=0.0) / self.control_period))
        self._backlash = np.array([r.servos[t].backlash for t in theirs])
        half = [np.array(r.foot_size_of(i)) / 2 for i in range(2)]            # each foot's own sole
        self._corners = np.stack([r.sole_points(i, [[sx * half[i][0], sy * half[i][1], 0.0] for sx, sy in CORNERS])
                                  for i in range(2)])  # (2, 4, 3) in foot frame
        self._corners_T = np.ascontiguousarray(self._corners.transpose(0, 2, 1))  # (2, 3, 4)
        #: the order of a controller's targets: our 20 roles, then the robot's extra joints (a
        #: controller that gives 20 holds the extras at their pose)
        self.target_names = tuple(JOINT_NAMES) + r.extra_joints
        self._col_in_gait = np.array([self.target_names.index(j) for j in self.joint_names])
        self._touch_sum = np.zeros((len(lay.touch_quadrant), 8))
        self._touch_sum[np.arange(len(lay.touch_quadrant)), list(lay.touch_quadrant)] = 1.0
        self._n_servo = len(self.joint_names)
        self._n_act = self._n_servo + len(held)
        # which servo actuators are dc-motors (the randomisation draws their voltage, kt, R, friction)
        self._motor = np.array([isinstance(r.servos[t], MotorServo) for t in theirs + list(held)], dtype=bool)
        self._act_dof = np.array([m.jnt_dofadr[m.actuator_trnid[k, 0]] for k in range(self._n_act)], dtype=int)

    def to_robot(self, q_gait: np.ndarray) -> np.ndarray:
        """Joint targets in gait-tuner order and signs (..., 20; or with the robot's extra joints
        after them, :attr:`target_names`) -> the robot's servos (..., n)."""
        return self.robot.with_extras(q_gait)[..., self._col_in_gait] * self._sign + self._offset

    def range_error(self, q_gait: np.ndarray, t: np.ndarray, tolerance: float = 1e-3) -> str | None:
        """The first target of a joint table (N, 20) in gait-tuner order outside its joint's range in
        the robot file (the servos would be clipped there, silently), as one sentence; None if none.
        ``tolerance`` [rad] (ours): rounding at a range's edge is not reported."""
        q = self.to_robot(q_gait)
        bad = (q < self._q_lo - tolerance) | (q > self._q_hi + tolerance)
        if not bad.any():
            return None
        i, j = (int(v[0]) for v in np.nonzero(bad))
        ours = self.joint_names[j]
        theirs = self.robot.joint_map[ours][0]
        return (f"the gait asks {ours} ({theirs} in the robot file) for {q[i, j]:+.3f} rad at t = {float(t[i]):.2f} s, "
                f"outside its range [{self._q_lo[j]:+.3f}, {self._q_hi[j]:+.3f}] rad in the file "
                f"(the servo stops at the limit there; widen the joint's range or change the gait)")

    def from_robot(self, q: np.ndarray) -> np.ndarray:
        """The robot's servo angles (..., n) -> gait-tuner signs (..., n), columns ``joint_names``."""
        return (np.asarray(q, dtype=float) - self._offset) * self._sign

    # --- one rollout ---------------------------------------------------------------
    def _lowest_sole_z(self) -> float:
        """Height of the lowest sole corner for the current qpos (runs the kinematics)."""
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        R = d.xmat[self._feet].reshape(2, 3, 3)
        corners = d.xpos[self._feet][:, None, :] + np.einsum("fij,fkj->fki", R, self._corners)
        return float(corners[..., 2].min())

    def _place(self, q0: np.ndarray, xy: np.ndarray) -> float:
        """Reset to the gait's first pose, soles resting on the blade tips; returns torso height."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[self._qadr] = q0
        d.qpos[self._held_qadr] = self._held_pose
        d.ctrl[self._n_servo:self._n_act] = self._held_pose
        d.qpos[0:3] = [xy[0], xy[1], 1.0]
        d.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
        d.qpos[2] = 1.0 - self._lowest_sole_z() + self.ground.layer_height + 0.0005
        mujoco.mj_forward(m, d)
        return float(d.sensordata[self._s_height])      # the fall check's height (scene: origin, or CoM)

    def landing_test(self, q0: np.ndarray, *, pitch: float = math.radians(10.0), forward_speed: float = 0.3,
                     sink_speed: float = 0.3, drop: float = 0.005, duration: float = 1.0) -> Trace:
        """The same toe-first landing on any surface: the calibration experiment for toe sticking.

        The robot, holding the joint pose ``q0`` (gait-tuner order), starts pitched forward by
        ``pitch`` [rad] with its toes ``drop`` [m] above the blade tips, moving forward at
        ``forward_speed`` and down at ``sink_speed`` [m/s]; the servos hold ``q0``; only a tilt
        beyond the fall limit ends it early (it starts low on purpose).
        Returns the trace (time from the release).
        """
        def release(m, d) -> None:
            d.qpos[3:7] = [math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0]
            d.qpos[2] += self.surface.layer_height + drop - self._lowest_sole_z()
            d.qvel[0] = forward_speed
            d.qvel[2] = -sink_speed
            mujoco.mj_forward(m, d)
        return self.run(HoldPose(q0, self.control_period), duration=duration, start=release, height_check=False)

    def _sole_corners(self, d: mujoco.MjData) -> np.ndarray:
        """The sole corners' world positions (8, 3) [m] in ``d`` (left foot's four, then right's)."""
        R = d.xmat[self._feet].reshape(2, 3, 3)
        off = R @ self._corners_T                                       # (2, 3, 4) corners from the feet
        return (d.xpos[self._feet][:, :, None] + off).transpose(0, 2, 1).reshape(8, 3)

    def n_random(self) -> tuple[int, int, int]:
        """(bodies, servo actuators incl. held joints, mapped servos): the sizes a perturbation draws."""
        return self.model.nbody, self._n_act, self._n_servo

    def _apply(self, p: Perturbation) -> None:
        """Set the model's numbers to one perturbation's (undone by :meth:`_restore`)."""
        m, nom = self.model, self._nominal
        f = p.body_mass.copy()
        f[0] = 1.0                                     # the world
        m.body_mass[:] = nom["body_mass"] * f
        sub = m.body_mass.copy()                       # the subtree masses the CoM sensor divides by
        for b in range(m.nbody - 1, 0, -1):
            sub[m.body_parentid[b]] += sub[b]
        m.body_subtreemass[:] = sub
        m.body_inertia[:] = nom["body_inertia"] * f[:, None]
        m.body_ipos[:] = nom["body_ipos"] + np.where(np.arange(m.nbody)[:, None] == 0, 0.0, p.body_com)
        a = slice(0, self._n_act)
        # a pd servo's gain and torque by their factors; a dc-motor servo's from its voltage, kt and R
        motor, volt = self._motor, p.voltage
        if p.kt is not None:
            fkt, fr, ff = p.kt, p.resistance, p.servo_friction
            torque_f = np.where(motor, volt * fkt / fr, 1.0)
            gain_f, torque_f = np.where(motor, torque_f, p.kp), np.where(motor, torque_f, p.torque)
            m.actuator_damping[a] = nom["actuator_damping"][a] * np.where(motor, fkt * fkt / fr, 1.0)
            dofs = self._act_dof
            m.dof_damping[dofs] = nom["dof_damping"][dofs] * np.where(motor, ff, 1.0)
            m.dof_frictionloss[dofs] = nom["dof_frictionloss"][dofs] * np.where(motor, ff, 1.0)
            if m.nuser_actuator:                  # the per-step friction term's base, Stribeck part and back-EMF
                u = nom["actuator_user"][a]
                m.actuator_user[a, 2:4] = u[:, 2:4] * np.where(motor, ff, 1.0)[:, None]
                if m.nuser_actuator > 14:
                    m.actuator_user[a, 14] = u[:, 14] * np.where(motor, fkt * fkt / fr, 1.0)
        else:
            gain_f, torque_f = p.kp, p.torque
        m.actuator_gainprm[a, 0] = nom["actuator_gainprm"][a, 0] * gain_f
        m.actuator_biasprm[a, 1] = nom["actuator_biasprm"][a, 1] * gain_f
        m.actuator_forcerange[a] = nom["actuator_forcerange"][a] * torque_f[:, None]
        self.ground.perturb(m, nom, p)          # its friction, height, stiffness and drag by their factors
        m.opt.gravity[:] = np.linalg.norm(self._nominal_gravity) * p.gravity_dir

    def _restore(self) -> None:
        m = self.model
        for name, value in self._nominal.items():
            getattr(m, name)[:] = value
        m.opt.gravity[:] = self._nominal_gravity
        self.ground.restore()

    def rollout(self, traj: GaitTrajectory, *, duration: float | None = None, perturb: Perturbation | None = None,
                stabiliser: StabiliserParams | None = None, record_qpos: bool = False) -> Trace:
        """Play a gait's joint table on the robot (:class:`gaits.control.TablePlayer`), with the IMU
        stabiliser around it when ``stabiliser`` is given and enabled; see :meth:`run`."""
        if abs(traj.dt - self.control_period) > 1e-9:
            raise ValueError(f"the joint table's dt ({traj.dt:g} s) must equal the control period "
                             f"({self.control_period:g} s)")
        controller = TablePlayer(traj)
        if stabiliser is not None and stabiliser.enabled:
            controller = Stabilised(controller, stabiliser)
        return self.run(controller, duration=duration, perturb=perturb, record_qpos=record_qpos)

    def tilt_and_height(self, d: mujoco.MjData | None = None) -> tuple[float, float]:
        """(cos of the torso's tilt from upright, the height the fall check reads [m]) of the state
        in ``d`` (default this simulator's) after a step: the two numbers the fall criteria judge."""
        s = (self.data if d is None else d).sensordata
        return float(s[self._s_tilt]), float(s[self._s_height])

    def run(self, controller: Controller, *, duration: float | None = None, perturb: Perturbation | None = None,
            commands=None, pushes=(), record_qpos: bool = False, start=None, height_check: bool = True,
            hooks=None, on_tick=None) -> Trace:
        """Walk the robot under ``controller`` (``gaits/control.py``); stop at the end, a fall, or
        divergence.

        ``duration`` [s]: how long (default, and at most: the controller's own ``duration``).
        ``perturb`` (``tuner/sim/randomisation.py``) changes the model for this rollout only and
        adds backlash, command and IMU latency, sensor noise, a start-pose error and a push (at
        its fraction of the controller's walking window). ``commands``: an object whose
        ``at(t)`` gives the walk command (vx, vy, wz) of time t, handed to the controller every
        tick. ``pushes``: (t [s], impulse (3,) [N s]) pairs, each applied to the torso over one
        control tick. ``record_qpos`` keeps the model's qpos per tick (for a video). ``start``
        (ours, for experiments): ``start(model, data)`` changes the placed state before the
        first measurement. ``hooks`` (ours, for experiments): {tick: fn(model, data)} called before
        that tick's physics (the push-recovery challenge releases its pendulum so). ``on_tick``:
        fn(tick, data) after each tick's physics (a live viewer syncs there); returning False ends
        the walk ("stopped").
        """
        dt = float(controller.dt)
        if abs(dt - self.control_period) > 1e-9:
            raise ValueError(f"the controller's control period ({dt:g} s) must equal the robot's "
                             f"({self.control_period:g} s)")
        own = getattr(controller, "duration", None)
        if own is None and duration is None:
            raise ValueError("give a duration: this controller walks as long as it is run")
        length = own if duration is None else (duration if own is None else min(duration, own))
        if perturb is None:
            return self._run(controller, length, None, commands, pushes, record_qpos, start, height_check, hooks,
                             on_tick)
        self._apply(perturb)
        try:
            return self._run(controller, length, perturb, commands, pushes, record_qpos, start, height_check, hooks,
                             on_tick)
        finally:
            self._restore()

    def _run(self, controller: Controller, length: float, pert: Perturbation | None, commands, pushes,
             record_qpos: bool, start, height_check: bool, hooks=None, on_tick=None) -> Trace:
        m, d = self.model, self.data
        dt = self.control_period
        n_ticks = int(round(length / dt)) + 1
        pose = controller.start_pose()
        q0 = self.to_robot(pose.q)
        z0 = self._place(q0, np.asarray(pose.p_world_pelvis_xy, dtype=float))
        cmd = q0.copy()
        step = self._max_step
        latency = self._latency
        backlash = self._backlash / 2 if np.any(self._backlash > 0) else None
        kicks: dict[int, np.ndarray] = {}
        for t_push, impulse in pushes:
            kicks[int(round(t_push / dt))] = np.asarray(impulse, dtype=float) / dt
        if pert is not None:
            step = step * pert.speed
            d.qpos[self._qadr] += pert.initial_pose
            mujoco.mj_forward(m, d)
            latency = self._latency + pert.latency
            band = self._backlash + pert.backlash
            backlash = band / 2 if np.any(band > 0) else None
            if pert.push_impulse > 0:
                first = int(round(getattr(controller, "walk_start", 0.0) / dt)) or 1
                tick = first + int(pert.push_time * max(n_ticks - 1 - first, 1))
                kicks[tick - 1] = (pert.push_impulse / dt) * np.array(
                    [math.cos(pert.push_angle), math.sin(pert.push_angle), 0.0])
        if start is not None:
            start(m, d)
            mujoco.mj_kinematics(m, d)          # positions only: the fall check's height, origin or CoM
            z0 = float(d.xipos[self._torso][2] if self._low_origin else d.qpos[2])
        sens = np.empty((n_ticks, m.nsensordata))
        cmds = np.empty((n_ticks, len(cmd)))
        sent_log = np.empty((n_ticks, len(cmd)))
        n_gait, n_roles = len(self.target_names), len(JOINT_NAMES)
        targets = np.empty((n_ticks, n_gait))
        sens[0] = d.sensordata
        cmds[0] = cmd
        sent_log[0] = cmd
        targets[0] = self.robot.with_extras(pose.q)
        qpos_log = np.empty((n_ticks, m.nq)) if record_qpos else None
        if qpos_log is not None:
            qpos_log[0] = d.qpos
        reader = SensorReader(self, getattr(controller, "senses", None), pert)
        cos_tilt = math.cos(self.fall.max_tilt)
        max_speed2, max_spin2, max_height = self.fall.max_speed ** 2, self.fall.max_spin ** 2, self.fall.max_height
        qvel = d.qvel
        z_min = self.fall.min_height_ratio * z0 if height_check else -math.inf
        # a per-tick part of the ground in Python: the blade layer, or the drag gate without its callback
        ground = self.ground.python_tick
        self.ground.reset()
        W = mujoco.mjtWarning          # MuJoCo resets a state it finds huge or NaN, with one of these
        warn_q, warn_v, warn_a = d.warning[W.mjWARN_BADQPOS], d.warning[W.mjWARN_BADQVEL], d.warning[W.mjWARN_BADQACC]
        reason, k_end = "completed", n_ticks
        torso = self._torso
        col, sign, offset, q_lo, q_hi = self._col_in_gait, self._sign, self._offset, self._q_lo, self._q_hi
        lo_step = -step
        vmax, vmin = np.maximum, np.minimum        # np.clip's own arithmetic, without its 2 us wrapper
        ctrl, sdata, qacc = d.ctrl, d.sensordata, d.qacc
        tilt_i, height_i = self._s_tilt, self._s_height
        n_servo = self._n_servo
        sent = deque(cmd.copy() for _ in range(latency))   # commands on their way to the servos
        meas = reader.read(0.0)
        controller.reset(meas)
        self.ground.arm(m, d, self.nstep)      # a contact layer's native drag gate from here on
        try:
            # a controller that senses nothing and knows its targets ahead (a joint table, without a
            # command stream): its targets mapped to the servos at once, not read, stepped and
            # mapped tick by tick (the same numbers: the same operations per element)
            ahead = getattr(controller, "ahead", None)
            rows = ahead(n_ticks) if ahead is not None and commands is None and not reader.senses else None
            planned = None
            k_first = 1
            if rows is not None:
                rows = self.robot.with_extras(rows)
                targets[1:] = rows[1:]
                # the rate limiter and the joint ranges read only the targets: every tick's servo
                # command is known now, and what reaches the servos through the latency (before backlash)
                cmds[:] = rate_limited(rows[:, col] * sign + offset, cmd, step, q_lo, q_hi)
                planned = cmds[np.maximum(np.arange(n_ticks) - latency, 0)]
                # nothing in the plant reads the state either (no backlash, no Python ground tick, no hook):
                # MuJoCo runs the walk natively in chunks
                if backlash is None and not ground and not hooks and on_tick is None:
                    sent_log[:] = planned
                    k_first, reason, k_end = self._native(planned, kicks, sens, qpos_log, z_min, cos_tilt)
                    if k_first < n_ticks:                       # handed back: the ticks below go on
                        reason, k_end = "completed", n_ticks
            for k in range(k_first, n_ticks):
                if planned is not None:
                    out = planned[k]
                else:
                    if k > 1:
                        meas = reader.read((k - 1) * dt)
                    command = None if commands is None else commands.at((k - 1) * dt)
                    target = controller.step(meas, command)
                    shape = np.shape(target)
                    if shape != (n_gait,) and shape != (n_roles,):
                        extra = f" (or ({n_gait},): then the extra joints {', '.join(self.robot.extra_joints)})" \
                            if n_gait > n_roles else ""
                        raise UserError(f"the controller ({getattr(controller, 'source', type(controller).__name__)}) "
                                        f"returned targets of shape {shape} at t = {(k - 1) * dt:.2f} s; "
                                        f"expected ({n_roles},), one per gaits.JOINT_NAMES{extra}")
                    try:
                        if shape == (n_gait,):
                            targets[k] = target
                        else:                                       # the extra joints held at their pose
                            targets[k, :n_roles] = target
                            targets[k, n_roles:] = 0.0
                    except (TypeError, ValueError):        # strings, None: not joint angles
                        raise UserError(f"the controller ({getattr(controller, 'source', type(controller).__name__)}) "
                                        f"returned targets that are not numbers at t = {(k - 1) * dt:.2f} s "
                                        f"(e.g. {next(iter(np.ravel(np.asarray(target, dtype=object))))!r}); "
                                        f"expected {n_gait} angles [rad]") from None
                    target = targets[k]
                    if not math.isfinite(float(target.dot(target))):   # MuJoCo would zero every servo's target
                        j = int(np.argmax(~np.isfinite(target) | (np.abs(target) > 1e150)))    # the first
                        reason = (f"diverged: the controller's target for {self.target_names[j]} is {targets[k, j]} "
                                  f"at t = {(k - 1) * dt:.2f} s")
                        k_end = k
                        break
                    delta = target[col] * sign + offset - cmd
                    cmd += vmin(vmax(delta, lo_step, out=delta), step, out=delta)
                    vmin(vmax(cmd, q_lo, out=cmd), q_hi, out=cmd)
                    cmds[k] = cmd
                    if latency:
                        sent.append(cmd.copy())
                        out = sent.popleft()
                    else:
                        out = cmd
                if backlash is not None:
                    out = dead_band(out, d.qpos[self._qadr], backlash)
                ctrl[:n_servo] = out
                sent_log[k] = out
                if ground:
                    self.ground.tick(m, d)
                kick = kicks.get(k - 1)
                if kick is not None:
                    d.xfrc_applied[torso, :3] = kick
                if hooks and (k - 1) in hooks:
                    hooks[k - 1](m, d)
                mujoco.mj_step(m, d, nstep=self.nstep)
                if kick is not None:
                    d.xfrc_applied[torso, :3] = 0.0
                sens[k] = sdata
                if qpos_log is not None:
                    qpos_log[k] = d.qpos
                if warn_q.number or warn_v.number or warn_a.number or not math.isfinite(qacc[0]):
                    what = "positions" if warn_q.number else "velocities" if warn_v.number else "accelerations"
                    reason, k_end = f"diverged: MuJoCo reported unstable {what} at t = {k * dt:.2f} s", k
                    break
                v0, v1, v2, w0, w1, w2 = qvel[0], qvel[1], qvel[2], qvel[3], qvel[4], qvel[5]
                if (v0 * v0 + v1 * v1 + v2 * v2 > max_speed2 or w0 * w0 + w1 * w1 + w2 * w2 > max_spin2
                        or sdata[height_i] > max_height or not math.isfinite(v0)):
                    k_end = k + 1
                    reason = self._impossible(k, v0 * v0 + v1 * v1 + v2 * v2, w0 * w0 + w1 * w1 + w2 * w2,
                                              float(sdata[height_i]))
                    break
                if sdata[tilt_i] < cos_tilt or sdata[height_i] < z_min:
                    k_end = k + 1
                    reason = "fell"
                    break
                if on_tick is not None and on_tick(k, d) is False:
                    k_end, reason = k + 1, "stopped"
                    break
        finally:
            self.ground.disarm(m, d)
        trace = self._trace(controller.plan(k_end), sens[:k_end], cmds[:k_end], targets[:k_end, col],
                            reason, z0)
        trace.q_sent = self.from_robot(sent_log[:k_end])
        if qpos_log is not None:
            trace.qpos = qpos_log[:k_end]
        if pert is not None:
            trace.meta.update({"seed": pert.seed, "namespace": pert.namespace,
                               "push_t": float(tick * dt) if pert.push_impulse > 0 else None,
                               "push_impulse": pert.push_impulse})
        if pushes:
            trace.meta["pushes"] = [(float(t), np.asarray(j, dtype=float).tolist()) for t, j in pushes]
        return trace

    def _native(self, sent: np.ndarray, kicks: dict, sens: np.ndarray, qpos_log: np.ndarray | None,
                z_min: float, cos_tilt: float) -> tuple[int, str, int]:
        """The ticks of a walk whose servo commands ``sent`` (n_ticks, n_servo) are all known, run
        by MuJoCo's native rollout (``mujoco.rollout``, on this thread) in chunks of
        :data:`NATIVE_CHUNK` ticks, each judged after it (the loop's fall and blow-up checks on the
        same numbers, vectorised: the torso's frame from the ``fall`` sensors, the velocities from
        the state); a tick with a push is a chunk of its own (the push as MuJoCo's applied force).
        Fills ``sens`` (and ``qpos_log``) tick by tick, bit for bit the loop's.

        Returns (k, reason, k_end): the walk ended at k_end for ``reason`` (k = n_ticks), or, when
        MuJoCo raised a warning inside a chunk (the native rollout stops there; the loop decides
        what a warning means), the state put back to the start of that chunk and k its first tick,
        for the tick loop to go on from."""
        m, d = self.model, self.data
        n_ticks, nst = len(sent), self.nstep
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
        with_force = (mujoco.mjtState.mjSTATE_CTRL.value | mujoco.mjtState.mjSTATE_XFRC_APPLIED.value)
        nstate = mujoco.mj_stateSize(m, full)
        q0, v0 = 1, 1 + m.nq                                   # qpos and qvel in a FULLPHYSICS state
        torso = self._torso
        per_step = np.empty((n_ticks * nst, m.nu))            # every physics step's controls
        per_step[:] = d.ctrl                                   # the held joints' targets as placed
        per_step[:, :self._n_servo] = np.repeat(sent, nst, axis=0)
        state0, warm0 = np.empty((1, nstate)), np.empty((1, m.nv))
        out_state = np.empty((1, NATIVE_CHUNK * nst, nstate))
        out_sens = np.empty((1, NATIVE_CHUNK * nst, m.nsensordata))
        max_speed2, max_spin2, max_height = self.fall.max_speed ** 2, self.fall.max_spin ** 2, self.fall.max_height
        pushed = sorted(j + 1 for j in kicks)                  # the ticks whose physics a push acts in
        k = 1
        while k < n_ticks:
            later = [j for j in pushed if j >= k]
            if later and later[0] == k:
                k1 = k + 1
                force = np.zeros((nst, m.nbody, 6))
                force[:, torso, :3] = kicks[k - 1]
                spec = with_force
                control = np.concatenate([per_step[k * nst:k1 * nst], force.reshape(nst, -1)], axis=1)[None]
            else:
                k1 = min(k + NATIVE_CHUNK, n_ticks, *later[:1])
                spec, control = mujoco.mjtState.mjSTATE_CTRL.value, per_step[None, k * nst:k1 * nst]
            n = k1 - k
            mujoco.mj_getState(m, d, state0[0], full)
            warm0[0] = d.qacc_warmstart
            user0 = d.userdata.copy()                          # the native drag gate's state (native_step.py)
            st, sd = out_state[:, :n * nst], out_sens[:, :n * nst]
            _ROLLOUT.rollout([m], [d], state0, control, control_spec=spec, skip_checks=True,
                             nstep=n * nst, initial_warmstart=warm0, state=st, sensordata=sd)
            if d.warning.number.any():
                mujoco.mj_setState(m, d, state0[0], full)
                d.qacc_warmstart[:] = warm0[0]
                d.userdata[:] = user0
                d.xfrc_applied[:] = 0.0
                for i in range(mujoco.mjtWarning.mjNWARNING.value):
                    d.warning[i].number = 0
                return k, "", n_ticks
            ticks_state, ticks_sens = st[0, nst - 1::nst], sd[0, nst - 1::nst]    # each tick's last step
            sens[k:k1] = ticks_sens
            if qpos_log is not None:
                qpos_log[k:k1] = ticks_state[:, q0:q0 + m.nq]
            v_0, v_1, v_2, w_0, w_1, w_2 = ticks_state[:, v0:v0 + 6].T
            speed2 = v_0 * v_0 + v_1 * v_1 + v_2 * v_2
            spin2 = w_0 * w_0 + w_1 * w_1 + w_2 * w_2
            zaxis_z, height = ticks_sens[:, self._s_tilt], ticks_sens[:, self._s_height]   # as the loop's
            impossible = (speed2 > max_speed2) | (spin2 > max_spin2) | (height > max_height) | ~np.isfinite(v_0)
            bad = impossible | (zaxis_z < cos_tilt) | (height < z_min)          # the loop's checks
            if bad.any():
                i = int(np.argmax(bad))
                j = k + i
                mujoco.mj_setState(m, d, ticks_state[i], full)         # the state the walk ended in
                if impossible[i]:
                    return n_ticks, self._impossible(j, float(speed2[i]), float(spin2[i]), float(height[i])), j + 1
                return n_ticks, "fell", j + 1
            k = k1
        return n_ticks, "completed", n_ticks

    def _impossible(self, k: int, speed2: float, spin2: float, height: float) -> str:
        """The reason a walk ended at tick ``k`` in a state no kid-size robot reaches."""
        return (f"impossible: at t = {k * self.control_period:.2f} s the torso moves {math.sqrt(speed2):.1f} "
                f"m/s, spins {math.sqrt(spin2):.0f} rad/s, {height:.2f} m high "
                f"(no kid-size robot does: limits {self.fall.max_speed:g} m/s, {self.fall.max_spin:g} "
                f"rad/s, {self.fall.max_height:g} m)")

    def _trace(self, plan: PlanRecord, sens: np.ndarray, cmds: np.ndarray, q_ref: np.ndarray,
               reason: str, z0: float) -> Trace:
        """The recorder: ground truth of every tick (the sensor vector) beside the controller's plan."""
        k = len(sens)
        t = np.arange(k) * self.control_period
        rpy = rpy_from_quat(sens[:, self._s_quat])
        pitch, roll = rpy[:, 1], rpy[:, 0]
        force = sens[:, self._s_touch] @ self._touch_sum
        p_touch = sens[:, self._s_touchpos].reshape(k, 8, 3)
        weight = float(self.model.body_subtreemass[self._torso]) * 9.81      # the robot's (not a pendulum's)
        zmp = centre_of_pressure(force, p_touch, min_total=0.1 * weight)
        # relative to the support foot (the midpoint of both in double support), so that an
        # open-loop drift of the whole walk does not count as ZMP tracking error
        sup = plan.support[:k, None]
        sole_l, sole_r = sens[:, self._s_sole][:, :2], sens[:, self._s_sole][:, 3:5]
        plan_l, plan_r = plan.p_world_foot_l[:k], plan.p_world_foot_r[:k]
        anchor = np.where(sup == 1, sole_l, np.where(sup == -1, sole_r, (sole_l + sole_r) / 2))
        anchor_ref = np.where(sup == 1, plan_l, np.where(sup == -1, plan_r, (plan_l + plan_r) / 2))
        fell = reason == "fell"
        outcome = reason.split(":")[0] if reason.split(":")[0] in OUTCOMES else reason
        t_fall = p_fall = None
        if fell:
            t_fall = float(t[-1])
            p_fall = sens[-1, self._s_pos].copy()
            reason = (f"fell at t = {t_fall:.2f} s, x = {p_fall[0]:.3f} m: torso pitch "
                      f"{math.degrees(pitch[-1]):+.0f} deg, roll {math.degrees(roll[-1]):+.0f} deg, "
                      f"height {(sens[-1, self._s_height] if self._low_origin else p_fall[2]) / z0:.0%} of start")
        zmp_ref = plan.p_world_zmp_ref[:k]
        return Trace(t=t, pitch=pitch, roll=roll, p_torso=sens[:, self._s_pos],
                     p_com=sens[:, self._s_com], p_sole_l=sens[:, self._s_sole][:, :3],
                     p_sole_r=sens[:, self._s_sole][:, 3:], force=force, p_touch=p_touch, zmp=zmp,
                     zmp_ref=zmp_ref, zmp_local=zmp - anchor,
                     zmp_ref_local=zmp_ref - anchor_ref, support=plan.support[:k],
                     q=self.from_robot(sens[:, self._s_q]), q_cmd=self.from_robot(cmds),
                     q_ref=np.array(q_ref),
                     tau=sens[:, self._s_tau] * self._sign, joint_names=self.joint_names, fell=fell,
                     t_fall=t_fall, p_fall=p_fall, reason=reason, walk_start=plan.walk_start,
                     cycle_time=plan.cycle_time,
                     meta={"robot": self.robot.name, "surface": self.surface.name,
                           "family": plan.family, "zmp_source": plan.zmp_source,
                           **{k: plan.meta[k] for k in ("steady", "step_starts", "stream", "steps", "replans",
                                                        "binding", "touchdowns", "estimate_com", "estimate_vel", "plan_com",
                                                        "plan_vel") if k in plan.meta}},
                     yaw=np.unwrap(rpy[:, 2]), outcome=outcome)
