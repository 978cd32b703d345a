"""The walk engine's own numbers (ours; the gait's come from its TLIPFM set): one parameter class,
its defaults, units and ranges, read from a gait file's ``engine:`` section."""

from __future__ import annotations

from dataclasses import dataclass

from ..params import GaitParams, ParamError, param

__all__ = ["EngineParams"]


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
    servo_share: float = param(0.0, "-", 0.0, 1.0, "each tick the targets move at most this share of each "
                               "joint's servo speed (the robot's; ours: a table the servos can play, as the "
                               "export's servo check asks; 0: not capped, the servos limit the moves)")
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
    combined_limit: float = param(2.0, "-", 0.3, 2.0, "the largest Euclidean norm of a command's shares of "
                                  "each direction's envelope (ours: 1 an ellipsoid, a walk forward while "
                                  "turning at the edge asks less of each; below 1 a smaller one, the step "
                                  "limits being kinematic, not what the walk keeps its balance at; from "
                                  "sqrt(3) = 1.73 up the box, each direction to its own limit)")
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

    load_share: float = param(0.0, "-", 0.0, 1.5, "share of the servos' predicted give under the stance "
                              "load put back into their targets (ours: gaits/engine/servo_load.py; needs "
                              "the robot's servo gains; 0: none)")
    lag_share: float = param(0.0, "-", 0.0, 1.5, "share of the servos' velocity lag (damping / kp times the "
                             "target's rate) the targets lead by (ours: gaits/engine/servo_load.py; 0: none)")

    def check_consistency(self) -> None:
        if self.shift_time > self.t_stand + 1e-12 and self.t_stand > 0:
            raise ParamError(f"engine: shift_time = {self.shift_time:g} s must fit in t_stand = "
                             f"{self.t_stand:g} s (the shift happens while standing)")
