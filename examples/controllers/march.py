"""An example of a controller of your own: marching in place on a sinusoidal sway (ours, an example).

Many teams' first walk is a central pattern generator: the pelvis sways from foot to foot on a
sine and each foot lifts while the body is over the other one. This one does that, online, from
the time alone, and adds an ankle feedback from the IMU, so it shows every part of the
``gaits.control.Controller`` protocol a team's own engine implements:

* built as ``MarchInPlace(params, robot, dt)``: ``params`` the values of ``march.yaml`` (or a
  study's trial), ``robot`` anything with ``leg`` (``gaits.LegGeometry``) and ``foot_size``;
* ``senses``: the readings it uses (the IMU's tilt and the gyro); the loop leaves out the rest;
* ``start_pose()``: the stance it starts in; ``reset(m)``; ``step(m, command)``: the 20 joint
  targets of the next tick; ``plan(n)``: what it planned per tick (support foot, sole centres,
  the pelvis as its ZMP reference), which the metrics compare with what the robot did.

Try it: ``gait-tuner simulate --controller examples/controllers/march.yaml --surface rigid``;
tune it: ``gait-tuner tune examples/controllers/march-study.yaml``.
"""

from __future__ import annotations

import math

import numpy as np

from gaits.control import PlanRecord, StartPose
from gaits.trajectory import assemble


class MarchInPlace:
    senses = frozenset({"imu_rpy", "gyro"})

    def __init__(self, params: dict, robot, dt: float) -> None:
        self.p = dict(params)
        self.leg = robot.leg
        self.dt = float(dt)
        self.duration = None              # it marches as long as it is run
        self.walk_start = self.p["t_stand"]
        self._log: list[tuple[int, float, float, float]] = []

    # the pose of the pattern at time t: pelvis (3,), left and right soles (3,), support side
    def _pattern(self, t: float):
        p = self.p
        s = t - p["t_stand"]
        ramp = min(max(s / p["ramp"], 0.0), 1.0) if s > 0 else 0.0
        phase = math.pi * s / p["period"] if s > 0 else 0.0    # one step per half sway cycle
        sway = math.sin(phase)
        pelvis = np.array([0.0, ramp * p["sway"] * sway, p["height"] - self.leg.com_above_pelvis])

        def lift(over: float) -> float:                       # the body is over the other foot
            return ramp * p["lift"] * max(0.0, (over - 0.3) / 0.7)
        left = np.array([0.0, p["half_width"], lift(-sway)])
        right = np.array([0.0, -p["half_width"], lift(sway)])
        support = 1 if right[2] > 0 else (-1 if left[2] > 0 else 0)
        return pelvis, left, right, support

    def _joints(self, t: float) -> np.ndarray:
        pelvis, left, right, support = self._pattern(t)
        traj = assemble("march", np.array([t]), self.leg, p_world_pelvis=pelvis[None], p_world_foot_l=left[None],
                        p_world_foot_r=right[None], support=np.array([support]))
        self._log.append((support, pelvis[0], pelvis[1], t))
        return traj.q_ref[0]

    def start_pose(self) -> StartPose:
        q = self._joints(0.0)
        self._log.clear()
        return StartPose(q)

    def reset(self, m) -> None:
        self._log.clear()
        self._t = 0.0

    def step(self, m, command=None) -> np.ndarray:
        q = self._joints(m.t + self.dt).copy()
        # the ankle strategy: press the toes down when tipping forward, the outer edge when rolling
        p = self.p
        pitch, roll = m.imu_rpy[1], m.imu_rpy[0]
        d_pitch = np.clip(p["k_pitch"] * pitch + p["d_pitch"] * m.gyro[1], -0.2, 0.2)
        d_roll = np.clip(p["k_roll"] * roll, -0.2, 0.2)
        for side in ("l", "r"):
            q[_JOINT[f"{side}_ankle_pitch"]] += d_pitch
            q[_JOINT[f"{side}_ankle_roll"]] += d_roll
        return q

    def plan(self, n: int) -> PlanRecord:
        log = [(0, 0.0, 0.0, 0.0)] + self._log[:n - 1]
        log += [log[-1]] * (n - len(log))
        support = np.array([r[0] for r in log], dtype=int)
        zmp = np.array([[r[1], r[2]] for r in log])
        w = self.p["half_width"]
        return PlanRecord("march", support, zmp, np.tile([0.0, w], (n, 1)), np.tile([0.0, -w], (n, 1)),
                          walk_start=self.walk_start, cycle_time=2 * self.p["period"])


from gaits.trajectory import JOINT_NAMES  # noqa: E402

_JOINT = {name: i for i, name in enumerate(JOINT_NAMES)}
