"""The walk engine itself (ours): the step state machine (stand, weight shift, steps, stop), the
swing and the legs' IK, around the estimator (``estimator.py``), the step adjustment
(``step_adjust.py``) and the command shaping (``shaping.py``); the package docstring says what it
does per step."""

from __future__ import annotations

import math

import numpy as np

from ..control import READINGS, Measurement, PlanRecord, StartPose, finite_readings
from ..footstep_planner import StepLimits, relative, swing_fraction
from ..leg_kinematics import LegGeometry, UnreachableTargetError, leg_ik_pose
from ..lipm import dcm_forward, propagate, zmp_at
from ..params import ParamError
from ..tlipfm import TlipfmParams
from ..trajectory import GRAVITY, JOINT_NAMES
from .estimator import CoMEstimator, _ry, sole_floats, sole_rate
from .params import EngineParams
from .servo_load import LoadCompensation, servo_terms
from .shaping import CommandShaper
from .step_adjust import Step, _Gait, adjust_step

__all__ = ["WalkEngine", "STAND", "SHIFT", "WALK"]


_LEG = {1: slice(JOINT_NAMES.index("l_hip_yaw"), JOINT_NAMES.index("l_hip_yaw") + 6),
        -1: slice(JOINT_NAMES.index("r_hip_yaw"), JOINT_NAMES.index("r_hip_yaw") + 6)}
STAND, SHIFT, WALK = "stand", "shift", "walk"
#: where the numerical leg IK stops each tick (ours): an error of 1e-7 m + rad, or a Newton step under
#: 1e-4 rad taken unevaluated (its error of the order of 1e-8); both four orders of magnitude below a
#: 4096-count encoder's 1.5 mrad. A tick then evaluates the leg twice where the solver's own 1e-10 did
#: three or four times (tests/test_leg_chain.py counts them).
IK_TOL, IK_STEP = 1e-7, 1e-4


def _rot_zyx(cw: float, sw: float, pitch: float, roll: float) -> tuple:
    """Rz(yaw) Ry(pitch) Rx(roll) as a 9-tuple, row by row (``cw``, ``sw`` the yaw's cosine and sine)."""
    cp, sp, cr, sr = math.cos(pitch), math.sin(pitch), math.cos(roll), math.sin(roll)
    return (cw * cp, -sw * cr + cw * sp * sr, sw * sr + cw * sp * cr,
            sw * cp, cw * cr + sw * sp * sr, -cw * sr + sw * sp * cr,
            -sp, cp * sr, cp * cr)


class WalkEngine:
    """The online walk engine (module docstring). ``robot`` needs ``leg`` and ``foot_size``;
    ``limits`` are the step limits (``gaits.family("tlipfm").step_limits``)."""

    senses = frozenset(READINGS)

    def __init__(self, gait: TlipfmParams, params: EngineParams, robot, dt: float, limits: StepLimits) -> None:
        self.gait = _Gait(gait, limits, params.stance_widen, params.stance_speed)
        self.params = params
        self.leg: LegGeometry = robot.leg
        self.foot_size = tuple(robot.foot_size)
        self.dt = float(dt)
        self.duration = None
        self.walk_start = params.t_stand
        L, Wd = self.foot_size
        self._sensor_xy = tuple((sx * L / 4, sy * Wd / 4) for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)))
        self._log: list[tuple] = []
        self._sole_offsets = {side: tuple(float(v) for v in self.leg.sole_in_ankle(side)) for side in (1, -1)}
        self.shaper = CommandShaper(params, limits, gait.period, dt)
        # the most each target may move in a tick (params.servo_share of the servo's speed; inf: not capped)
        speeds = joint_speeds(robot)
        self._capping = params.servo_share > 0 and speeds is not None
        self._max_move = params.servo_share * speeds * self.dt if self._capping else None
        self._terms = servo_terms(robot)
        self._load = None
        if params.load_share > 0 or params.lag_share > 0:
            if self._terms is None:
                raise ParamError(f"engine: load_share = {params.load_share:g}, lag_share = {params.lag_share:g} "
                                 f"need the servos' gains, which this robot does not state (a robot file exported "
                                 f"before they were written: export it again, gait-tuner robot export MAP --out FILE)")
            self._load = LoadCompensation(self.leg, self._terms, self.dt, params.load_share, params.lag_share,
                                          (gait.mass_thigh, gait.mass_calf))
        self._robot_weight = (gait.mass_upper + 2 * (gait.mass_thigh + gait.mass_calf)) * GRAVITY
        self.reset_state()

    # --- what the engine offers ------------------------------------------------------------
    def envelope(self) -> dict[str, float]:
        """The largest command per direction its step limits and period allow [m/s, rad/s] (a
        command the ``stride_*`` calibration plans shorter steps for may be that much larger)."""
        return self.shaper.envelope()

    @property
    def command(self) -> np.ndarray:
        """(3,) the command the steps are planned for (:class:`CommandShaper`)."""
        return self.shaper.command

    @property
    def asked(self) -> np.ndarray:
        """(3,) the last command taken, clipped to the envelope."""
        return self.shaper.asked

    # --- the controller protocol -----------------------------------------------------------
    def reset_state(self) -> None:
        p = self.gait.p
        W = p.half_width
        self.feet = {1: np.array([0.0, W, 0.0]), -1: np.array([0.0, -W, 0.0])}
        self.mode = STAND
        self.t = 0.0
        self.shaper.reset()
        self.com = np.zeros(2)
        self.vel = np.zeros(2)
        self.zmp = np.zeros(2)
        self.cur: Step | None = None
        self.step_t0 = 0.0
        self.state_tau = 0.0
        self._boundary = np.zeros(2)
        self.next_side = -p.first_support          # the foot that swings first
        self.last_replan = -1.0
        self.weight = (p.mass_upper + p.mass_thigh + p.mass_calf) * GRAVITY
        self.estimator = CoMEstimator(self.gait.Tc, self.dt, self.params.kf_accel, self.params.kf_position,
                                      self.params.kf_velocity)
        self.steps_taken = 0
        self.replans = 0
        self.touchdowns = 0
        self.clamped = 0
        self.capped = 0                            # ticks whose targets were capped at the servos' speed
        self._last_q: np.ndarray | None = None
        self._last_out: np.ndarray | None = None       # the last targets sent, offsets included
        self.binding = {"replans": 0, "reach": 0, "sole": 0, "timing": 0, "speed": 0}   # re-plans on a limit
        self.step_starts: list[float] = []
        self.tilt = np.zeros(2)                    # filtered (roll, pitch beyond the planned lean) [rad]
        self.last_residual = 0.0
        self._history: list[tuple[np.ndarray, np.ndarray]] = []   # the plan's (com, vel) of recent ticks
        self._bias = np.zeros(4)                                   # slow mean of (position, velocity) error
        self.events: list[tuple[float, str]] = []      # (time, what): steps, re-plans, touch-downs
        self.dropped = {name: 0 for name in READINGS + ("command",)}   # ticks each was not finite
        self._dropping: tuple[str, ...] = ()
        self._log = []
        self._soles: dict = {}                      # this tick's sole points in the world (``_joints``)
        self._plan_rotation: tuple = ()             # this tick's pelvis as planned, Rz(psi) Ry(lean) (``_joints``)
        self._ik_seen: dict = {1: (None, None), -1: (None, None)}   # each leg's IK answers, the last two ticks
        if self._load is not None:
            self._load.reset()

    def start_pose(self) -> StartPose:
        self.reset_state()
        q = self._joints(self.com, self.feet[1], self.feet[-1])[0]
        self._last_q = np.array(q, dtype=float)
        return StartPose(q)

    def predicted_give(self) -> np.ndarray | None:
        """(20,) how far each servo gives way [rad] standing on the left foot in the start pose, the
        whole weight on it (``servo_load.py``'s model, all of it); None when the robot states no gains."""
        if self._terms is None:
            return None
        g = self.gait.p
        q = self._joints(self.com, self.feet[1], self.feet[-1])[0]
        comp = LoadCompensation(self.leg, self._terms, self.dt, 1.0, 0.0, (g.mass_thigh, g.mass_calf))
        feet = {side: np.append(f, 0.0) for side, f in self.feet.items()}
        return -comp.offsets(q, feet, self._soles, feet[1][:2], 1, self._robot_weight,
                             _ry(g.torso_pitch), self.foot_size)

    def reset(self, m: Measurement) -> None:
        self.reset_state()
        if m.foot_force is not None and float(np.sum(m.foot_force)) > 0.2 * self.weight:
            self.weight = float(np.sum(m.foot_force))
        self.estimator.reset(self.com)

    def step(self, m: Measurement, command: np.ndarray | None = None) -> np.ndarray:
        dt = self.dt
        m, dropped = finite_readings(m)
        if command is not None:
            command = np.asarray(command, dtype=float)
            if command.shape != (3,):
                raise ValueError(f"a walk command is (vx, vy, wz), shape (3,); got shape {command.shape}")
            if not math.isfinite(float(command.sum())):
                dropped += ("command",)
                command = self.asked                   # the last command taken holds
        if dropped or self._dropping:
            self._note_dropped(m.t, dropped)
        self._estimate(m, lost="q" in dropped or "imu_rpy" in dropped)
        self.shaper.update(command, walking=self.mode == WALK)
        self.t = m.t + dt
        if m.q is not None and m.imu_rpy is not None:
            self._learn_bias()
        self._advance(m)
        self._history.append((self.com.copy(), self.vel.copy()))
        if len(self._history) > 50:
            del self._history[:-25]
        q, support, feet = self._targets()
        if self._capping and self._last_q is not None:
            move = np.clip(q - self._last_q, -self._max_move, self._max_move)
            if np.any(move != q - self._last_q):
                self.capped += 1
            q = self._last_q + move
        self._last_q = np.array(q, dtype=float)
        if self._load is not None:
            q = q + self._load_offsets(q, support, feet)
            if self._capping:                          # the offsets' own moves within the servos' speed too
                if self._last_out is not None:
                    q = self._last_out + np.clip(q - self._last_out, -self._max_move, self._max_move)
                self._last_out = np.array(q, dtype=float)
        est = self.estimator
        self._log.append((support, self.zmp[0], self.zmp[1], feet[1][0], feet[1][1], feet[-1][0], feet[-1][1],
                          est.position[0], est.position[1], est.velocity[0], est.velocity[1],
                          self.com[0], self.com[1], self.vel[0], self.vel[1]))
        return q

    def plan(self, n: int) -> PlanRecord:
        W = self.gait.p.half_width
        rows = [(0, 0.0, 0.0, 0.0, W, 0.0, -W) + (0.0,) * 8] + self._log[:n - 1]
        rows += [rows[-1]] * (n - len(rows))
        a = np.array(rows, dtype=float)
        return PlanRecord("tlipfm-engine", a[:, 0].astype(int), a[:, 1:3], a[:, 3:5], a[:, 5:7],
                          walk_start=self.walk_start, cycle_time=2 * self.gait.p.period,
                          meta={"step_starts": list(self.step_starts), "steps": self.steps_taken,
                                "replans": self.replans, "binding": dict(self.binding),
                                "touchdowns": self.touchdowns, "dropped": dict(self.dropped),
                                "estimate_com": a[:, 7:9],
                                "estimate_vel": a[:, 9:11], "plan_com": a[:, 11:13], "plan_vel": a[:, 13:15]})

    # --- each tick ---------------------------------------------------------------------------
    def _note_dropped(self, t: float, dropped: tuple[str, ...]) -> None:
        """Count the readings (and the command) not taken this tick, and log each run of them once."""
        for name in dropped:
            self.dropped[name] += 1
            if name not in self._dropping:
                self.events.append((t, f"{name} not finite: not taken (the last one holds)"))
        self._dropping = dropped

    def _estimate(self, m: Measurement, lost: bool = False) -> None:
        """One estimator tick from the encoders, the IMU and the sole forces. A tick whose encoders
        or IMU were dropped (``lost``: not finite) predicts from the model alone; one that never
        had them (a controller run without sensing) leaves the estimator as it is."""
        if m.gyro is not None:
            self.shaper.gyro_z = float(m.gyro[2])
        if m.q is None or m.imu_rpy is None:
            if lost:
                cop = self._cop(m)
                self.estimator.update(self.zmp if cop is None else cop, None)
            return
        roll, pitch = float(m.imu_rpy[0]), float(m.imu_rpy[1])
        a = self.dt / (self.params.tilt_filter + self.dt)
        self.tilt = self.tilt + a * (np.array([roll, pitch - self.gait.p.torso_pitch]) - self.tilt)
        measured, measured_vel = self._kinematic_com(m)
        cop = self._cop(m)
        self.estimator.update(self.zmp if cop is None else cop, measured, measured_vel)

    def _kinematic_com(self, m: Measurement) -> tuple[np.ndarray, np.ndarray | None]:
        """The CoM (x, y) in the engine's world from the support leg's encoders turned by the IMU's
        tilt, its sole standing where it was planned (both legs averaged while standing), and, with
        ``kf_velocity`` > 0 and the rates read, its velocity (x, y): the trunk's turn (the gyro, in
        the trunk's axes) about the sole plus the leg's joint rates through the chain (its Jacobian
        by a difference along dq), not in a step's first ``lag``; ours."""
        q = m.in_our_order(m.q)
        roll, pitch = float(m.imu_rpy[0]), float(m.imu_rpy[1])
        walking = self.cur is not None and self.mode == WALK
        sides = (self.cur.side,) if walking else (1, -1)
        # Not in a step's first `lag`: the new stance leg's encoders still turn with the landing
        # swing (measured on a 0.3 m/s carpet4 walk: -0.14 m/s read in the first 20 ms where the
        # CoM moved at +0.20 m/s, a quarter of the walk's speed lost on the mean; ours).
        rates = (self.params.kf_velocity > 0.0 and m.dq is not None and m.gyro is not None
                 and not (walking and self.t - self.step_t0 < self.params.lag))
        dq = m.in_our_order(m.dq) if rates else None
        # in plain floats (numpy's per-call cost dominates 3-vectors; this runs every tick)
        cx, cy, cz = (float(v) for v in self.leg.com_in_pelvis)
        gyro = None if not rates else tuple(float(v) for v in m.gyro)
        ex = ey = vx = vy = 0.0
        for side in sides:
            leg_q = q[_LEG[side]]
            (px, py, pz), R_ps = sole_floats(leg_q, self.leg, side)
            foot = self.feet[side]
            psi = float(foot[2]) - math.atan2(R_ps[3], R_ps[0])
            w00, w01, w02, w10, w11, w12, w20, w21, w22 = _rot_zyx(math.cos(psi), math.sin(psi), pitch, roll)
            dx, dy, dz = cx - px, cy - py, cz - pz
            ax, ay = w00 * dx + w01 * dy + w02 * dz, w10 * dx + w11 * dy + w12 * dz
            sx, sy = self._sole_xy(foot, side)
            ex, ey = ex + sx + ax, ey + sy + ay
            if rates:
                az = w20 * dx + w21 * dy + w22 * dz
                mx, my, mz = sole_rate(leg_q, dq[_LEG[side]], self.leg, side, (px, py, pz))
                g0, g1, g2 = gyro
                ox, oy, oz = w00 * g0 + w01 * g1 + w02 * g2, w10 * g0 + w11 * g1 + w12 * g2, w20 * g0 + w21 * g1 + w22 * g2
                vx += (oy * az - oz * ay) - (w00 * mx + w01 * my + w02 * mz)
                vy += (oz * ax - ox * az) - (w10 * mx + w11 * my + w12 * mz)
        n = len(sides)
        return np.array((ex / n, ey / n)), (np.array((vx / n, vy / n)) if rates else None)

    def _cop(self, m: Measurement) -> np.ndarray | None:
        if m.foot_force is None:
            return None
        f = [max(float(v), 0.0) for v in m.foot_force]      # plain floats: this runs every tick
        total = ((f[0] + f[1]) + (f[2] + f[3])) + ((f[4] + f[5]) + (f[6] + f[7]))
        if total < 0.1 * self.weight:
            return None
        x = y = 0.0
        for side, block in ((1, f[:4]), (-1, f[4:])):
            pose = self._foot_now(side)
            px, py, yaw = float(pose[0]), float(pose[1]), float(pose[2])
            c, s = math.cos(yaw), math.sin(yaw)
            for fi, (sx, sy) in zip(block, self._sensor_xy):     # each sensor turned by the foot's yaw
                x += fi * (px + (sx * c - sy * s))
                y += fi * (py + (sx * s + sy * c))
        return np.array((x / total, y / total))

    def _foot_now(self, side: int) -> np.ndarray:
        st = self.cur
        if st is None or self.mode != WALK or side == st.side:
            return self.feet[side]
        return self._swing_pose(self.t - self.step_t0)[0]

    # --- the plan --------------------------------------------------------------------------
    def _disturbance(self) -> tuple[np.ndarray, np.ndarray]:
        """(position, velocity) (2,) each of the estimated CoM beyond what the plan predicts: the
        estimate less the plan ``lag`` ago, less the slow mean of that difference (the model's
        and the servos' systematic share, learnt while walking undisturbed)."""
        n = int(round(self.params.lag / self.dt))
        com, vel = self._history[-1 - n] if len(self._history) > n else (self.com, self.vel)
        e = np.concatenate([self.estimator.position - com, self.estimator.velocity - vel]) - self._bias
        return e[:2], e[2:]

    def _dcm_error(self) -> np.ndarray:
        dx, dv = self._disturbance()
        return dx + self.gait.Tc * dv

    def _learn_bias(self) -> None:
        """The slow mean of the error (not while it is large: a push is not model error)."""
        dx, dv = self._disturbance()
        if float(np.linalg.norm(dx + self.gait.Tc * dv)) < self.params.replan_error:
            self._bias = self._bias + (self.dt / self.params.bias_time) * np.concatenate([dx, dv])

    def _blended(self) -> tuple[np.ndarray, np.ndarray]:
        e = self.params
        dx, dv = self._disturbance()
        return self.com + e.k_pos * dx, self.vel + e.k_vel * dv

    def _take_blended(self) -> None:
        """The plan takes the blended state (a re-plan), and the plan's last ``lag`` of ticks the same
        correction: the disturbance is the estimate less the plan ``lag`` ago, so without it a second
        re-plan within ``lag`` would count the first one's share of the push again (with
        ``replan_interval`` below ``lag``: re-planning every tick took the grass30 challenge from
        0.95 to 0.70 m, median of nine push seeds; ours)."""
        com, vel = self._blended()
        dc, dv = com - self.com, vel - self.vel
        n = int(round(self.params.lag / self.dt))
        for i in range(max(0, len(self._history) - n - 1), len(self._history)):
            c, v = self._history[i]
            self._history[i] = (c + dc, v + dv)
        self.com, self.vel = com, vel

    def _advance(self, m: Measurement) -> None:
        """Move the plan on to time ``self.t`` (the targets' time): stand, shift, steps, stop. The
        plan's CoM state (``com``, ``vel``) is always that of local time ``state_tau`` of the
        current phase, carried exactly across a step that ends between two ticks."""
        e, dt = self.params, self.dt
        t = self.t
        walking_wanted = bool(np.any(np.abs(self.asked) > 1e-6)) or e.idle == "step"
        if self.mode == STAND:
            if walking_wanted and t - dt >= e.t_stand - e.shift_time - 1e-9:
                self._start_shift(t - dt)               # from the state of now: the first step at t_stand
            else:
                self._hold()
                return
        if self.mode == SHIFT:
            end = self.step_t0 + e.shift_time
            self._follow(min(t, end) - self.step_t0)
            if t < end - 1e-9:
                return
            self._begin_step(end, first=True)
        st = self.cur
        while t >= self.step_t0 + st.T - 1e-9:
            self._follow(st.T)
            self._end_step()
            if self.mode == STAND:
                self._hold()
                return
            st = self.cur
        tau = t - self.step_t0
        self._follow(tau)
        # early touchdown: the descending swing foot carries weight
        if (not st.landed and st.t1 < tau < st.t2 and self._theta(tau) > math.pi and m.foot_force is not None):
            block = m.foot_force[:4] if st.side == -1 else m.foot_force[4:]
            if float(np.sum(block)) > e.touchdown_force * self.weight:
                self._touch_down(tau)
                return
        # a push: re-plan the rest of the step from the blended state
        err = float(np.linalg.norm(self._dcm_error()))
        if (err > e.replan_error and not st.landed and tau < st.t2 - 2 * dt
                and t - self.last_replan >= e.replan_interval - 1e-9):
            self._replan(tau)

    def _hold(self) -> None:
        """Standing: the ZMP drives the plan's capture point to between the feet,
        p = xi + (T_c / ``stand_time``) (xi - mid), within the feet (a fixed ZMP would let any
        leftover error diverge: x350 in a second for T_c = 0.17 s)."""
        g = self.gait
        mid = (self.feet[1][:2] + self.feet[-1][:2]) / 2
        xi = self.com + g.Tc * self.vel
        p = xi + (g.Tc / self.params.stand_time) * (xi - mid)
        lo = np.minimum(self.feet[1][:2], self.feet[-1][:2]) - np.array(self.foot_size) / 2
        hi = np.maximum(self.feet[1][:2], self.feet[-1][:2]) + np.array(self.foot_size) / 2
        self.zmp = np.clip(p, lo, hi)
        self.com, self.vel = propagate(self.com, self.vel, 0.0, self.dt, np.array([0.0, 1.0]),
                                       np.array([self.zmp, self.zmp]), np.zeros(2), g.Tc)

    def _start_shift(self, t0: float) -> None:
        """The weight shift before the first step: ZMP from between the feet to a point solved so
        that the DCM reaches what the first step needs (2 x 2, affine in that point)."""
        e, g = self.params, self.gait
        self.mode = SHIFT
        self.step_t0 = t0
        self.state_tau = 0.0
        side = -self.next_side                       # the first support foot
        support = self.feet[side]
        mid = (self.feet[1][:2] + self.feet[-1][:2]) / 2
        x, v = self._blended()
        xi0 = x + g.Tc * v
        kt = np.array([0.0, e.shift_time])

        def residual(P: np.ndarray) -> np.ndarray:
            xi_end = dcm_forward(xi0, 0.0, e.shift_time, kt, np.array([mid, P]), np.zeros(2), g.Tc)
            return xi_end - g.required_dcm(support, side, P, self.command, e.preview_steps)
        r0 = residual(mid)
        J = np.column_stack([residual(mid + d) - r0 for d in (np.array([0.01, 0.0]), np.array([0.0, 0.01]))]) / 0.01
        P = mid + np.linalg.solve(J, -r0)
        lo = np.minimum(self.feet[1][:2], self.feet[-1][:2]) - np.array(self.foot_size) / 2
        hi = np.maximum(self.feet[1][:2], self.feet[-1][:2]) + np.array(self.foot_size) / 2
        self._shift = (kt, np.array([mid, np.clip(P, lo, hi)]))
        self.com, self.vel = x, v

    def _begin_step(self, t0: float, first: bool = False) -> None:
        p = self.gait.p
        side = -self.next_side
        support = self.feet[side].copy()
        p0 = self._shift[1][-1] if first else self._boundary
        st = Step(side, support, self.feet[-side].copy(), support.copy(), np.array(p0, dtype=float),
                  p.t1, p.t2, p.period, self.command.copy())
        self.mode = WALK
        self.cur = st
        self.step_t0 = t0
        self.state_tau = 0.0
        st.pose_a = st.swing_from.copy()
        st.tau_a = p.t1
        st.theta_a = 0.0
        st.offset = np.zeros(2)
        if not first and float(np.linalg.norm(self._dcm_error())) > self.params.replan_error:
            self._take_blended()
        self._plan_rest(0.0, swing_pose=None)
        self.step_starts.append(t0)
        self.events.append((t0, f"step {self.steps_taken} on the {'left' if side == 1 else 'right'} foot to "
                                f"{st.target[0]:.3f},{st.target[1]:.3f} in {st.T:.2f} s"))

    def _plan_rest(self, tau: float, swing_pose: np.ndarray | None) -> dict:
        """Adjust the step's target, timing and ZMP offset from its state at ``tau``; rebuild its ZMP.
        Returns :func:`adjust_step`'s info."""
        g, st = self.gait, self.cur
        xi = self.com + g.Tc * self.vel
        n = 0 if self._stopping() else self.params.preview_steps
        target, lam, offset, info = adjust_step(g, st, tau, xi, self.command, n,
                                                swing_pose, self.params, self.dt, fixed_target=st.landed)
        if not info.get("kept"):
            p = g.p
            if not st.landed:
                st.t2 = p.t1 + lam * (p.t2 - p.t1)
                st.T = st.t2 + (p.period - p.t2)
                st.target = target
            st.offset = offset
        self.last_residual = info.get("residual", float("nan"))
        st.knots_t, st.knots_p, st.shift = g.knots(st.support, st.p0, st.target, st.t1, st.t2, st.T, st.offset)
        self.zmp = zmp_at(st.knots_t, st.knots_p, tau)
        return info

    def _stopping(self) -> bool:
        """This step ends the walk: nothing is asked, the command has ramped down, the engine stands
        at a zero command, and the feet will stand side by side (the planner's zero step)."""
        idle = self.params.idle == "stand" and not np.any(np.abs(self.asked) > 1e-6) \
            and not np.any(np.abs(self.command) > 1e-6)
        if not idle:
            return False
        st = self.cur
        return abs(relative(st.support, st.swing_from)[2]) < 1e-3

    def _replan(self, tau: float) -> None:
        st = self.cur
        self.replans += 1
        self.last_replan = self.t
        self.events.append((self.t, f"re-plan at tau {tau:.2f} s, capture-point error "
                                    f"{float(np.linalg.norm(self._dcm_error())) * 1000:.0f} mm"))
        self._take_blended()
        if tau > st.t1:                               # re-target the swing from where the foot is
            pose, theta = self._swing_pose(tau)
            st.pose_a, st.tau_a, st.theta_a = pose[:3], tau, theta
            info = self._plan_rest(tau, swing_pose=pose)
        else:
            info = self._plan_rest(tau, swing_pose=None)
        self.binding["replans"] += 1
        for name in info["binds"]:
            self.binding[name] += 1

    def _touch_down(self, tau: float) -> None:
        """An early touch-down: the swing foot stays where it touched (it only comes down the rest of
        the way, by the plan's t2) and the ZMP's last segment aims from there. The step keeps its
        timing: a shorter step would leave the capture point where the next step cannot catch it
        (an error at a step's start grows by e^{T / T_c} by its end: 40x for a 0.64 s step)."""
        st = self.cur
        pose, theta = self._swing_pose(tau)
        self.touchdowns += 1
        self.events.append((self.t, f"early touch-down at tau {tau:.2f} s (planned {st.t2:.2f} s)"))
        st.target = pose[:3].copy()
        st.pose_a, st.tau_a, st.theta_a = pose[:3].copy(), tau, theta
        st.landed = True
        self._plan_rest(tau, swing_pose=None)            # the ZMP offset absorbs where it landed

    def _end_step(self) -> None:
        st = self.cur
        e = self.params
        self.feet[-st.side] = st.target.copy()
        self._boundary = st.knots_p[-1].copy()
        self.steps_taken += 1
        self.next_side = st.side                      # the support foot swings next
        t_end = self.step_t0 + st.T
        together = abs(relative(self.feet[st.side], self.feet[-st.side])[0]) < 1e-3
        idle = not np.any(np.abs(self.command) > 1e-6) and not np.any(np.abs(self.asked) > 1e-6) \
            and e.idle == "stand"
        mid = (self.feet[1][:2] + self.feet[-1][:2]) / 2
        at_rest = float(np.linalg.norm(self.com + self.gait.Tc * self.vel - mid)) < e.stop_error
        if idle and together and at_rest and float(np.linalg.norm(self._dcm_error())) < e.replan_error:
            self.mode = STAND
            self.cur = None
            return
        self._begin_step(t_end)

    def _follow(self, tau: float) -> None:
        """The plan's CoM state and ZMP carried (closed form) from ``state_tau`` to local time ``tau``."""
        g = self.gait
        if self.mode == SHIFT:
            kt, kp = self._shift
            sh = np.zeros(2)
        else:
            kt, kp, sh = self.cur.knots_t, self.cur.knots_p, self.cur.shift
        if tau > self.state_tau:
            self.com, self.vel = propagate(self.com, self.vel, self.state_tau, tau, kt, kp, sh, g.Tc)
            self.state_tau = tau
        self.zmp = zmp_at(kt, kp, tau)

    def _load_offsets(self, q: np.ndarray, support: int, feet: dict) -> np.ndarray:
        """What the servos will give way by under this tick's load and moves, to add to ``q``
        (``servo_load.py``), the pelvis turned as planned."""
        R_wp = np.array(self._plan_rotation).reshape(3, 3)      # this tick's, from _joints
        return self._load.offsets(q, feet, self._soles, self.zmp, support, self._robot_weight, R_wp,
                                  self.foot_size)

    def _sole_point(self, foot: np.ndarray, side: int) -> np.ndarray:
        """The sole point (the chain's, ``ankle_height`` below the ankle) in the world, from the sole
        centre's (x, y, yaw[, z])."""
        x, y = self._sole_xy(foot, side)
        return np.array((x, y, (float(foot[3]) if len(foot) > 3 else 0.0) - self._sole_offsets[side][2]))

    def _sole_xy(self, foot, side: int) -> tuple[float, float]:
        """:meth:`_sole_point`'s (x, y) in plain floats."""
        ox, oy, _ = self._sole_offsets[side]
        yaw = float(foot[2])
        c, s = math.cos(yaw), math.sin(yaw)
        return float(foot[0]) - (c * ox - s * oy), float(foot[1]) - (s * ox + c * oy)

    # --- the swing and the joints ----------------------------------------------------------
    def _theta(self, tau: float) -> float:
        st = self.cur
        if tau <= st.tau_a:
            return st.theta_a if tau >= st.t1 else 0.0
        if tau >= st.t2:
            return 2 * math.pi
        return st.theta_a + (2 * math.pi - st.theta_a) * (tau - st.tau_a) / (st.t2 - st.tau_a)

    def _swing_pose(self, tau: float) -> tuple[np.ndarray, float]:
        """The swing foot (x, y, yaw, z) at local time ``tau`` and its cycloid phase (eq 27)."""
        st, p = self.cur, self.gait.p
        theta = self._theta(tau)
        fa = float(swing_fraction(st.theta_a))
        f = (float(swing_fraction(theta)) - fa) / (1.0 - fa) if fa < 1.0 else 1.0
        pose = st.pose_a + f * (st.target - st.pose_a)
        bulge = p.w_y * (-st.side) * (1.0 - math.cos(theta)) / 2.0
        c, s = math.sin(st.support[2]), math.cos(st.support[2])
        z = (1.0 - math.cos(theta)) * p.h_z / 2.0
        return np.array([pose[0] - c * bulge, pose[1] + s * bulge, pose[2], z]), theta

    def _targets(self) -> tuple[np.ndarray, int, dict]:
        feet = {1: np.append(self.feet[1], 0.0), -1: np.append(self.feet[-1], 0.0)}
        support = 0
        if self.mode == WALK:
            st = self.cur
            tau = self.t - self.step_t0
            if st.t1 < tau < st.t2:
                support = 0 if st.landed else st.side
                feet[-st.side] = self._swing_pose(tau)[0]
            elif tau >= st.t2:
                feet[-st.side] = np.append(st.target, 0.0)
        q = self._joints(self.com, feet[1], feet[-1], swing=-support if support else 0, tick=True)
        return q[0], support, feet

    def _joints(self, com: np.ndarray, left: np.ndarray, right: np.ndarray, swing: int = 0,
                tick: bool = False) -> np.ndarray:
        """Leg IK for the CoM (x, y) at z_c and the soles (x, y, yaw[, z]) -> (1, 20) targets.

        What ``trajectory.assemble`` does for a table (the pelvis moved by the robot's CoM offset,
        each ankle by its sole offset, the pelvis heading the mean of the feet's, leaned forward
        by ``torso_pitch``, the soles flat on the ground), with the closed-form IK
        (``leg_kinematics.leg_ik_pose``) for one sample. The swing leg (``swing`` = its side) takes
        ``level_feet`` of the measured tilt out, so its sole lands level in the world; the support
        leg keeps the plan's upright pelvis (its targets are what pushes a tilted trunk back)."""
        p, leg = self.gait.p, self.leg
        # in plain floats (numpy's per-call cost dominates 3 x 3 products; this runs every tick)
        psi = (float(left[2]) + float(right[2])) / 2
        cw, sw = math.cos(psi), math.sin(psi)
        self._plan_rotation = R_plan = _rot_zyx(cw, sw, p.torso_pitch, 0.0)   # _load_offsets takes it too
        k = self.params.level_feet
        R_tilted = _rot_zyx(cw, sw, p.torso_pitch + k * float(self.tilt[1]), k * float(self.tilt[0])) if k else R_plan
        cf, cl = leg.com_forward, leg.com_lateral
        pelvis = (float(com[0]) - (cw * cf - sw * cl), float(com[1]) - (sw * cf + cw * cl), p.z_c - leg.com_above_pelvis)
        q = np.zeros((1, len(JOINT_NAMES)))
        for side, foot in ((1, left), (-1, right)):
            w00, w01, w02, w10, w11, w12, w20, w21, w22 = R_tilted if side == swing else R_plan
            yaw = float(foot[2])
            cy, sy = math.cos(yaw), math.sin(yaw)
            self._soles[side] = sole_point = self._sole_point(foot, side)
            dx, dy, dz = (float(v) - o for v, o in zip(sole_point, pelvis))
            # R_wp^T (sole - pelvis) and R_wp^T Rz(yaw)
            target = np.array((w00 * dx + w10 * dy + w20 * dz, w01 * dx + w11 * dy + w21 * dz,
                               w02 * dx + w12 * dy + w22 * dz))
            R_ps = np.array(((w00 * cy + w10 * sy, w10 * cy - w00 * sy, w20),
                             (w01 * cy + w11 * sy, w11 * cy - w01 * sy, w21),
                             (w02 * cy + w12 * sy, w12 * cy - w02 * sy, w22)))
            target = self._reachable(target, R_ps, side)
            try:                                        # the numerical IK starts from the last ticks'
                q[0, _LEG[side]] = leg_ik_pose(target, R_ps, leg, side, self._ik_start(side), IK_TOL, IK_STEP)
            except UnreachableTargetError as exc:
                best = getattr(exc, "best", None)      # the numerical IK's closest pose (gaits.leg_chain)
                if best is None:
                    raise
                self.clamped += 1
                q[0, _LEG[side]] = best
            if tick and leg.chains is not None:
                self._ik_seen[side] = (self._ik_seen[side][1], q[0, _LEG[side]].copy())
        return q

    def _ik_start(self, side: int) -> np.ndarray | None:
        """Where the numerical leg IK starts this tick: the last two ticks' answers carried on a tick
        (2 q[k-1] - q[k-2]: the targets move smoothly, so the first Newton step is shorter: Wolfgang-OP's
        forward walk of benchmarks/bench_tick.py evaluates a leg 2.1 times a tick instead of 2.5, counted
        under cProfile; the built-in robot's legs as chains 2.0 instead of 2.2, tests/test_leg_chain.py),
        else the last targets sent (ours). The closed-form IK takes none."""
        if self.leg.chains is None:
            return None
        before, last = self._ik_seen[side]
        if last is not None and before is not None:
            return 2.0 * last - before
        return None if self._last_q is None else self._last_q[_LEG[side]]

    def _reachable(self, target: np.ndarray, R_ps: np.ndarray, side: int) -> np.ndarray:
        """The sole target moved toward the hip until the leg reaches it (a plan that runs away, a
        fall: the engine's targets stay a pose the leg can take, the robot falls as it would)."""
        leg = self.leg
        ah = leg.ankle_height
        zx, zy, zz = float(R_ps[0, 2]) * ah, float(R_ps[1, 2]) * ah, float(R_ps[2, 2]) * ah
        hx, hy, hz = leg.hip_offset_x, side * leg.hip_offset_y, -leg.hip_offset_z
        tx, ty, tz = target.tolist()
        dx, dy, dz = tx + zx - hx, ty + zy - hy, tz + zz - hz
        n = math.sqrt(dx * dx + dy * dy + dz * dz)
        reach = 0.999 * (leg.thigh + leg.shank)
        if n <= reach:
            return target
        self.clamped += 1
        f = reach / n
        return np.array((hx + dx * f - zx, hy + dy * f - zy, hz + dz * f - zz))


def joint_speeds(robot) -> np.ndarray | None:
    """Each of our joints' servo speed [rad/s] (``JOINT_NAMES`` order; inf for a joint the robot
    lacks) from a robot file (``joints``: each with ``speed``) or a simulator's robot (``joint_map``
    and ``servos`` by its own joint names); None when the robot states no servos."""
    out = np.full(len(JOINT_NAMES), np.inf)
    joints = getattr(robot, "joints", None)
    if hasattr(joints, "items") and joints and hasattr(next(iter(joints.values())), "speed"):
        for ours, j in joints.items():
            out[JOINT_NAMES.index(ours)] = float(j.speed)
        return out
    jmap, servos = getattr(robot, "joint_map", None), getattr(robot, "servos", None)
    if not jmap or not servos:
        return None
    for ours, (theirs, _) in jmap.items():
        if theirs in servos:
            out[JOINT_NAMES.index(ours)] = float(servos[theirs].speed)
    return out
