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

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from gaits import JOINT_NAMES, GaitTrajectory

from .centre_of_pressure import centre_of_pressure
from .robots import RobotModel
from .surfaces import Surface

__all__ = ["FallCriteria", "Trace", "Simulator"]


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

    @property
    def completed(self) -> bool:
        return self.reason == "completed"


def _quat_pitch_roll(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Z-Y-X Euler pitch and roll from quaternions (K, 4) [w, x, y, z]."""
    w, x, y, z = q.T
    r20 = 2 * (x * z - w * y)
    r21 = 2 * (y * z + w * x)
    r22 = 1 - 2 * (x * x + y * y)
    pitch = np.arcsin(np.clip(-r20, -1.0, 1.0))
    roll = np.arctan2(r21, r22)
    return pitch, roll


class Simulator:
    """One compiled MuJoCo model of a robot on a surface, reused across rollouts."""

    def __init__(self, robot: RobotModel, surface: Surface, *, control_period: float = 0.01,
                 timestep: float = 0.002, fall: FallCriteria = FallCriteria()) -> None:
        self.robot = robot
        self.surface = surface
        self.fall = fall
        self.control_period = control_period
        self.nstep = int(round(control_period / timestep))
        if self.nstep < 1 or abs(self.nstep * timestep - control_period) > 1e-9:
            raise ValueError(f"control_period {control_period} s must be a multiple of timestep {timestep} s")
        spec = robot.spec()
        self._build(spec, timestep)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._index()

    # --- model assembly ------------------------------------------------------------
    def _build(self, spec: mujoco.MjSpec, timestep: float) -> None:
        r, s = self.robot, self.surface
        spec.option.timestep = timestep
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        for g in list(spec.worldbody.geoms):           # the robot file's own floor, if any
            if g.type == mujoco.mjtGeom.mjGEOM_PLANE:
                spec.delete(g)
        for a in list(spec.actuators):                 # our servo model replaces the file's actuators
            spec.delete(a)
        for sn in list(spec.sensors):
            spec.delete(sn)
        soil = spec.worldbody.add_geom(name="soil", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
        soil.friction = [s.soil_friction, 0.005, 0.0001]
        soil.priority = 2
        soil.contype = 0
        soil.conaffinity = 1
        soil.rgba = [0.45, 0.35, 0.25, 1]
        if not s.rigid:
            layer = spec.worldbody.add_geom(name="layer", type=mujoco.mjtGeom.mjGEOM_PLANE,
                                            size=[0, 0, 0.05])
            layer.margin = s.layer_height
            layer.friction = [s.friction, 0.005, 0.0001]
            layer.solref = [s.layer_timeconst, s.layer_dampratio]
            layer.solimp = [s.layer_dmin, s.layer_dmax, s.layer_height, 0.5, 2.0]
            layer.priority = 2
            layer.contype = 0
            layer.conaffinity = 1
            layer.group = 1
            layer.rgba = [0.2, 0.6, 0.2, 0.3]
        torso = spec.body(r.torso)
        torso.add_site(name="imu", pos=[0, 0, 0.05])
        fl, fw = r.foot_size
        depth = s.layer_height + 0.03
        for side, fname, sole in zip("lr", r.feet, r.soles):
            foot = spec.body(fname)
            foot.add_site(name=f"{side}_sole", pos=list(sole))
            pad = 0.005       # reach past the sole's edge so corner contacts are not lost
            for k, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
                foot.add_site(name=f"{side}_touch{k}", type=mujoco.mjtGeom.mjGEOM_BOX,
                              pos=[sole[0] + sx * (fl / 4 + pad / 2), sole[1] + sy * (fw / 4 + pad / 2),
                                   sole[2] - depth / 2 + 0.004],
                              size=[fl / 4 + pad / 2, fw / 4 + pad / 2, depth / 2 + 0.004], group=4)
        # joints: armature, damping and friction of the servos; actuators for every mapped joint
        self.joint_names = tuple(n for n in JOINT_NAMES if n in r.joint_map)
        for ours in self.joint_names:
            theirs, _ = r.joint_map[ours]
            servo = r.leg_servo if ours[2:] in ("hip_yaw", "hip_roll", "hip_pitch", "knee",
                                                "ankle_pitch", "ankle_roll") else r.arm_servo
            j = spec.joint(theirs)
            j.armature = servo.armature
            j.damping = [servo.damping, 0.0, 0.0]
            j.frictionloss = servo.frictionloss
            act = spec.add_actuator(name=f"act_{ours}", target=theirs,
                                    trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_position(kp=servo.kp, kv=servo.kv)
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [-servo.torque, servo.torque]
        # in-layer drag: per sole corner, a damper along world x and y (site transmission with a
        # world reference site): force = -drag * v * ctrl, computed by MuJoCo every physics step and
        # integrated implicitly (implicitfast), so it is stable at any drag; ctrl gates it per tick
        # to the corners that are inside the layer.
        self._drag_names = []
        if s.drag > 0.0:
            spec.worldbody.add_site(name="drag_ref", pos=[0, 0, 0])
            for side, fname, sole in zip("lr", r.feet, r.soles):
                foot = spec.body(fname)
                for k, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
                    site = f"{side}_corner{k}"
                    foot.add_site(name=site, pos=[sole[0] + sx * fl / 2, sole[1] + sy * fw / 2, sole[2]],
                                  group=4)
                    for axis, gear in (("x", [1, 0, 0, 0, 0, 0]), ("y", [0, 1, 0, 0, 0, 0])):
                        act = spec.add_actuator(name=f"drag_{site}_{axis}", target=site, refsite="drag_ref",
                                                trntype=mujoco.mjtTrn.mjTRN_SITE)
                        act.set_to_damper(kv=s.drag)
                        act.gear = gear
                        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
                        act.ctrlrange = [0.0, 1.0]
                        self._drag_names.append(act.name)
        # sensors, in this order (offsets below)
        add = spec.add_sensor
        add(name="imu_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT, objtype=mujoco.mjtObj.mjOBJ_SITE,
            objname="imu")
        add(name="imu_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=mujoco.mjtObj.mjOBJ_SITE,
            objname="imu")
        add(name="com", type=mujoco.mjtSensor.mjSENS_SUBTREECOM, objtype=mujoco.mjtObj.mjOBJ_BODY,
            objname=r.torso)
        for side in "lr":
            add(name=f"{side}_sole_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"{side}_sole")
        for side in "lr":
            for k in range(4):
                add(name=f"{side}_touch{k}", type=mujoco.mjtSensor.mjSENS_TOUCH,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"{side}_touch{k}")
        for side in "lr":
            for k in range(4):
                add(name=f"{side}_touch{k}_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"{side}_touch{k}")
        for ours in self.joint_names:
            add(name=f"q_{ours}", type=mujoco.mjtSensor.mjSENS_ACTUATORPOS,
                objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=f"act_{ours}")
        for ours in self.joint_names:
            add(name=f"tau_{ours}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=f"act_{ours}")

    def _index(self) -> None:
        m, r = self.model, self.robot
        n = len(self.joint_names)
        o = 0
        self._s_quat = slice(o, o + 4); o += 4
        self._s_pos = slice(o, o + 3); o += 3
        self._s_com = slice(o, o + 3); o += 3
        self._s_sole = slice(o, o + 6); o += 6
        self._s_touch = slice(o, o + 8); o += 8
        self._s_touchpos = slice(o, o + 24); o += 24
        self._s_q = slice(o, o + n); o += n
        self._s_tau = slice(o, o + n); o += n
        assert o == m.nsensordata, (o, m.nsensordata)
        self._torso = m.body(r.torso).id
        self._feet = np.array([m.body(f).id for f in r.feet])
        self._roots = m.body_rootid[self._feet]
        self._sign = np.array([r.joint_map[j][1] for j in self.joint_names], dtype=float)
        self._qadr = np.array([m.jnt_qposadr[m.joint(r.joint_map[j][0]).id] for j in self.joint_names])
        jr = np.array([m.jnt_range[m.joint(r.joint_map[j][0]).id] for j in self.joint_names])
        limited = np.array([m.jnt_limited[m.joint(r.joint_map[j][0]).id] for j in self.joint_names], bool)
        self._q_lo = np.where(limited, jr[:, 0], -np.inf)
        self._q_hi = np.where(limited, jr[:, 1], np.inf)
        speeds = np.array([(r.leg_servo if j[2:] in ("hip_yaw", "hip_roll", "hip_pitch", "knee",
                                                     "ankle_pitch", "ankle_roll") else r.arm_servo).speed
                           for j in self.joint_names])
        self._max_step = speeds * self.control_period
        fl, fw = r.foot_size
        corners = np.array([[sx * fl / 2, sy * fw / 2, 0.0] for sx in (1, -1) for sy in (1, -1)])
        self._corners = np.stack([corners + np.array(s) for s in r.soles])      # (2, 4, 3) in foot frame
        self._corners_T = np.ascontiguousarray(self._corners.transpose(0, 2, 1))  # (2, 3, 4)
        self._col_in_gait = np.array([JOINT_NAMES.index(j) for j in self.joint_names])
        self._n_servo = len(self.joint_names)

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
        d.qpos[0:3] = [xy[0], xy[1], 1.0]
        d.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
        d.qpos[2] = 1.0 - self._lowest_sole_z() + self.surface.layer_height + 0.0005
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
        q0 = np.asarray(q0, dtype=float)[self._col_in_gait] * self._sign
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
        inside = (pz < self.surface.layer_height).astype(float).ravel()
        d.ctrl[self._n_servo:] = np.repeat(inside, 2)                       # x and y per corner

    def rollout(self, traj: GaitTrajectory, *, duration: float | None = None) -> Trace:
        """Play a gait's joint table on the robot; stop at the end, a fall, or divergence."""
        if abs(traj.dt - self.control_period) > 1e-9:
            raise ValueError(f"the joint table's dt ({traj.dt:g} s) must equal the control period "
                             f"({self.control_period:g} s)")
        m, d = self.model, self.data
        q_ref = traj.q_ref[:, self._col_in_gait] * self._sign        # into the robot's joint signs
        n_ticks = len(traj.t)
        if duration is not None:
            n_ticks = min(n_ticks, int(round(duration / self.control_period)) + 1)
        z0 = self._place(q_ref[0], traj.p_world_pelvis[0, :2])
        cmd = q_ref[0].copy()
        sens = np.empty((n_ticks, m.nsensordata))
        cmds = np.empty((n_ticks, len(cmd)))
        sens[0] = d.sensordata
        cmds[0] = cmd
        cos_tilt = math.cos(self.fall.max_tilt)
        z_min = self.fall.min_height_ratio * z0
        drag = self.surface.drag > 0.0
        warn = mujoco.mjtWarning.mjWARN_BADQACC
        reason, k_end = "completed", n_ticks
        torso = self._torso
        step = self._max_step
        for k in range(1, n_ticks):
            cmd += np.clip(q_ref[k] - cmd, -step, step)
            np.clip(cmd, self._q_lo, self._q_hi, out=cmd)
            d.ctrl[:self._n_servo] = cmd
            if drag:
                self._drag()
            mujoco.mj_step(m, d, nstep=self.nstep)
            sens[k] = d.sensordata
            cmds[k] = cmd
            if d.warning[warn].number or not math.isfinite(d.qacc[0]):
                reason, k_end = f"diverged: MuJoCo reported unstable accelerations at t = {k * self.control_period:.2f} s", k
                break
            if d.xmat[torso, 8] < cos_tilt or d.xpos[torso, 2] < z_min:
                k_end = k + 1
                reason = "fell"
                break
        sens = sens[:k_end]
        return self._trace(traj, sens, cmds[:k_end], q_ref[:k_end], reason, z0)

    def _trace(self, traj: GaitTrajectory, sens: np.ndarray, cmds: np.ndarray, q_ref: np.ndarray,
               reason: str, z0: float) -> Trace:
        k = len(sens)
        t = traj.t[:k]
        pitch, roll = _quat_pitch_roll(sens[:, self._s_quat])
        force = sens[:, self._s_touch]
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
                     q=sens[:, self._s_q] * self._sign, q_cmd=cmds * self._sign, q_ref=q_ref * self._sign,
                     tau=sens[:, self._s_tau] * self._sign, joint_names=self.joint_names, fell=fell,
                     t_fall=t_fall, p_fall=p_fall, reason=reason, walk_start=walk_start,
                     cycle_time=float(traj.meta.get("cycle_time", 1.0)),
                     meta={"robot": self.robot.name, "surface": self.surface.name,
                           "family": traj.family, "zmp_source": traj.zmp_source})
