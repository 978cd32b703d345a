"""The online walk engine (ours): TLIPFM's natural-ZMP walk, planned step by step from what the robot
senses, for a walk command that may change at any tick.

It is a :class:`gaits.control.Controller` in pure numpy, so it runs in the simulator's loop and on
a robot (``gaits/robot/loop.py``). Every control tick it takes the current command (vx, vy, wz),
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

The rooms: ``params.py`` the engine's numbers (:class:`EngineParams`); ``estimator.py`` the CoM
estimator and the leg's forward kinematics; ``step_adjust.py`` a step, the rules taken from the
TLIPFM set and the step adjustment's QP; ``shaping.py`` the command shaping (envelope, ramp, the
gyro's turn feedback, the stride calibration); ``walk.py`` the engine: the step state machine, the
swing and the legs' IK; ``servo_load.py`` the servos' give and lag put back into the targets;
``residual.py`` a linear correction on the legs' targets trained in the tool's own loop.
"""

from .estimator import CoMEstimator, sole_in_pelvis
from .params import EngineParams
from .residual import ResidualParams, ResidualWalk, residual_from_mapping
from .shaping import CommandShaper
from .step_adjust import Step, _Gait, adjust_step
from .walk import SHIFT, STAND, WALK, WalkEngine

__all__ = ["EngineParams", "WalkEngine", "CoMEstimator", "CommandShaper", "Step", "adjust_step", "sole_in_pelvis",
           "STAND", "SHIFT", "WALK", "_Gait", "ResidualParams", "ResidualWalk",
           "residual_from_mapping"]
