"""The online walk engine (ours): TLIPFM's natural-ZMP walk, planned step by step from what the robot
senses, for a walk command that may change at any tick.

It is a :class:`gaits.control.Controller` in pure numpy, so it runs in the simulator's loop and on
a robot (``examples/robot_loop.py``). Every control tick it takes the current command (vx, vy, wz),
rate-limits it (``accel_*``) and clips it to its envelope (:meth:`WalkEngine.envelope`), reads the
encoders, IMU and sole forces, and returns the 20 joint targets of the next tick.

Per step (ours unless named):

* **footsteps** from the *current* command only: the planner rule of ``gaits/footstep_planner.py``
  for this step and ``preview_steps`` more, the command held (no future command is known); slow
  steps may land wider than the gait's ``half_width`` (``stance_widen``, fading out by
  ``stance_speed``: a wider base against pushes from the side while stepping in place);
* the **natural ZMP** of the TLIPFM paper (eqs 10-11, the three segments 0, t1, t2, T with d1, d2,
  a) along them, and the **CoM in closed form** (eqs 23-26; ``gaits/lipm.py``) from a state that
  blends the plan's with the *estimated* one (``k_pos``, ``k_vel``: 0 is the open-loop plan, 1 a
  re-plan from the estimate alone);
* **step adjustment**: the next footstep's place u (in the support foot's frame) and the swing's
  duration (its single support scaled by lambda in [``min_ssp_scale``, 1]) are chosen so that the
  capture point (DCM) at the step's end is the one the following steps need:
  r(u, lambda) = xi_end(u, lambda) - xi_req(u) is affine in u (both sides are closed-form LIPM
  passes: xi_end's columns are the pass's linear weights, ``lipm.dcm_forward_weights``; xi_req's
  follow from one backward pass and a closed-form weight, since moving the footstep moves every
  later ZMP point with it but one, the next step's first), so for each of five lambdas the engine
  solves the box QP
  min |r|^2 + ``step_weight`` |u - u_nominal|^2 over the reach box (forward, backward, outward
  reach; the inward bound keeps the soles ``min_gap`` apart) exactly (``lipm.solve_box_qp``),
  drops lambdas whose re-targeted swing would exceed ``foot_speed`` (the servos' speed), and
  takes the lambda of least cost + ``timing_weight`` (1 - lambda)^2 (a lambda whose timing term
  alone exceeds the best cost found is not solved: it cannot win). With the estimated state equal
  to the plan, u is the planner's own footstep and lambda = 1: the walk is the table's;
* a step is **re-planned in swing** when the DCM error passes ``replan_error`` (a push), and the
  **cycloid swing** (eq 27) is re-targeted from where the foot is;
* **phase reset**: a swing foot that touches down early (its sole forces pass ``touchdown_force``
  of the robot's weight while it descends) lands there and then;
* the start: a weight shift over ``shift_time`` whose ZMP end point is solved so that the DCM
  reaches what the first step needs; the stop: with a zero command (and ``idle: stand``) the
  feet come together, the ZMP returns between them and the robot stands.

The **estimator**: the CoM from the support leg's forward kinematics (encoders) turned by the
IMU's tilt, as a measurement of a Kalman filter whose model is the same LIPM driven by the
measured centre of pressure of the sole forces (``kf_accel``, ``kf_position``: its process and
measurement noise), and with ``kf_velocity`` > 0 the CoM's velocity measured too, from the gyro and
the encoders' rates (a push shows in it at once, where the position shows it only as it builds
up; not read in a step's first ``lag``, while the landing leg still turns with the swing). The
support foot is taken to stand where it was planned (no slip): the engine's world is its own
odometry, starting at the robot's start pose.

Which family does what (``gaits.family(...).engine``): TLIPFM has this engine and its state
feedback; EROS and the cosine law walk online commands through their own tables re-planned at
each step (``gaits/online_table.py``: no state feedback; of the engine section they use
``preview_steps`` and ``idle``). The IMU stabiliser (``gaits/imu_stabiliser.py``) is applied
inside the step when the gait file has one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .control import READINGS, Measurement, PlanRecord, StartPose, finite_readings
from .footstep_planner import StepLimits, compose, relative, swing_fraction
from .leg_kinematics import LegGeometry, leg_ik_pose
from .lipm import dcm_backward, dcm_forward, dcm_forward_weights, propagate, solve_box_qp, zmp_at
from .params import GaitParams, ParamError, param
from .tlipfm import TlipfmParams, pendulum_constants
from .trajectory import GRAVITY, JOINT_NAMES

__all__ = ["EngineParams", "WalkEngine", "CoMEstimator", "Step", "adjust_step"]


@dataclass(frozen=True)
class EngineParams(GaitParams):
    """The walk engine's own numbers (ours; the gait's come from its TLIPFM set), SI units."""

    FAMILY = "engine"
    t_stand: float = param(1.0, "s", 0.0, 10.0, "standing before the first step may start")
    shift_time: float = param(0.4, "s", 0.1, 2.0, "weight shift onto the first support foot")
    preview_steps: int = param(3, "-", 1, 8, "steps planned ahead with the current command")
    accel_vx: float = param(0.6, "m/s^2", 0.05, 20.0, "largest change of the forward command per second")
    accel_vy: float = param(0.4, "m/s^2", 0.05, 20.0, "largest change of the sideways command per second")
    accel_wz: float = param(2.0, "rad/s^2", 0.1, 50.0, "largest change of the turning command per second")
    k_pos: float = param(0.0, "-", 0.0, 1.0, "share of the estimated CoM position in a re-plan")
    k_vel: float = param(0.8, "-", 0.0, 1.0, "share of the estimated CoM velocity in a re-plan")
    step_weight: float = param(0.05, "-", 0.0, 100.0, "cost of moving a footstep from the planner's, "
                               "against the capture point's mismatch")
    zmp_weight: float = param(0.05, "-", 0.0, 100.0, "cost of moving the ZMP on the sole, against the "
                              "capture point's mismatch")
    zmp_margin: float = param(0.01, "m", 0.0, 0.05, "how far inside the sole's edge the ZMP stays")
    timing_weight: float = param(0.001, "m^2", 0.0, 10.0, "cost of a shorter swing: (1 - lambda)^2 times this")
    min_ssp_scale: float = param(0.6, "-", 0.3, 1.0, "shortest single support, of the nominal")
    replan_error: float = param(0.06, "m", 0.001, 10.0, "capture-point error (beyond the plan and its slow "
                                "mean) that re-plans the step: a push")
    replan_interval: float = param(0.05, "s", 0.0, 1.0, "least time between two re-plans of a step")
    touchdown_force: float = param(0.3, "-", 0.05, 1.0, "sole force, of the robot's weight, that lands "
                                   "a descending swing foot early")
    lag: float = param(0.03, "s", 0.0, 0.2, "estimator: how far the measured CoM lags the plan (servo lag, "
                       "latency): the estimate is compared with the plan this long ago")
    bias_time: float = param(0.5, "s", 0.05, 20.0, "estimator: time constant of the slow mean of the capture-"
                             "point error that is taken as model error, not disturbance")
    kf_accel: float = param(1.0, "m/s^2", 0.01, 100.0, "estimator: process noise of the CoM acceleration")
    kf_position: float = param(0.008, "m", 1e-4, 0.1, "estimator: noise of the kinematic CoM")
    kf_velocity: float = param(0.0, "m/s", 0.0, 1.0, "estimator: noise of the kinematic CoM velocity (the "
                               "encoders' rates and the gyro; ours); 0: the velocity is not measured")
    foot_speed: float = param(1.2, "m/s", 0.1, 10.0, "fastest swing foot the servos carry (a re-targeted "
                              "swing may not need more)")
    level_feet: float = param(1.0, "-", 0.0, 1.0, "share of the measured torso tilt the legs' IK takes out, "
                              "keeping the soles level in the world (0: the plan's upright pelvis)")
    tilt_filter: float = param(0.03, "s", 0.0, 1.0, "time constant of the tilt the IK uses")
    yaw_feedback: float = param(0.0, "1/s", 0.0, 20.0, "how fast the planned turn makes up the gyro's "
                                "measured shortfall of the commanded turning rate (ours; 0: none)")
    yaw_hold: float = param(0.0, "rad/s", 0.0, 1.0, "with yaw_feedback: the largest turn its correction may "
                            "plan while walking with no turn asked, holding the heading (ours; 0: none)")
    stride_forward: float = param(1.0, "-", 0.5, 1.5, "the steps are planned for the forward command times "
                                  "this (ours: the walk's odometry calibrated per surface; < 1 where the "
                                  "feet slide on, > 1 where the walk falls short)")
    stride_backward: float = param(1.0, "-", 0.5, 1.5, "the same for a backward command")
    stride_sideways: float = param(1.0, "-", 0.5, 1.5, "the same for a sideways command")
    stride_turn: float = param(1.0, "-", 0.5, 1.5, "the same for a turning command")
    idle: str = param("stand", "-", doc="at a zero command: stand, or step in place",
                      choices=("stand", "step"))
    stance_widen: float = param(0.0, "m", 0.0, 0.03, "slow steps land this much wider on each side than "
                                "the gait's half_width, less as the command grows (ours: a wider stance "
                                "for pushes from the side while stepping slowly or in place)")
    stance_speed: float = param(0.1, "m/s", 0.01, 1.0, "the command at which the widening is gone: the "
                                "larger of |vx|, |vy| and |wz| times the feet's distance (2 half_width)")
    stop_error: float = param(0.005, "m", 0.0005, 0.05, "the plan stops stepping when its capture point is "
                              "this close to between the feet")
    stand_time: float = param(0.2, "s", 0.02, 5.0, "standing: time constant of the capture point's return "
                              "to between the feet")

    def check_consistency(self) -> None:
        if self.shift_time > self.t_stand + 1e-12 and self.t_stand > 0:
            raise ParamError(f"engine: shift_time = {self.shift_time:g} s must fit in t_stand = "
                             f"{self.t_stand:g} s (the shift happens while standing)")


# --- the estimator ----------------------------------------------------------------------------

def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def sole_in_pelvis(q: np.ndarray, leg: LegGeometry, side: int) -> tuple[np.ndarray, np.ndarray]:
    """The leg's forward kinematics for one sample (``leg_kinematics.leg_fk``'s chain, scalar and
    fast): the point ``ankle_height`` below the ankle, and the sole's rotation, in the pelvis frame."""
    q1, q2, q3, q4, q5, q6 = (float(v) for v in q)
    R = _rz(q1) @ _rx(q2) @ _ry(q3)
    p = leg.hip_in_pelvis(side) + R @ np.array([0.0, 0.0, -leg.thigh])
    R = R @ _ry(q4)
    p = p + R @ np.array([0.0, 0.0, -leg.shank])
    R = R @ _ry(q5) @ _rx(q6)
    p = p + R @ np.array([0.0, 0.0, -leg.ankle_height])
    return p, R


class CoMEstimator:
    """The CoM's horizontal position and velocity in the engine's world (module docstring).

    A Kalman filter per axis on x'' = (x - p) / T_c^2 (exact over a tick for p held), p the measured
    centre of pressure (the plan's ZMP when the soles carry less than a tenth of the weight),
    measured by the kinematic CoM and, with ``velocity_noise`` > 0, by its velocity too (ours: a
    push is a force the model does not know, and the position alone shows it only as the
    model's velocity drifts after it: measured on the grass30 challenge at D 1.0 m, the estimate
    held 0.05 m/s of a 0.30 m/s push 60 ms after the impact, 0.18 at 160 ms). Both axes share one
    covariance (the same noise on each).
    """

    def __init__(self, Tc: float, dt: float, accel_noise: float, position_noise: float,
                 velocity_noise: float = 0.0) -> None:
        c, s = math.cosh(dt / Tc), math.sinh(dt / Tc)
        self.A = np.array([[c, Tc * s], [s / Tc, c]])
        self.B = np.array([1.0 - c, -s / Tc])                # times p
        G = np.array([0.5 * dt * dt, dt])
        self.Q = np.outer(G, G) * accel_noise ** 2
        self.R = position_noise ** 2
        self.R_v = velocity_noise ** 2
        self.x = np.zeros((2, 2))                            # rows: position, velocity; columns: axes
        self.P = np.diag([position_noise ** 2, 0.01])

    def reset(self, c: np.ndarray) -> None:
        self.x = np.array([c, [0.0, 0.0]], dtype=float)
        self.P = np.diag([self.R, 1e-4])

    def update(self, p: np.ndarray, measured: np.ndarray | None, measured_vel: np.ndarray | None = None) -> None:
        """Predict one tick with the ZMP ``p`` (2,), then correct with the kinematic CoM (2,) and,
        when given and the filter has a velocity noise, its velocity (2,); without ``measured``
        (a tick whose readings were dropped) the prediction only."""
        self.x = self.A @ self.x + np.outer(self.B, p)
        self.P = self.A @ self.P @ self.A.T + self.Q
        if measured is None:
            return
        if measured_vel is None or self.R_v <= 0.0:
            K = self.P[:, 0] / (self.P[0, 0] + self.R)
            self.x = self.x + np.outer(K, measured - self.x[0])
            self.P = self.P - np.outer(K, self.P[0])
            return
        K = self.P @ np.linalg.inv(self.P + np.diag([self.R, self.R_v]))     # H = I: both measured
        self.x = self.x + K @ (np.vstack([measured, measured_vel]) - self.x)
        self.P = self.P - K @ self.P

    @property
    def position(self) -> np.ndarray:
        return self.x[0]

    @property
    def velocity(self) -> np.ndarray:
        return self.x[1]


# --- a step and its adjustment ----------------------------------------------------------------

@dataclass
class Step:
    """One step of the engine's plan (times local to the step, poses (x, y, yaw) in its world)."""

    side: int                    # +1 the left foot supports, -1 the right
    support: np.ndarray          # (3,) support foot pose
    swing_from: np.ndarray       # (3,) where the swing foot lifts off
    target: np.ndarray           # (3,) where it lands
    p0: np.ndarray               # (2,) the ZMP at the step's start (the previous boundary)
    t1: float                    # [s] lift-off
    t2: float                    # [s] touch-down
    T: float                     # [s] the step's end
    command: np.ndarray          # (3,) the command it was planned for
    knots_t: np.ndarray = None   # ZMP profile of the step
    knots_p: np.ndarray = None
    shift: np.ndarray = None     # (2,) the flywheel's ZMP shift
    # the swing, re-targetable: from (tau_a, pose_a, theta_a) to (t2, target)
    tau_a: float = 0.0
    pose_a: np.ndarray = None
    theta_a: float = 0.0
    landed: bool = False
    offset: np.ndarray = None    # (2,) the ZMP's move on the support sole (its frame)


class _Gait:
    """What the engine takes from a TLIPFM set, and the step rules that use it."""

    def __init__(self, p: TlipfmParams, limits: StepLimits, stance_widen: float = 0.0,
                 stance_speed: float = 0.1) -> None:
        if not isinstance(p, TlipfmParams):
            raise ParamError(f"the walk engine plans TLIPFM steps; a {p.FAMILY!r} set has no engine "
                             f"(gaits.family({p.FAMILY!r}).engine)")
        self.p = p
        const = pendulum_constants(p)
        self.Tc = const.T
        self.zmp_shift = const.zmp_shift
        self.limits = limits
        total = p.d1 + p.d2
        self.rho = p.d2 / total if abs(total) > 1e-12 else 0.5
        self.stance_widen, self.stance_speed = float(stance_widen), float(stance_speed)
        # d required_dcm / d p0: a step's first ZMP point enters only the backward pass's first
        # segment (0 to t1; the later steps start from this one's boundary, not from p0), whose
        # forward pass is xi(t1) = a xi(0) + w_0 p0 + w_1 p1, so xi(0) moves by -w_0 / a with p0 (ours)
        a, w, _ = dcm_forward_weights(0.0, p.t1, (0.0, p.t1), self.Tc)
        self.start_weight = float(-w[0] / a)

    def half_width(self, command: np.ndarray) -> float:
        """Half the feet's distance the steps of ``command`` land at [m]: the gait's ``half_width``,
        plus ``stance_widen`` at a zero command, falling linearly to nothing at ``stance_speed`` of
        the larger of |vx|, |vy| and a turn's speed of one foot about the other, |wz| 2 half_width
        (ours)."""
        W = self.p.half_width
        if self.stance_widen <= 0.0:
            return W
        speed = max(abs(float(command[0])), abs(float(command[1])), abs(float(command[2])) * 2.0 * W)
        return W + self.stance_widen * max(0.0, 1.0 - speed / self.stance_speed)

    def nominal_target(self, support: np.ndarray, side: int, command: np.ndarray) -> np.ndarray:
        """The planner's footstep (``footstep_planner.plan_footsteps``' rule) for a held command, the
        feet ``half_width(command)`` from the mid-line."""
        T, W = self.p.period, self.half_width(command)
        s = -side
        vx, vy, wz = command
        mid = compose(support, np.array([0.0, s * W, 0.0]))
        dy = 2.0 * vy * T if s * vy > 0 else 0.0
        dth = 2.0 * wz * T if s * wz > 0 else 0.0
        return compose(compose(compose(mid, np.array([vx * T, dy, 0.0])), np.array([0.0, 0.0, dth])),
                       np.array([0.0, s * W, 0.0]))

    def box(self, side: int, turn: float) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the swing target (x, y) in the support foot's frame: the reach, and an inward
        bound that keeps the soles ``min_gap`` apart (widened by a turned foot's corner)."""
        lim, W = self.limits, self.p.half_width
        s = -side
        inner = lim.sole_width + lim.min_gap + abs(math.sin(turn)) * lim.sole_length / 2
        outer = max(2 * W + lim.max_outward, inner)
        ys = sorted((s * inner, s * outer))
        return np.array([-lim.max_backward, ys[0]]), np.array([lim.max_forward, ys[1]])

    def knots(self, support: np.ndarray, p0: np.ndarray, target: np.ndarray, t1: float, t2: float,
              T: float, offset: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The natural ZMP of a step (``tlipfm.command_zmp_segments``): p0 -> a behind -> a ahead of
        the support foot along its heading -> the boundary toward the next one; and the shift.
        ``offset`` (2,) [m], in the support foot's frame, moves the two points on the support foot
        (the ankle's share of a step adjustment, ours)."""
        c, s = math.cos(support[2]), math.sin(support[2])
        h, lat = np.array([c, s]), np.array([-s, c])
        F = support[:2]
        if offset is not None:
            F = F + offset[0] * h + offset[1] * lat
        nxt = target[:2] - support[:2]
        boundary = support[:2] + self.rho * float(nxt @ h) * h + 0.5 * float(nxt @ lat) * lat
        pts = np.array([p0, F - self.p.a * h, F + self.p.a * h, boundary])
        return np.array([0.0, t1, t2, T]), pts, self.zmp_shift * h

    def zmp_box(self, margin: float) -> tuple[np.ndarray, np.ndarray]:
        """How far the ZMP's points may move on the support sole (its frame), ``margin`` [m] inside."""
        L, Wd = self.limits.sole_length, self.limits.sole_width
        hx = max(L / 2 - abs(self.p.a) - margin, 0.0)
        hy = max(Wd / 2 - margin, 0.0)
        return np.array([-hx, -hy]), np.array([hx, hy])

    def required_dcm(self, support: np.ndarray, side: int, p0: np.ndarray, command: np.ndarray,
                     n: int) -> np.ndarray:
        """The DCM a step starting on ``support`` needs for ``n`` steps of the held command that end
        with the ZMP at their last boundary (a zero command's boundary lies between the feet: rest)."""
        p = self.p
        steps = []
        F, sd, start = support, side, p0
        for _ in range(n):
            B = self.nominal_target(F, sd, command)
            kt, kp, sh = self.knots(F, start, B, p.t1, p.t2, p.period)
            steps.append((kt, kp, sh))
            F, sd, start = B, -sd, kp[-1]
        xi = steps[-1][1][-1].copy()
        for kt, kp, sh in reversed(steps):
            xi = dcm_backward(xi, kt, kp, sh, self.Tc)
        return xi


def adjust_step(gait: _Gait, step: Step, tau: float, xi: np.ndarray, command: np.ndarray, n_preview: int,
                swing_pose: np.ndarray | None, params: EngineParams, dt: float,
                fixed_target: bool = False) -> tuple[np.ndarray, float, np.ndarray, dict]:
    """The next footstep (x, y; its heading kept), the single-support scale lambda and the ZMP
    offset on the support sole for a step at local time ``tau`` whose DCM is ``xi``.

    Variables z = (du, dp): the footstep's move from the planner's and the ZMP's move on the sole,
    both in the support foot's frame. The DCM mismatch at the step's end, r = xi_end - xi_req, is
    affine in z (a closed-form LIPM pass at z = 0, and the pass's linear weights for the columns); the
    engine minimises |r|^2 + ``step_weight`` |du|^2 + ``zmp_weight`` |dp|^2 over the reach box and the
    sole (``lipm.solve_box_qp``) for each of five lambdas, drops those whose swing would exceed
    ``foot_speed``, and keeps the lambda of least cost + ``timing_weight`` (1 - lambda)^2.
    ``fixed_target``: the foot has landed; only the ZMP offset is free.
    Returns (target (3,), lambda, offset (2,), info); ``info["binds"]`` names the limits the chosen
    solution sits on (ours, for reports): ``reach`` (the footstep at its reach box or sole gap),
    ``sole`` (the ZMP at the sole's edge less ``zmp_margin``), ``timing`` (a shorter swing than
    planned), ``speed`` (a swing dropped because it would exceed ``foot_speed``; a timing whose
    (1 - lambda)^2 term alone costs more than the best found is not solved, so it is never dropped:
    the speed did not bind there)."""
    p = gait.p
    nominal = step.target.copy() if fixed_target else gait.nominal_target(step.support, step.side, command)
    c, s = math.cos(step.support[2]), math.sin(step.support[2])
    Rot = np.array([[c, -s], [s, c]])
    u_nom = Rot.T @ (nominal[:2] - step.support[:2])
    lo_u, hi_u = gait.box(step.side, nominal[2] - step.support[2])
    if not fixed_target:
        u_nom = np.clip(u_nom, lo_u, hi_u)
    lo_p, hi_p = gait.zmp_box(params.zmp_margin)
    ssp = p.t2 - p.t1
    tail = p.period - p.t2
    n_var = 2 if fixed_target else 4

    # the mismatch r(z) = r0 + M z: r0 from one closed-form pass per timing; M's columns from the
    # pass's weights (lipm.dcm_forward_weights: the ZMP's two sole points move with dp, the boundary
    # with du through the knots' rho and 1/2) less the next steps' required DCM, which depends on the
    # footstep alone (affine: one backward pass and _Gait.start_weight, once, not per timing)
    def required(u: np.ndarray, boundary: np.ndarray) -> np.ndarray:
        B_xy = step.support[:2] + Rot @ u
        return gait.required_dcm(np.array([B_xy[0], B_xy[1], nominal[2]]), -step.side, boundary, command, n_preview)

    B0 = np.array([*(step.support[:2] + Rot @ u_nom), nominal[2]])
    D = Rot * np.array([gait.rho, 0.5])             # d boundary / du
    _, kp0, sh = gait.knots(step.support, step.p0, B0, step.t1, p.t2, p.period)   # the points at z = 0
    if n_preview == 0:                              # a stop: at rest between the feet when this step ends
        req0, J_req = kp0[-1], D
    else:
        req0 = required(u_nom, kp0[-1])
        # moving the footstep by Rot d moves every later point by the same, so the required DCM
        # too, except through the step's boundary (the next step's first ZMP point), which moves
        # by D d; the LIPM being isotropic, that point's weight is one number (_Gait.start_weight)
        J_req = Rot + gait.start_weight * (D - Rot)

    weights = np.array([params.zmp_weight] * 2 + [params.step_weight] * 2)[:n_var]
    W = np.diag(weights)
    lo = np.concatenate([lo_p, lo_u - u_nom])[:n_var]
    hi = np.concatenate([hi_p, hi_u - u_nom])[:n_var]
    # the nominal timing first: when it leaves no mismatch (undisturbed walking) no shorter swing
    # can cost less, and the other timings are not tried
    m = params.min_ssp_scale
    lams = [(step.t2 - p.t1) / ssp] if fixed_target else [1.0] + [m + (1.0 - m) * k / 4 for k in range(4)]
    best = None
    dropped = False
    for lam in lams:
        if best is not None and best[4] < 1e-4 and lam < 1.0:
            break
        if best is not None and params.timing_weight * (1.0 - lam) ** 2 >= best[0]:
            continue                             # its timing alone costs more than the best: it cannot win
        t2 = p.t1 + lam * ssp
        if not fixed_target and t2 < tau + 2 * dt - 1e-12:
            continue                             # the swing cannot land sooner than that
        T = t2 + tail if not fixed_target else step.T
        a, w, ws = dcm_forward_weights(tau, T, (0.0, step.t1, t2, T), gait.Tc)   # _Gait.knots' times
        r0 = a * xi + w @ kp0 + ws * sh - req0
        M = (w[1] + w[2]) * Rot
        if not fixed_target:
            M = np.hstack([M, w[3] * D - J_req])
        H = 2.0 * (M.T @ M + W)
        g = 2.0 * (M.T @ r0)
        z = solve_box_qp(H, g, lo, hi)
        r = M @ z + r0
        u = u_nom if fixed_target else u_nom + z[2:]
        B_xy = step.support[:2] + Rot @ u
        if swing_pose is not None and tau >= step.t1 and not fixed_target:
            remaining = t2 - tau
            if remaining <= 0 or np.linalg.norm(B_xy - swing_pose[:2]) / remaining > params.foot_speed:
                dropped = True
                continue
        cost = float(r @ r + z @ (weights * z) + params.timing_weight * (1.0 - lam) ** 2)
        if best is None or cost < best[0]:
            best = (cost, B_xy, lam, z.copy(), float(np.linalg.norm(r)))
    if best is None:                              # no lambda meets the servo speed: keep the step as it is
        return step.target.copy(), (step.t2 - p.t1) / ssp, step.offset.copy(), \
            {"residual": float("nan"), "kept": True, "binds": ("speed",)}
    _, B_xy, lam, z, res = best
    at = (np.abs(z - lo) < 1e-9) | (np.abs(z - hi) < 1e-9)
    binds = tuple(name for name, hit in (("reach", bool(at[2:].any())), ("sole", bool(at[:2].any())),
                                         ("timing", lam < 1.0 - 1e-9 and not fixed_target),
                                         ("speed", dropped)) if hit)
    return np.array([B_xy[0], B_xy[1], nominal[2]]), float(lam), z[:2].copy(), \
        {"residual": res, "kept": False, "binds": binds}


# --- the engine -------------------------------------------------------------------------------

_LEG = {1: slice(JOINT_NAMES.index("l_hip_yaw"), JOINT_NAMES.index("l_hip_yaw") + 6),
        -1: slice(JOINT_NAMES.index("r_hip_yaw"), JOINT_NAMES.index("r_hip_yaw") + 6)}
STAND, SHIFT, WALK = "stand", "shift", "walk"


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
        self._sensors = np.array([[sx * L / 4, sy * Wd / 4] for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1))])
        self._log: list[tuple] = []
        self.reset_state()

    # --- what the engine offers ------------------------------------------------------------
    def envelope(self) -> dict[str, float]:
        """The largest command per direction its step limits and period allow [m/s, rad/s] (a
        command the ``stride_*`` calibration plans shorter steps for may be that much larger)."""
        lim, T, e = self.gait.limits, self.gait.p.period, self.params
        side = lim.max_outward / (2 * T * e.stride_sideways)
        turn = lim.max_turn / (2 * T * e.stride_turn)
        return {"forward": lim.max_forward / (T * e.stride_forward),
                "backward": lim.max_backward / (T * e.stride_backward), "left": side, "right": side,
                "turn_left": turn, "turn_right": turn}

    def _clip_command(self, c: np.ndarray) -> np.ndarray:
        e = self.envelope()
        return np.array([min(max(c[0], -e["backward"]), e["forward"]), min(max(c[1], -e["left"]), e["left"]),
                         min(max(c[2], -e["turn_left"]), e["turn_left"])])

    # --- the controller protocol -----------------------------------------------------------
    def reset_state(self) -> None:
        p = self.gait.p
        W = p.half_width
        self.feet = {1: np.array([0.0, W, 0.0]), -1: np.array([0.0, -W, 0.0])}
        self.mode = STAND
        self.t = 0.0
        self.command = np.zeros(3)
        self.asked = np.zeros(3)
        self.ramp = np.zeros(3)                    # the asked command, rate-limited (before the gyro's correction)
        self._wz_measured = 0.0                    # the gyro's yaw rate, filtered over a step
        self._wz_extra = 0.0                       # the correction the gyro asks for
        self._gyro_z = 0.0
        self._wz_steady = 0.0                      # how long the asked turn has been reached
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

    def start_pose(self) -> StartPose:
        self.reset_state()
        return StartPose(self._joints(self.com, self.feet[1], self.feet[-1])[0])

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
        self._command(command)
        self.t = m.t + dt
        if m.q is not None and m.imu_rpy is not None:
            self._learn_bias()
        self._advance(m)
        self._history.append((self.com.copy(), self.vel.copy()))
        if len(self._history) > 50:
            del self._history[:-25]
        q, support, feet = self._targets()
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

    def _command(self, command: np.ndarray | None) -> None:
        """The command the steps are planned for: the asked one clipped to the envelope and
        rate-limited by ``accel_*`` (``ramp``); the ramp starts with the first step (standing, the
        engine keeps zero), as a table's ramp does; with ``yaw_feedback``, its turn corrected by
        the gyro (:meth:`_turn_feedback`); its speeds scaled by the ``stride_*`` calibration."""
        target = self._clip_command(np.zeros(3) if command is None else np.asarray(command, dtype=float))
        self.asked = target
        if self.mode != WALK:
            self.command = self.ramp = np.zeros(3)
            return
        e = self.params
        lim = np.array([e.accel_vx, e.accel_vy, e.accel_wz]) * self.dt
        self.ramp = self.ramp + np.clip(target - self.ramp, -lim, lim)
        c = self._turn_feedback() if e.yaw_feedback > 0.0 else self.ramp
        self.command = self._stride(c)

    def _stride(self, c: np.ndarray) -> np.ndarray:
        """The command the steps are planned for: (vx, vy, wz) times the ``stride_*`` calibration (ours).
        On a surface where the feet slide on after landing (which no encoder sees) the walk goes
        faster than its steps, where the servos cannot carry the swing it falls short; a team
        calibrates its walk's odometry per field for that, and these are the same numbers, measured
        per surface in simulation (the engine sets' files say how). At 1 (the default) the command
        is planned as asked."""
        e = self.params
        if e.stride_forward == e.stride_backward == e.stride_sideways == e.stride_turn == 1.0:
            return c
        out = np.array(c, dtype=float)
        out[0] *= e.stride_forward if out[0] > 0 else e.stride_backward
        out[1] *= e.stride_sideways
        out[2] *= e.stride_turn
        return out

    def _turn_feedback(self) -> np.ndarray:
        """Turning by the gyro (ours): the yaw rate the robot measured, filtered over a step,
        against the ramp's; once the asked turn has been reached for three steps (the filter has
        caught up), the shortfall integrated at ``yaw_feedback`` is added to the turn the steps
        are planned for, at most 30 % of it either way and within the envelope; a zero turn leaves
        the correction to decay (a zero command ends it: a correction that only decays never
        reaches zero, and the walk would not stop), or with ``yaw_hold`` holds the heading while
        walking (the measured drift integrated the same way, the planned turn at most
        ``yaw_hold``). Measured
        (``benchmarks/bench_engine.py --walks 100 --parts walks --yaw-feedback 6``): on carpet4 the
        match stream's turning segments go from 80 % to 94 % of the command, survival unchanged."""
        e, dt = self.params, self.dt
        wanted = float(self.ramp[2])
        a = dt / (self.gait.p.period + dt)
        self._wz_measured += a * (self._gyro_z - self._wz_measured)
        steady = abs(self.asked[2] - wanted) < 1e-9      # not ramping: the asked turn is reached
        self._wz_steady = self._wz_steady + dt if steady else 0.0
        turning = abs(wanted) > 1e-6
        holding = (not turning and e.yaw_hold > 0.0 and self.mode == WALK
                   and bool(np.any(np.abs(self.asked[:2]) > 1e-6)))      # walking, not stopping
        if (turning or holding) and self._wz_steady > 3 * self.gait.p.period:   # the filter has caught up
            self._wz_extra += e.yaw_feedback * dt * (wanted - self._wz_measured)
            bound = 0.3 * abs(wanted) if turning else e.yaw_hold   # 30 % of the command, or the hold's
            self._wz_extra = min(max(self._wz_extra, -bound), bound)
        elif not np.any(np.abs(self.asked) > 1e-6):
            self._wz_extra = 0.0                   # asked to stop: no turn to correct, and the stop may stop
        elif not turning:
            self._wz_extra *= 1.0 - a
        c = self.ramp.copy()
        c[2] = wanted + self._wz_extra
        return self._clip_command(c)

    def _estimate(self, m: Measurement, lost: bool = False) -> None:
        """One estimator tick from the encoders, the IMU and the sole forces. A tick whose encoders
        or IMU were dropped (``lost``: not finite) predicts from the model alone; one that never
        had them (a controller run without sensing) leaves the estimator as it is."""
        if m.gyro is not None:
            self._gyro_z = float(m.gyro[2])
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
        q = self._q_ours(m)
        roll, pitch = float(m.imu_rpy[0]), float(m.imu_rpy[1])
        walking = self.cur is not None and self.mode == WALK
        sides = (self.cur.side,) if walking else (1, -1)
        # Not in a step's first `lag`: the new stance leg's encoders still turn with the landing
        # swing (measured on a 0.3 m/s carpet4 walk: -0.14 m/s read in the first 20 ms where the
        # CoM moved at +0.20 m/s, a quarter of the walk's speed lost on the mean; ours).
        rates = (self.params.kf_velocity > 0.0 and m.dq is not None and m.gyro is not None
                 and not (walking and self.t - self.step_t0 < self.params.lag))
        dq = self._ours(m, m.dq) if rates else None
        estimates, velocities = [], []
        for side in sides:
            p_ps, R_ps = sole_in_pelvis(q[_LEG[side]], self.leg, side)
            foot = self.feet[side]
            yaw_pelvis = foot[2] - math.atan2(R_ps[1, 0], R_ps[0, 0])
            R_wp = _rz(yaw_pelvis) @ _ry(pitch) @ _rx(roll)
            below_ankle = np.array([foot[0], foot[1], 0.0]) - _rz(foot[2]) @ self.leg.sole_in_ankle(side)
            arm = R_wp @ (self.leg.com_in_pelvis - p_ps)
            estimates.append(below_ankle + arm)
            if rates:
                h = 1e-3
                p_moved = sole_in_pelvis(q[_LEG[side]] + h * dq[_LEG[side]], self.leg, side)[0]
                velocities.append(np.cross(R_wp @ m.gyro, arm) - R_wp @ ((p_moved - p_ps) / h))
        return np.mean(estimates, axis=0)[:2], (np.mean(velocities, axis=0)[:2] if rates else None)

    def _q_ours(self, m: Measurement) -> np.ndarray:
        return self._ours(m, m.q)

    @staticmethod
    def _ours(m: Measurement, values: np.ndarray) -> np.ndarray:
        """An encoder reading (angles or rates) in our joint order."""
        if m.joint_names == JOINT_NAMES:
            return values
        out = np.zeros(len(JOINT_NAMES))
        for name, v in zip(m.joint_names, values):
            out[JOINT_NAMES.index(name)] = v
        return out

    def _cop(self, m: Measurement) -> np.ndarray | None:
        if m.foot_force is None:
            return None
        f = np.maximum(np.asarray(m.foot_force, dtype=float), 0.0)
        total = float(f.sum())
        if total < 0.1 * self.weight:
            return None
        pts = []
        for side, block in ((1, f[:4]), (-1, f[4:])):
            pose = self._foot_now(side)
            c, s = math.cos(pose[2]), math.sin(pose[2])
            pts.append(pose[:2] + self._sensors @ np.array([[c, s], [-s, c]]))
        pts = np.vstack(pts)
        return (f[:, None] * pts).sum(axis=0) / total

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
        q = self._joints(self.com, feet[1], feet[-1], swing=-support if support else 0)
        return q[0], support, feet

    def _joints(self, com: np.ndarray, left: np.ndarray, right: np.ndarray, swing: int = 0) -> np.ndarray:
        """Leg IK for the CoM (x, y) at z_c and the soles (x, y, yaw[, z]) -> (1, 20) targets.

        What ``trajectory.assemble`` does for a table (the pelvis moved by the robot's CoM offset,
        each ankle by its sole offset, the pelvis heading the mean of the feet's, leaned forward
        by ``torso_pitch``, the soles flat on the ground), with the closed-form IK
        (``leg_kinematics.leg_ik_pose``) for one sample. The swing leg (``swing`` = its side) takes
        ``level_feet`` of the measured tilt out, so its sole lands level in the world; the support
        leg keeps the plan's upright pelvis (its targets are what pushes a tilted trunk back)."""
        p, leg = self.gait.p, self.leg
        psi = (left[2] + right[2]) / 2
        R_plan = _rz(psi) @ _ry(p.torso_pitch)
        k = self.params.level_feet
        R_tilted = _rz(psi) @ _ry(p.torso_pitch + k * self.tilt[1]) @ _rx(k * self.tilt[0]) if k else R_plan
        pelvis = np.array([com[0], com[1], p.z_c - leg.com_above_pelvis]) \
            - _rz(psi) @ np.array([leg.com_forward, leg.com_lateral, 0.0])
        q = np.zeros((1, len(JOINT_NAMES)))
        for side, foot in ((1, left), (-1, right)):
            R_wp = R_tilted if side == swing else R_plan
            z = foot[3] if len(foot) > 3 else 0.0
            R_f = _rz(foot[2])
            sole_point = np.array([foot[0], foot[1], z]) - R_f @ leg.sole_in_ankle(side)
            target, R_ps = R_wp.T @ (sole_point - pelvis), R_wp.T @ R_f
            q[0, _LEG[side]] = leg_ik_pose(self._reachable(target, R_ps, side), R_ps, leg, side)
        return q

    def _reachable(self, target: np.ndarray, R_ps: np.ndarray, side: int) -> np.ndarray:
        """The sole target moved toward the hip until the leg reaches it (a plan that runs away, a
        fall: the engine's targets stay a pose the leg can take, the robot falls as it would)."""
        leg = self.leg
        hip = leg.hip_in_pelvis(side)
        ankle = target + R_ps[:, 2] * leg.ankle_height
        d = ankle - hip
        n = float(np.linalg.norm(d))
        reach = 0.999 * (leg.thigh + leg.shank)
        if n <= reach:
            return target
        self.clamped += 1
        return hip + d * (reach / n) - R_ps[:, 2] * leg.ankle_height
