"""The sensor reader: what a kid-size robot would sense of the simulated state, every control tick.

It is the only place a controller's inputs are made (``gaits.control.Measurement``): joint
encoders (position and velocity, from MuJoCo's actuator sensors, in gait-tuner's signs), the
IMU (orientation, gyro, accelerometer at the ``gt/imu`` site on the torso) and the eight sole
force readings (the touch sensors of the four sole quadrants of each foot). Ground truth (the
free joint's pose, the CoM, contacts) is not in it; the recorder keeps that for the metrics.

How each reading is made, and what it costs (the loop's budget is a few microseconds a tick):

* encoders and sole forces: MuJoCo's sensors. Like every MuJoCo sensor read after ``mj_step``,
  they describe the state at the start of the last physics step (2 ms before the tick);
* orientation: the site's frame quaternion sensor, turned into Z-Y-X roll, pitch, yaw by the
  same numpy expressions as the trace's pitch and roll;
* gyro: the torso's angular velocity in its own frame at the tick (the free joint's rates: our
  IMU site sits on the torso with its axes);
* accelerometer: the site's specific force, R^T (a_origin - g) + alpha x r + omega x (omega x r),
  from the free joint's accelerations (MuJoCo's accelerometer sensor would add ~10 us to every
  tick of every rollout, about 9% of the physics: measured);
* a reading the controller does not use (its ``senses``) is not made.

Noise and latency (a perturbation of ``tuner/sim/randomisation.py``): the tilt (pitch, roll) and
the pitch and roll rates get Gaussian noise from the perturbation's noise stream, four draws per
tick in that order, every tick whatever the controller senses (so a rollout's noise does not
depend on its controller); the other readings (yaw, yaw rate, accelerometer, encoders, forces)
from a second stream of the same seed. The IMU's readings reach the controller
``imu_latency`` ticks late; before the first one arrives the IMU reads zeros. A sole force reads
>= 0 (the sensor cannot pull).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from gaits.control import READINGS, Measurement, rpy_from_quat

__all__ = ["SensorReader"]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for two 3-vectors (np.cross costs 50 us on 3 elements)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


class SensorReader:
    """Makes the :class:`~gaits.control.Measurement` of each tick for one rollout."""

    def __init__(self, sim, senses, pert=None) -> None:
        senses = frozenset(READINGS if senses is None else senses)
        unknown = senses - set(READINGS)
        if unknown:
            raise ValueError(f"unknown readings {sorted(unknown)}: a controller senses {', '.join(READINGS)}")
        self.sim, self.d = sim, sim.data
        self.senses = senses
        self._want = {name: name in senses for name in READINGS}
        # a robot without sole sensors gives no foot_force reading, whatever the controller would use
        self._want["foot_force"] &= bool(getattr(sim.robot, "foot_sensors", True))
        self._imu = self._want["imu_rpy"] or self._want["gyro"] or self._want["accel"]
        self._noise = pert is not None
        self._latency = pert.imu_latency if pert is not None else 0
        self._queue: deque = deque([None] * self._latency)
        n = sim._n_servo
        if pert is not None:
            self._rng_a = np.random.default_rng(pert.noise_seed)
            self._rng_b = np.random.default_rng([pert.noise_seed, 1])
            self._scale_a = np.array([pert.imu_noise, pert.imu_noise, pert.gyro_noise, pert.gyro_noise])
            self._scale_b = np.concatenate([[pert.imu_noise, pert.gyro_noise], np.full(3, pert.accel_noise),
                                            np.full(n, pert.encoder_noise), np.full(n, pert.encoder_rate_noise),
                                            np.full(8, pert.force_noise)])
        self._n = n
        self._r_site = sim._imu_offset
        self._gravity = sim.model.opt.gravity

    def _imu_reading(self, a: np.ndarray | None, b: np.ndarray | None):
        """(rpy, gyro, accel) of the current state, with this tick's noise."""
        d, s = self.d, self.d.sensordata
        rpy = gyro = accel = None
        if self._want["imu_rpy"]:
            rpy = rpy_from_quat(s[self.sim._s_quat])
        if self._want["gyro"]:
            gyro = d.qvel[3:6].copy()
        if a is not None:
            if rpy is not None:
                rpy[1] += a[0]
                rpy[0] += a[1]
                rpy[2] += b[0]
            if gyro is not None:
                gyro[1] += a[2]
                gyro[0] += a[3]
                gyro[2] += b[1]
        if self._want["accel"]:
            R = d.xmat[self.sim._torso].reshape(3, 3)
            w, alpha, r = d.qvel[3:6], d.qacc[3:6], self._r_site
            wr = _cross(w, r)
            accel = R.T @ (d.qacc[0:3] - self._gravity) + _cross(alpha, r) + _cross(w, wr)
            if b is not None:
                accel = accel + b[2:5]
        return rpy, gyro, accel

    def read(self, t: float) -> Measurement:
        """The measurement of the current state at time ``t`` [s]."""
        a = self._rng_a.normal(0.0, 1.0, 4) * self._scale_a if self._noise else None
        b = self._rng_b.normal(0.0, 1.0, len(self._scale_b)) * self._scale_b if self._noise else None
        m = Measurement(t, joint_names=self.sim.joint_names)
        if self._imu:
            reading = self._imu_reading(a, b)
            if self._latency:
                self._queue.append(reading)
                reading = self._queue.popleft()
            if reading is None:
                reading = tuple(None if not self._want[k] else np.zeros(3) for k in ("imu_rpy", "gyro", "accel"))
            m.imu_rpy, m.gyro, m.accel = reading
        want, sim, s, n = self._want, self.sim, self.d.sensordata, self._n
        if want["q"]:
            m.q = sim.from_robot(s[sim._s_q])
            if b is not None:
                m.q += b[5:5 + n]
        if want["dq"]:
            m.dq = s[sim._s_dq] * sim._sign
            if b is not None:
                m.dq += b[5 + n:5 + 2 * n]
        if want["foot_force"]:
            f = s[sim._s_touch] @ sim._touch_sum
            if b is not None:
                f = np.maximum(f + b[5 + 2 * n:], 0.0)
            m.foot_force = f
        return m
