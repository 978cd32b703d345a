"""A servo on a pendulum bench, as Rhoban's BAM identifies servos: a point mass on a rod (the arm
down is 0 rad, positive counter-clockwise), in MuJoCo with the simulator's own options (MuJoCo's
solver defaults, the implicit-fast integrator; ``tuner/sim/scene.py``), the servo given its pieces by
``tuner.servos.configure`` and, for an extended friction, run by the native step (``native_step.py``). Used to test our law
against BAM's trajectories (``tests/test_servo_law.py``) and to show a preset's behaviour.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..servos import ServoLaw, configure
from .native_step import require

__all__ = ["Bench", "track"]

GRAVITY = 9.80665        # [m/s^2] BAM's bench's


@dataclass(frozen=True)
class Bench:
    """The pendulum: ``mass`` [kg] at ``length`` [m] on a rod of ``arm_mass`` [kg]."""

    mass: float
    length: float
    arm_mass: float = 0.0

    def spec(self, servo: ServoLaw, timestep: float) -> tuple[mujoco.MjSpec, bool]:
        spec = mujoco.MjSpec()
        spec.option.gravity = [0.0, 0.0, -GRAVITY]
        spec.option.timestep = timestep
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
        body = spec.worldbody.add_body(name="arm")
        joint = body.add_joint(name="hinge", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[1.0, 0.0, 0.0])
        total = self.mass + self.arm_mass
        com = -(self.mass * self.length + self.arm_mass * self.length / 2) / total
        pivot = self.mass * self.length ** 2 + self.arm_mass * self.length ** 2 / 3
        inertia = max(pivot - total * com * com, 1e-9)
        body.mass, body.ipos, body.inertia = total, [0.0, 0.0, com], [inertia] * 3
        act = spec.add_actuator(name="servo", target="hinge", trntype=mujoco.mjtTrn.mjTRN_JOINT)
        return spec, configure(spec, joint, act, servo)


def track(servo: ServoLaw, bench: Bench, goal: np.ndarray, timestep: float, q0: float = 0.0,
          noslip: int = 0) -> np.ndarray:
    """The arm's angle [rad] at each physics step while the servo is given ``goal`` (one target per
    step, the first at rest at ``q0``; a cap on the target's speed applied per step, as a firmware's
    profile speed is): row k is the angle before step k, as BAM's logs hold it. ``noslip``: MuJoCo's
    noslip iterations (BAM's bench runs 1; the simulator none)."""
    spec, term = bench.spec(servo, timestep)
    spec.option.noslip_iterations = noslip
    if term:
        require(f"a {servo.law} servo's extended friction on the bench")
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[0] = q0
    mujoco.mj_forward(model, data)
    out = np.empty(len(goal))
    cap = servo.target_speed * timestep
    target = q0
    for k, g in enumerate(goal):
        out[k] = data.qpos[0]
        target = min(max(g, target - cap), target + cap)
        data.ctrl[0] = target
        mujoco.mj_step(model, data)
    return out
