"""The command the engine's steps are planned for (ours): the asked command clipped to the
engine's envelope, rate-limited by ``accel_*``, its turn corrected by the gyro (``yaw_feedback``,
``yaw_hold``) and its speeds scaled by the ``stride_*`` calibration."""

from __future__ import annotations

import numpy as np

from .params import EngineParams

__all__ = ["CommandShaper"]


class CommandShaper:
    """Shapes each tick's asked command into the one the steps are planned for.

    ``asked``: the last command taken, clipped to the envelope; ``ramp``: it rate-limited (before
    the gyro's correction); ``command``: what the steps are planned for. ``gyro_z`` [rad/s] is the
    gyro's yaw rate of the tick (the engine's estimator sets it)."""

    def __init__(self, params: EngineParams, limits, period: float, dt: float) -> None:
        self.params, self.limits, self.period, self.dt = params, limits, float(period), float(dt)
        self.reset()

    def reset(self) -> None:
        self.command = np.zeros(3)
        self.asked = np.zeros(3)
        self.ramp = np.zeros(3)                    # the asked command, rate-limited (before the gyro's correction)
        self.wz_measured = 0.0                     # the gyro's yaw rate, filtered over a step
        self.wz_extra = 0.0                        # the correction the gyro asks for
        self.gyro_z = 0.0
        self.wz_steady = 0.0                       # how long the asked turn has been reached

    def envelope(self) -> dict[str, float]:
        """The largest command per direction its step limits and period allow [m/s, rad/s] (a
        command the ``stride_*`` calibration plans shorter steps for may be that much larger)."""
        lim, T, e = self.limits, self.period, self.params
        side = lim.max_outward / (2 * T * e.stride_sideways)
        turn = lim.max_turn / (2 * T * e.stride_turn)
        return {"forward": lim.max_forward / (T * e.stride_forward),
                "backward": lim.max_backward / (T * e.stride_backward), "left": side, "right": side,
                "turn_left": turn, "turn_right": turn}

    def clip(self, c: np.ndarray) -> np.ndarray:
        """``c`` within the envelope: each direction to its own limit (a box), then, where the
        command's shares of those limits have a Euclidean norm above ``combined_limit``, scaled
        down to it along its own direction (ours: at 1 an ellipsoid; a walk forward while turning
        at both edges asks the swing for the longest step and the largest turn at once)."""
        e = self.envelope()
        out = np.array([min(max(c[0], -e["backward"]), e["forward"]), min(max(c[1], -e["left"]), e["left"]),
                        min(max(c[2], -e["turn_left"]), e["turn_left"])])
        cap = self.params.combined_limit
        if cap < 3.0 ** 0.5:
            shares = out / np.array([e["forward"] if out[0] >= 0 else e["backward"], e["left"], e["turn_left"]])
            norm = float(np.sqrt(np.sum(shares ** 2)))
            if norm > cap:
                out = out * (cap / norm)
        return out

    def update(self, command: np.ndarray | None, walking: bool) -> None:
        """The command the steps are planned for: the asked one clipped to the envelope and
        rate-limited by ``accel_*`` (``ramp``); the ramp starts with the first step (standing,
        ``walking`` False, the engine keeps zero), as a table's ramp does; with ``yaw_feedback``,
        its turn corrected by the gyro (:meth:`turn_feedback`); its speeds scaled by the
        ``stride_*`` calibration."""
        target = self.clip(np.zeros(3) if command is None else np.asarray(command, dtype=float))
        self.asked = target
        if not walking:
            self.command = self.ramp = np.zeros(3)
            return
        e = self.params
        lim = np.array([e.accel_vx, e.accel_vy, e.accel_wz]) * self.dt
        self.ramp = self.ramp + np.clip(target - self.ramp, -lim, lim)
        c = self.turn_feedback(walking) if e.yaw_feedback > 0.0 else self.ramp
        self.command = self.stride(c)

    def stride(self, c: np.ndarray) -> np.ndarray:
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

    def turn_feedback(self, walking: bool) -> np.ndarray:
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
        a = dt / (self.period + dt)
        self.wz_measured += a * (self.gyro_z - self.wz_measured)
        steady = abs(self.asked[2] - wanted) < 1e-9      # not ramping: the asked turn is reached
        self.wz_steady = self.wz_steady + dt if steady else 0.0
        turning = abs(wanted) > 1e-6
        holding = (not turning and e.yaw_hold > 0.0 and walking
                   and bool(np.any(np.abs(self.asked[:2]) > 1e-6)))      # walking, not stopping
        if (turning or holding) and self.wz_steady > 3 * self.period:   # the filter has caught up
            self.wz_extra += e.yaw_feedback * dt * (wanted - self.wz_measured)
            bound = 0.3 * abs(wanted) if turning else e.yaw_hold   # 30 % of the command, or the hold's
            self.wz_extra = min(max(self.wz_extra, -bound), bound)
        elif not np.any(np.abs(self.asked) > 1e-6):
            self.wz_extra = 0.0                    # asked to stop: no turn to correct, and the stop may stop
        elif not turning:
            self.wz_extra *= 1.0 - a
        c = self.ramp.copy()
        c[2] = wanted + self.wz_extra
        return self.clip(c)
