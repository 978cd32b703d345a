"""The speed test of a speed study (ours); the commanded walk itself is ``gaits.command_walk``.

:func:`speed_test` walks one direction's staircase (``gaits.SpeedStaircase``) in one
rollout and finds the highest stair the robot *holds*: it is still up at the stair's
end and its measured velocity along the direction, over the stair's whole cycles, is
at least ``1 - tolerance`` of the command. The stairs must be held in order (a stair
after a failed one does not count), so the score is the command the walk reaches
before it falls or stops gaining, in the spirit of the published Optuna walk tuner
(Bestmann and Zhang, RoboCup 2022) but in one rollout per direction. Stairs the
footstep planner rejects (a step beyond the robot's step limits) are not walked.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

import gaits
from gaits import ParamError, SpeedStaircase
from gaits.walk_command import DIRECTIONS

from .metrics import heading_velocity, pitch_rms

__all__ = ["speed_test", "DirectionResult", "command_limit", "saturation"]


def command_limit(params: gaits.GaitParams, robot, direction: str) -> float:
    """The largest command along a direction the step limits allow for these parameters
    (m/s or rad/s); 0 for a direction the family does not walk."""
    return gaits.family_of(params).command_limit(params, robot, DIRECTIONS[direction])


@dataclass(frozen=True)
class DirectionResult:
    """One direction's speed test on one surface."""

    direction: str
    reached: float               # [m/s or rad/s] highest stair held (0: none)
    measured: float              # its measured velocity along the direction
    levels: tuple[float, ...]    # commanded value of every stair walked
    achieved: tuple[float, ...]  # measured velocity per stair (NaN where the robot was down)
    fell: bool
    pitch_rms_deg: float
    reason: str
    unit: str = "m/s"
    extra: dict = field(default_factory=dict)


def speed_test(sim, params: gaits.GaitParams, stairs: SpeedStaircase, tolerance: float = 0.2,
               stabiliser=None, limits: bool = False) -> DirectionResult:
    """Walk a direction's staircase on ``sim`` and score the highest stair held (module docstring).

    ``limits``: also report in ``extra["saturation"]`` the servos that hit their torque or speed
    limit on the stair after the highest one held (where the walk stopped gaining)."""
    robot = sim.robot
    if not gaits.walks_direction(params.FAMILY, stairs.direction):
        return DirectionResult(stairs.direction, 0.0, 0.0, (), (), False, float("nan"),
                               f"gait {params.FAMILY!r} does not walk {stairs.direction}", stairs.unit)
    top = min(stairs.top, command_limit(params, robot, stairs.direction))
    values = stairs.level_values()
    n_ok = int(np.sum(values <= top + 1e-12))
    if n_ok == 0:
        return DirectionResult(stairs.direction, 0.0, 0.0, (), (), False, float("nan"),
                               f"the first stair {values[0]:g} {stairs.unit} is beyond the step limits",
                               stairs.unit)
    stairs = dataclasses.replace(stairs, top=float(values[n_ok - 1]), levels=n_ok)
    traj = None
    while stairs.levels >= 1:
        try:
            traj = gaits.family_of(params).walk(params, robot, sim.control_period, stairs.per_step())
            break
        except ParamError:
            if stairs.levels == 1:
                return DirectionResult(stairs.direction, 0.0, 0.0, (), (), False, float("nan"),
                                       "no stair can be planned", stairs.unit)
            v = stairs.level_values()
            stairs = dataclasses.replace(stairs, top=float(v[-2]), levels=stairs.levels - 1)
    trace = sim.rollout(traj, stabiliser=stabiliser)
    unit = np.array(DIRECTIONS[stairs.direction])
    achieved, reached, measured, holding = [], 0.0, 0.0, True
    starts = gaits.step_starts(params, len(stairs.per_step()))
    for i, value in enumerate(stairs.level_values()):
        a, b = stairs.level_steps(i)
        t0, t1 = float(starts[a]), float(starts[b])
        v = heading_velocity(trace.t, trace.p_torso, trace.yaw, t0, t1)
        along = float(v @ unit)
        achieved.append(along)
        ok = np.isfinite(along) and along >= (1.0 - tolerance) * value
        if holding and ok:
            reached, measured = float(value), along
        else:
            holding = False
    w = trace.t >= trace.walk_start
    extra = {}
    if limits:
        values = list(stairs.level_values())
        i = min(values.index(reached) + 1 if reached in values else 0, len(values) - 1)
        a, b = stairs.level_steps(i)
        extra["saturation_stair"] = float(values[i])
        extra["saturation"] = saturation(sim, trace, float(starts[a]), float(starts[b]))[:3]
    return DirectionResult(stairs.direction, reached, measured, tuple(float(x) for x in stairs.level_values()),
                           tuple(achieved), not trace.survived,
                           pitch_rms(np.degrees(trace.pitch[w])) if w.any() else float("nan"),
                           trace.reason, stairs.unit, extra)


def saturation(sim, trace, t0: float, t1: float) -> list[dict]:
    """Which servos hit a limit in [t0, t1]: per joint the share of control ticks at >= 95% of
    the torque limit, and at the speed limit (the rate-limited command moved its full step),
    sorted by the larger share, highest first."""
    sel = (trace.t >= t0) & (trace.t <= t1)
    if sel.sum() < 2:
        return []
    n = len(trace.joint_names)
    tau_max = sim.model.actuator_forcerange[:n, 1]
    tau_share = np.mean(np.abs(trace.tau[sel]) >= 0.95 * tau_max, axis=0)
    moved = np.abs(np.diff(trace.q_cmd[sel], axis=0))
    speed_share = np.mean(moved >= 0.99 * sim._max_step[:n], axis=0)
    rows = [{"joint": j, "torque_share": float(a), "speed_share": float(b)}
            for j, a, b in zip(trace.joint_names, tau_share, speed_share)]
    return sorted(rows, key=lambda r: -max(r["torque_share"], r["speed_share"]))
