"""MuJoCo walking rollouts: q_ref(t) -> position servos -> a trace of what the robot did.

This is the only module that reads physics. A :class:`Simulator` is built once
per (robot, surface) and runs many rollouts. Per control tick (10 ms by
default) it rate-limits the joint targets to the servos' speed, sets the
position actuators (torque-limited), applies the grass drag (see
``tuner.surfaces``), advances MuJoCo by ``nstep`` steps in one call, copies the
sensor vector, and checks for a fall or a diverging simulation.

Sensors: an IMU site on the torso (orientation, gyro), the whole-body CoM, each
sole centre, and four touch sensors per sole (toe-left, toe-right, heel-left,
heel-right quadrants), the quantity the TLIPFM paper measured with four force
sensors per sole; the measured ZMP is their centre of pressure.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from gaits import JOINT_NAMES, GaitTrajectory, StabiliserParams, stabiliser_corrections

from .centre_of_pressure import centre_of_pressure
from .randomisation import Perturbation
from ..robots import PREFIX, RobotModel, SimOptions, build_scene
from ..robots.scene import CORNERS
from .surfaces import Surface

__all__ = ["FallCriteria", "Trace", "Simulator", "dead_band"]


@dataclass(frozen=True)
class FallCriteria:
    """When a rollout counts as a fall (and stops early)."""

    max_tilt: float = math.radians(50.0)   # [rad] torso tilt from upright (pitch and roll together)
    min_height_ratio: float = 0.6          # torso below this fraction of its starting height


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
    reason: str                 # "completed", "fell: ...", "diverged: ..."
    walk_start: float           # [s] first planned single support
    cycle_time: float           # [s] one gait cycle (two steps), for the +- amplitude
    meta: dict = field(default_factory=dict)
    q_sent: np.ndarray | None = None   # (K, n) [rad] targets the servos received (after latency, backlash)
    yaw: np.ndarray | None = None      # (K,) [rad] torso heading, unwrapped (counter-clockwise positive)
    qpos: np.ndarray | None = None     # (K, nq) MuJoCo qpos per tick, when the rollout recorded it

    @property
    def completed(self) -> bool:
        return self.reason == "completed"


def dead_band(target: np.ndarray, q: np.ndarray, half_width: np.ndarray) -> np.ndarray:
    """Backlash as a dead band: the target a servo acts on when errors below ``half_width`` [rad]
    move nothing and larger ones move it by what exceeds the band (shapes (n,))."""
    e = target - q
    return q + np.sign(e) * np.maximum(np.abs(e) - half_width, 0.0)


def _quat_pitch_roll(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Z-Y-X Euler pitch and roll from quaternions (K, 4) [w, x, y, z]."""
    w, x, y, z = q.T
    r20 = 2 * (x * z - w * y)
    r21 = 2 * (y * z + w * x)
    r22 = 1 - 2 * (x * x + y * y)
    pitch = np.arcsin(np.clip(-r20, -1.0, 1.0))
    roll = np.arctan2(r21, r22)
    return pitch, roll


def _quat_yaw(q: np.ndarray) -> np.ndarray:
    """Z-Y-X Euler yaw from quaternions (K, 4) [w, x, y, z], unwrapped along K [rad]."""
    w, x, y, z = q.T
    return np.unwrap(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


class Simulator:
    """One compiled MuJoCo model of a robot on a surface, reused across rollouts."""

    def __init__(self, robot: RobotModel, surface: Surface, *, control_period: float | None = None,
                 timestep: float | None = None, fall: FallCriteria | None = None) -> None:
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
        self.spec = spec
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._index()
        self._layer_h = surface.layer_height
        m = self.model
        self._nominal = {name: getattr(m, name).copy() for name in
                         ("body_mass", "body_subtreemass", "body_inertia", "body_ipos", "actuator_gainprm", "actuator_biasprm",
                          "actuator_forcerange", "geom_friction", "geom_margin", "geom_solref", "geom_solimp")}
        self._nominal_gravity = m.opt.gravity.copy()
        self._ground = [m.geom(PREFIX + "soil").id] + ([m.geom(PREFIX + "layer").id] if not surface.rigid else [])
        self._layer = m.geom(PREFIX + "layer").id if not surface.rigid else None
        # stabiliser: which servo columns each of its four corrections moves, with the joint's sign
        self._stab = np.zeros((self._n_servo, 4))
        for c, kind in enumerate(("ankle_pitch", "hip_pitch", "ankle_roll", "hip_roll")):
            for side in "lr":
                name = f"{side}_{kind}"
                if name in self.joint_names:
                    i = self.joint_names.index(name)
                    self._stab[i, c] = self._sign[i]

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
        self._s_q, self._s_tau = blocks["q"], blocks["tau"]
        self._torso = m.body(r.torso).id
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
        speeds = np.array([r.servos[t].speed for t in theirs])
        self._max_step = speeds * self.control_period
        fl, fw = r.foot_size
        corners = np.array([[sx * fl / 2, sy * fw / 2, 0.0] for sx, sy in CORNERS])
        self._corners = np.stack([r.sole_points(i, corners) for i in range(2)])  # (2, 4, 3) in foot frame
        self._corners_T = np.ascontiguousarray(self._corners.transpose(0, 2, 1))  # (2, 3, 4)
        self._col_in_gait = np.array([JOINT_NAMES.index(j) for j in self.joint_names])
        self._touch_sum = np.zeros((len(lay.touch_quadrant), 8))
        self._touch_sum[np.arange(len(lay.touch_quadrant)), list(lay.touch_quadrant)] = 1.0
        self._n_servo = len(self.joint_names)
        self._n_act = self._n_servo + len(held)

    def to_robot(self, q_gait: np.ndarray) -> np.ndarray:
        """Joint targets in gait-tuner order and signs (..., 20) -> the robot's servos (..., n)."""
        return np.asarray(q_gait, dtype=float)[..., self._col_in_gait] * self._sign + self._offset

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
        d.qpos[2] = 1.0 - self._lowest_sole_z() + self._layer_h + 0.0005
        mujoco.mj_forward(m, d)
        return float(d.qpos[2])

    def landing_test(self, q0: np.ndarray, *, pitch: float = math.radians(10.0), forward_speed: float = 0.3,
                     sink_speed: float = 0.3, drop: float = 0.005, duration: float = 1.0) -> Trace:
        """The same toe-first landing on any surface: the calibration experiment for toe sticking.

        The robot, holding the joint pose ``q0`` (gait-tuner order), starts pitched forward by
        ``pitch`` [rad] with its toes ``drop`` [m] above the blade tips, moving forward at
        ``forward_speed`` and down at ``sink_speed`` [m/s]; the servos hold ``q0``.
        Returns the trace (time from the release).
        """
        m, d = self.model, self.data
        q0 = self.to_robot(q0)
        self._place(q0, np.zeros(2))
        d.qpos[3:7] = [math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0]
        d.qpos[2] += self.surface.layer_height + drop - self._lowest_sole_z()
        d.qvel[0] = forward_speed
        d.qvel[2] = -sink_speed
        mujoco.mj_forward(m, d)
        n = int(round(duration / self.control_period)) + 1
        t = np.arange(n) * self.control_period
        from gaits import GaitTrajectory
        zeros3 = np.zeros((n, 3))
        traj = GaitTrajectory("landing-test", t, np.zeros((n, len(JOINT_NAMES))), zeros3, zeros3,
                              np.zeros((n, 2)), zeros3, zeros3, np.zeros(n, dtype=int))
        sens = np.empty((n, m.nsensordata))
        sens[0] = d.sensordata
        d.ctrl[:self._n_servo] = q0
        drag = self.surface.drag > 0.0
        k_end, reason = n, "completed"
        for k in range(1, n):
            if drag:
                self._drag()
            mujoco.mj_step(m, d, nstep=self.nstep)
            sens[k] = d.sensordata
            if d.xmat[self._torso, 8] < math.cos(self.fall.max_tilt):
                k_end, reason = k + 1, "fell"
                break
        cmds = np.repeat(q0[None, :], k_end, axis=0)
        return self._trace(traj, sens[:k_end], cmds, cmds, reason, float(d.qpos[2]))

    def _drag(self) -> None:
        """Switch on the drag dampers of the sole corners that are inside the layer (module
        ``tuner.surfaces``); MuJoCo applies -drag * v at each of them every physics step."""
        d = self.data
        R = d.xmat[self._feet].reshape(2, 3, 3)
        pz = d.xpos[self._feet, 2:3] + (R @ self._corners_T)[:, 2, :]      # (2, 4) corner heights
        inside = (pz < self._layer_h).astype(float).ravel()
        d.ctrl[self._n_act:] = np.repeat(inside, 2)                       # x and y per corner

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
        m.actuator_gainprm[a, 0] = nom["actuator_gainprm"][a, 0] * p.kp
        m.actuator_biasprm[a, 1] = nom["actuator_biasprm"][a, 1] * p.kp
        m.actuator_forcerange[a] = nom["actuator_forcerange"][a] * p.torque[:, None]
        for g in self._ground:
            m.geom_friction[g, 0] = nom["geom_friction"][g, 0] * p.friction
        if self._layer is not None:
            g = self._layer
            self._layer_h = self.surface.layer_height * p.layer_height
            m.geom_margin[g] = nom["geom_margin"][g] * p.layer_height
            m.geom_solimp[g, 2] = nom["geom_solimp"][g, 2] * p.layer_height
            m.geom_solref[g, 0] = nom["geom_solref"][g, 0] * p.layer_timeconst
        drag = slice(self._n_act, m.nu)
        m.actuator_gainprm[drag, 2] = nom["actuator_gainprm"][drag, 2] * p.drag
        m.opt.gravity[:] = np.linalg.norm(self._nominal_gravity) * p.gravity_dir

    def _restore(self) -> None:
        m = self.model
        for name, value in self._nominal.items():
            getattr(m, name)[:] = value
        m.opt.gravity[:] = self._nominal_gravity
        self._layer_h = self.surface.layer_height

    def rollout(self, traj: GaitTrajectory, *, duration: float | None = None, perturb: Perturbation | None = None,
                stabiliser: StabiliserParams | None = None, record_qpos: bool = False) -> Trace:
        """Play a gait's joint table on the robot; stop at the end, a fall, or divergence.

        ``perturb`` (see ``tuner/sim/randomisation.py``) changes the model for this rollout only and
        adds backlash, command and IMU latency, IMU noise, a start-pose error and a push;
        ``stabiliser`` closes the IMU loop of ``gaits/imu_stabiliser.py`` every tick.
        ``record_qpos`` keeps the model's full qpos per tick in ``Trace.qpos`` (for a video).
        """
        if abs(traj.dt - self.control_period) > 1e-9:
            raise ValueError(f"the joint table's dt ({traj.dt:g} s) must equal the control period "
                             f"({self.control_period:g} s)")
        if perturb is None:
            return self._rollout(traj, duration, None, stabiliser, record_qpos)
        self._apply(perturb)
        try:
            return self._rollout(traj, duration, perturb, stabiliser, record_qpos)
        finally:
            self._restore()

    def _rollout(self, traj: GaitTrajectory, duration: float | None, pert: Perturbation | None,
                 stabiliser: StabiliserParams | None, record_qpos: bool = False) -> Trace:
        m, d = self.model, self.data
        q_ref = self.to_robot(traj.q_ref)                            # into the robot's joints
        n_ticks = len(traj.t)
        if duration is not None:
            n_ticks = min(n_ticks, int(round(duration / self.control_period)) + 1)
        z0 = self._place(q_ref[0], traj.p_world_pelvis[0, :2])
        cmd = q_ref[0].copy()
        sens = np.empty((n_ticks, m.nsensordata))
        cmds = np.empty((n_ticks, len(cmd)))
        sent_log = np.empty((n_ticks, len(cmd)))
        sens[0] = d.sensordata
        cmds[0] = cmd
        sent_log[0] = cmd
        qpos_log = np.empty((n_ticks, m.nq)) if record_qpos else None
        cos_tilt = math.cos(self.fall.max_tilt)
        z_min = self.fall.min_height_ratio * z0
        drag = self.surface.drag > 0.0
        warn = mujoco.mjtWarning.mjWARN_BADQACC
        reason, k_end = "completed", n_ticks
        torso = self._torso
        step = self._max_step
        stab = stabiliser is not None and stabiliser.enabled
        latency = imu_latency = 0
        backlash = None
        push_tick = -1
        if pert is not None:
            step = step * pert.speed
            d.qpos[self._qadr] += pert.initial_pose
            mujoco.mj_forward(m, d)
            latency, imu_latency = pert.latency, pert.imu_latency
            backlash = pert.backlash / 2 if np.any(pert.backlash > 0) else None
            noise = np.random.default_rng(pert.noise_seed)
            if pert.push_impulse > 0:
                walking = np.flatnonzero(traj.support[:n_ticks] != 0)
                first = int(walking[0]) if len(walking) else 1
                push_tick = first + int(pert.push_time * max(n_ticks - 1 - first, 1))
                push = (pert.push_impulse / self.control_period) * np.array(
                    [math.cos(pert.push_angle), math.sin(pert.push_angle), 0.0])
        if qpos_log is not None:
            qpos_log[0] = d.qpos
        sent = [cmd.copy() for _ in range(latency)]       # commands on their way to the servos
        imu = [np.zeros(4) for _ in range(imu_latency)]   # readings on their way from the IMU
        for k in range(1, n_ticks):
            target = q_ref[k]
            if stab:
                pitch, roll = _quat_pitch_roll(d.sensordata[self._s_quat][None, :])
                reading = np.array([pitch[0], roll[0], d.qvel[4], d.qvel[3]])
                if pert is not None:
                    reading += noise.normal(0.0, 1.0, 4) * [pert.imu_noise, pert.imu_noise,
                                                            pert.gyro_noise, pert.gyro_noise]
                imu.append(reading)
                p_, r_, pr, rr = imu.pop(0)
                target = target + self._stab @ stabiliser_corrections(stabiliser, p_, r_, pr, rr)
            cmd += np.clip(target - cmd, -step, step)
            np.clip(cmd, self._q_lo, self._q_hi, out=cmd)
            if latency:
                sent.append(cmd.copy())
                out = sent.pop(0)
            else:
                out = cmd
            if backlash is not None:
                out = dead_band(out, d.qpos[self._qadr], backlash)
            d.ctrl[:self._n_servo] = out
            sent_log[k] = out
            if drag:
                self._drag()
            if k == push_tick:
                d.xfrc_applied[torso, :3] = push
            mujoco.mj_step(m, d, nstep=self.nstep)
            if k == push_tick:
                d.xfrc_applied[torso, :3] = 0.0
            sens[k] = d.sensordata
            cmds[k] = cmd
            if qpos_log is not None:
                qpos_log[k] = d.qpos
            if d.warning[warn].number or not math.isfinite(d.qacc[0]):
                reason, k_end = f"diverged: MuJoCo reported unstable accelerations at t = {k * self.control_period:.2f} s", k
                break
            if d.xmat[torso, 8] < cos_tilt or d.xpos[torso, 2] < z_min:
                k_end = k + 1
                reason = "fell"
                break
        sens = sens[:k_end]
        trace = self._trace(traj, sens, cmds[:k_end], q_ref[:k_end], reason, z0)
        trace.q_sent = self.from_robot(sent_log[:k_end])
        if qpos_log is not None:
            trace.qpos = qpos_log[:k_end]
        if pert is not None:
            trace.meta.update({"seed": pert.seed, "namespace": pert.namespace,
                               "push_t": None if push_tick < 0 else float(traj.t[push_tick]),
                               "push_impulse": pert.push_impulse})
        return trace

    def _trace(self, traj: GaitTrajectory, sens: np.ndarray, cmds: np.ndarray, q_ref: np.ndarray,
               reason: str, z0: float) -> Trace:
        k = len(sens)
        t = traj.t[:k]
        pitch, roll = _quat_pitch_roll(sens[:, self._s_quat])
        force = sens[:, self._s_touch] @ self._touch_sum
        p_touch = sens[:, self._s_touchpos].reshape(k, 8, 3)
        weight = float(np.sum(self.model.body_mass)) * 9.81
        zmp = centre_of_pressure(force, p_touch, min_total=0.1 * weight)
        # relative to the support foot (the midpoint of both in double support), so that an
        # open-loop drift of the whole walk does not count as ZMP tracking error
        sup = traj.support[:k, None]
        sole_l, sole_r = sens[:, self._s_sole][:, :2], sens[:, self._s_sole][:, 3:5]
        plan_l, plan_r = traj.p_world_foot_l[:k, :2], traj.p_world_foot_r[:k, :2]
        anchor = np.where(sup == 1, sole_l, np.where(sup == -1, sole_r, (sole_l + sole_r) / 2))
        anchor_ref = np.where(sup == 1, plan_l, np.where(sup == -1, plan_r, (plan_l + plan_r) / 2))
        fell = reason == "fell"
        t_fall = p_fall = None
        if fell:
            t_fall = float(t[-1])
            p_fall = sens[-1, self._s_pos].copy()
            reason = (f"fell at t = {t_fall:.2f} s, x = {p_fall[0]:.3f} m: torso pitch "
                      f"{math.degrees(pitch[-1]):+.0f} deg, roll {math.degrees(roll[-1]):+.0f} deg, "
                      f"height {p_fall[2] / z0:.0%} of start")
        walking = np.flatnonzero(traj.support != 0)
        walk_start = float(traj.t[walking[0]]) if len(walking) else 0.0
        return Trace(t=t, pitch=pitch, roll=roll, p_torso=sens[:, self._s_pos],
                     p_com=sens[:, self._s_com], p_sole_l=sens[:, self._s_sole][:, :3],
                     p_sole_r=sens[:, self._s_sole][:, 3:], force=force, p_touch=p_touch, zmp=zmp,
                     zmp_ref=traj.p_world_zmp_ref[:k], zmp_local=zmp - anchor,
                     zmp_ref_local=traj.p_world_zmp_ref[:k] - anchor_ref, support=traj.support[:k],
                     q=self.from_robot(sens[:, self._s_q]), q_cmd=self.from_robot(cmds),
                     q_ref=self.from_robot(q_ref),
                     tau=sens[:, self._s_tau] * self._sign, joint_names=self.joint_names, fell=fell,
                     t_fall=t_fall, p_fall=p_fall, reason=reason, walk_start=walk_start,
                     cycle_time=float(traj.meta.get("cycle_time", 1.0)),
                     meta={"robot": self.robot.name, "surface": self.surface.name,
                           "family": traj.family, "zmp_source": traj.zmp_source,
                           **({"steady": traj.meta["steady"]} if "steady" in traj.meta else {})},
                     yaw=_quat_yaw(sens[:, self._s_quat]))
