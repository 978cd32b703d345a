"""The physical bound of the push-recovery challenge and of forward speed for a robot (ours):
``gait-tuner challenge bound``.

A reduced model that knows the push in advance and is given every benefit of the doubt, so that
what it cannot absorb no controller on this robot can (an upper bound, within what it models):

* **The body**: the linear inverted pendulum (LIPM) of the robot's CoM at its walking height z_c
  (``omega = sqrt(g / z_c)``), its whole mass; no angular momentum (no upper-body swing, no
  flywheel: a robot that windmills its arms could do a little more, which the bound leaves out).
* **The push**: the bottle meets the robot inelastically (the foam: restitution 0), so the CoM
  takes Delta v = p_B / (m_B + m_R), the least of any restitution. The robot stands on one foot with
  the CoM over it, in the middle of stepping in place, ready to step at once.
* **The feet**: the ZMP anywhere on the support sole (the sole's front and back edges from the
  ankle, ``robot.soles``/``foot_size``), and no further than the ankle's servo torque carries the
  whole weight (tau / (m g)). Each step lands within ``reach`` (thigh + shank times the reach
  ratio, as the engine's ``reach_forward``, default 0.8, the parameter's range's top) and takes
  at least the swing time the leg's servos allow: the hip pitch turning the leg through the step,
  the knee bending to lift the foot by ``lift`` and straightening, each the fastest rest-to-rest move
  its servo allows (the leg as point masses, the servo's armature added): a motor's along its
  torque-speed line (full duty one way then the other, the torque falling with speed by the
  back-EMF and the viscous friction, less its dry friction: ``move_time``, exact for that model);
  a pd servo's at its no-load speed and stall torque (``_move_bounds``). Gravity on the swing leg
  left out, so shorter than any real swing. Double support is instantaneous.
* **Captured**: after the last step the capture point lies on the last sole (the robot can then
  stop over it).

The trajectory optimisation (CasADi, IPOPT): decision variables the push's Delta v (maximised),
each phase's duration and constant ZMP, each step's place; the LIPM integrated exactly per phase
(the named block ``lipm_phase``). The closed form it is tested against: one step, ZMP at the
sole's edge, Delta v_max = omega (b + l e^{-omega T_s(l)}) (Koolen et al. 2012, capturability,
with a finite sole), the best step length l up to the reach.

Forward speed: a periodic LIPM gait's speed is step / period; the step at most ``reach`` long,
the period at least the swing time of that step; the largest of step / swing_time(step) over
steps up to the reach, with its Froude number v^2 / (g z_c). What it leaves out (``LEAVES_OUT``,
said with every bound): the friction and the turf (a rigid floor: the turf slows the swing),
the stance knee's torque under load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

__all__ = ["robot_bound", "LegLimits", "leg_limits", "swing_times", "lipm_phase_function", "one_step_capture", "push_bound", "push_bounds",
           "speed_bound", "swing_time", "bottle_figures", "LEAVES_OUT"]

#: what the model leaves out, said with every bound
LEAVES_OUT = ("angular momentum (arm or trunk swing, a flywheel)", "friction and the turf (a rigid floor)",
              "gravity on the swing leg (and a pd servo's torque-speed droop: a motor's is in)",
              "double support's duration", "the stance knee's torque under load", "the bottle's bounce (inelastic)")

GRAVITY = 9.81


@dataclass(frozen=True)
class LegLimits:
    """What the bound takes of a robot (SI units)."""

    mass: float               # [kg] the whole robot
    z_c: float                # [m] CoM height walking
    sole_front: float         # [m] the sole's front edge ahead of the ankle
    sole_back: float          # [m] its back edge behind the ankle
    reach: float              # [m] the longest step, forward or backward
    leg: float                # [m] hip to ankle at the crouch
    thigh: float              # [m]
    shank: float              # [m]
    crouch_height: float      # [m] hip to ankle height at the walking crouch
    hip_speed: float          # [rad/s] hip pitch servo
    knee_speed: float         # [rad/s] knee servo
    ankle_torque: float       # [N m] ankle pitch servo
    knee_torque: float        # [N m] knee servo
    lift: float               # [m] the swing foot's lift
    hip_torque: float = math.inf      # [N m] hip pitch servo
    leg_inertia: float = 0.0          # [kg m^2] the swing leg about the hip pitch axis (its servo's armature in)
    shank_inertia: float = 0.0        # [kg m^2] the shank and foot about the knee (its armature in)
    hip_droop: float = 0.0            # [N m s/rad] the hip pitch motor's torque lost per rad/s (back-EMF and viscous)
    knee_droop: float = 0.0           # [N m s/rad] the knee motor's
    hip_friction: float = 0.0         # [N m] the hip pitch servo's dry friction (a motor's: it takes that from the stall torque)
    knee_friction: float = 0.0        # [N m]

    @property
    def omega(self) -> float:
        return math.sqrt(GRAVITY / self.z_c)

    def zmp_front(self) -> float:
        """[m] the furthest ZMP ahead of the ankle: the sole's edge, or what the ankle's torque carries."""
        return min(self.sole_front, self.ankle_torque / (self.mass * GRAVITY))

    def zmp_back(self) -> float:
        return min(self.sole_back, self.ankle_torque / (self.mass * GRAVITY))


def _knee_angle(height: float, thigh: float, shank: float) -> float:
    """The knee's bend [rad] that puts the ankle ``height`` below the hip (law of cosines)."""
    c = (thigh * thigh + shank * shank - height * height) / (2 * thigh * shank)
    return math.pi - math.acos(max(-1.0, min(1.0, c)))


def move_time(angle: np.ndarray | float, torque: float, droop: float, inertia: float) -> np.ndarray:
    """[s] The fastest move through ``angle`` [rad] from rest to rest of an ``inertia`` [kg m^2] driven
    along a torque-speed line, I w' = u torque - droop w with |u| <= 1 (a motor at full duty, its
    stall torque ``torque`` less its dry friction, losing ``droop`` [N m s/rad] per rad/s to its
    back-EMF and viscous friction): full duty forward then full duty back (bang-bang, the switch where
    the braking ends at rest on the angle). Exact for the model; solved for the switch by bisection."""
    theta = np.atleast_1d(np.asarray(angle, dtype=float))
    a, c = torque / inertia, droop / inertia
    top = a / c                                            # [rad/s] the no-load speed

    def reached(t1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w1 = top * (1.0 - np.exp(-c * t1))                 # speed at the switch
        s2 = np.log1p(w1 / top) / c                        # braking time to rest
        return top * (t1 - (1.0 - np.exp(-c * t1)) / c) + w1 / c - top * s2, t1 + s2
    lo, hi = np.zeros_like(theta), np.full_like(theta, 1.0)
    while np.any(reached(hi)[0] < theta):
        hi = np.where(reached(hi)[0] < theta, 2 * hi, hi)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        low = reached(mid)[0] < theta
        lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
    out = reached(hi)[1]
    return out if np.ndim(angle) else out[0]


def _move_time_function(torque: float, droop: float, inertia: float, top: float) -> ca.Function:
    """``move_time`` over [0, ``top``] rad as a named CasADi block (a B-spline through 400 exact
    points: smooth for the optimiser)."""
    grid = np.linspace(0.0, top, 400)
    return ca.interpolant("move_time", "bspline", [grid], move_time(grid, torque, droop, inertia))


def _move_bounds(angle: Any, speed: float, torque: float, inertia: float, droop: float = 0.0,
                 friction: float = 0.0) -> list[Any]:
    """Lower bounds [s] of the shortest move through ``angle`` [rad] from rest to rest. A motor
    (``droop`` > 0): its exact fastest move along its torque-speed line (``move_time``, its stall
    torque less its dry ``friction``). A pd servo: no shorter than at full speed throughout (angle /
    speed), nor than at full torque throughout (bang-bang accelerate-decelerate, 2 sqrt(angle /
    (torque / inertia))): the true shortest move (ramps at full torque, then full speed) is longer
    than both, so the bound stays an upper bound, a little looser, and each term is smooth for the
    optimiser. Gravity is left out. Works on numbers and CasADi expressions."""
    symbolic = isinstance(angle, (ca.SX, ca.MX))
    if droop > 0 and inertia > 0 and math.isfinite(torque) and torque > friction:
        if symbolic:
            return [_move_time_function(torque - friction, droop, inertia, math.pi)(angle)]
        return [float(move_time(angle, torque - friction, droop, inertia))]
    sqrt = ca.sqrt if symbolic else math.sqrt
    if droop > 0 and not symbolic and torque <= friction:
        return [math.inf]                          # a motor too weak to overcome its own friction
    out = [angle / speed if speed > 0 else math.inf]
    if inertia > 0 and math.isfinite(torque):
        out.append(2 * sqrt(angle * inertia / torque + 1e-12))
    return out


def _hip_turn(lim: LegLimits, step: Any) -> Any:
    """[rad] the swing leg's turn for a step: from half a step behind the hip to half a step ahead
    (a step stays under the reach, well below twice the leg, so the arcsine is defined)."""
    asin = ca.asin if isinstance(step, (ca.SX, ca.MX)) else math.asin
    return 2 * asin(step / (2 * lim.leg))


def _knee_bend(lim: LegLimits) -> float:
    return _knee_angle(lim.crouch_height - lim.lift, lim.thigh, lim.shank) - \
        _knee_angle(lim.crouch_height, lim.thigh, lim.shank)


def _swing_bounds(lim: LegLimits, step: Any) -> list[Any]:
    """Lower bounds [s] of a swing ``step`` [m] long: the hip pitch turning the leg through the step
    (``_hip_turn``) and the knee bending to lift the foot ``lift`` then straightening (two moves),
    each at its servo's torque and speed (``_move_bounds``)."""
    knee = [2 * b for b in _move_bounds(_knee_bend(lim), lim.knee_speed, lim.knee_torque, lim.shank_inertia,
                                        lim.knee_droop, lim.knee_friction)]
    return _move_bounds(_hip_turn(lim, step), lim.hip_speed, lim.hip_torque, lim.leg_inertia, lim.hip_droop,
                        lim.hip_friction) + knee


def swing_time(lim: LegLimits, step: float) -> float:
    """[s] The shortest swing of a step ``step`` [m] long: the largest of ``_swing_bounds``."""
    return float(swing_times(lim, np.array([abs(step)]))[0])


def swing_times(lim: LegLimits, steps: np.ndarray) -> np.ndarray:
    """``swing_time`` of many steps [m] at once (numpy: a motor's exact move solved for all together)."""
    steps = np.abs(np.asarray(steps, dtype=float))
    hip = 2 * np.arcsin(np.clip(steps / (2 * lim.leg), -1.0, 1.0))

    def bounds(angle, speed, torque, inertia, droop, friction):
        if droop > 0 and inertia > 0 and math.isfinite(torque):
            if torque <= friction:
                return np.full(np.shape(angle), math.inf)
            return np.asarray(move_time(angle, torque - friction, droop, inertia), dtype=float)
        out = np.asarray(angle, dtype=float) / speed if speed > 0 else np.full(np.shape(angle), math.inf)
        if inertia > 0 and math.isfinite(torque):
            out = np.maximum(out, 2 * np.sqrt(np.asarray(angle) * inertia / torque + 1e-12))
        return out
    knee = 2 * bounds(np.array([_knee_bend(lim)]), lim.knee_speed, lim.knee_torque, lim.shank_inertia, lim.knee_droop,
                      lim.knee_friction)[0]
    swing = np.maximum(bounds(hip, lim.hip_speed, lim.hip_torque, lim.leg_inertia, lim.hip_droop, lim.hip_friction), knee)
    return np.maximum(swing, 1e-3)


def lipm_phase_function() -> ca.Function:
    """Named block ``lipm_phase``: (x0, v0, p, t, omega) -> (x1, v1), the LIPM with its ZMP held at p
    for t seconds, exactly (x - p)'' = omega^2 (x - p)."""
    x0, v0, p, t, w = (ca.SX.sym(n) for n in ("x0", "v0", "p", "t", "omega"))
    c, s = ca.cosh(w * t), ca.sinh(w * t)
    x1 = p + (x0 - p) * c + v0 / w * s
    v1 = (x0 - p) * w * s + v0 * c
    return ca.Function("lipm_phase", [x0, v0, p, t, w], [x1, v1], ["x0", "v0", "p", "t", "omega"], ["x1", "v1"])


def one_step_capture(lim: LegLimits, step: float | None = None) -> float:
    """The closed form [m/s]: the largest Delta v one step of length ``step`` absorbs, the ZMP at the
    sole's edge b through the shortest swing T_s(step), captured on the new sole's edge:
    omega (b + step e^{-omega T_s}). Without ``step``: the best step up to the reach (a dense grid)."""
    w = lim.omega
    if step is not None:
        return w * (lim.zmp_front() + step * math.exp(-w * swing_time(lim, step)))
    steps = np.linspace(0.0, lim.reach, 2001)
    return float(np.max(w * (lim.zmp_front() + steps * np.exp(-w * swing_times(lim, steps)))))


def push_bound(lim: LegLimits, steps: int = 3) -> dict[str, Any]:
    """The largest forward Delta v [m/s] the LIPM absorbs with up to ``steps`` steps (trajectory
    optimisation; a push from behind: backward is the same with the sole's back edge, see
    :func:`push_bounds`), the plan that does it, and the closed form for one step beside it."""
    phase = lipm_phase_function()
    opti = ca.Opti()
    dv = opti.variable()
    w = lim.omega
    x, v = 0.0, dv                     # the CoM over the stance ankle, pushed
    foot = 0.0
    front, back = lim.zmp_front(), lim.zmp_back()
    plan = []
    guess_foot = 0.0
    for i in range(steps):
        t = opti.variable()
        p = opti.variable()
        step = opti.variable()
        opti.subject_to(opti.bounded(foot - back, p, foot + front))
        opti.subject_to(opti.bounded(0.0, step, lim.reach))
        # the swing's hip turn through the step and the knee's lift, at the servos' torque and speed
        for low in _swing_bounds(lim, step):
            opti.subject_to(t >= low)
        opti.subject_to(t <= 1.0)                 # a longer swing never helps (and e^{omega t} conditions badly)
        x, v = phase(x, v, p, t, w)
        foot = foot + step
        plan.append((t, p, step))
        opti.set_initial(t, swing_time(lim, lim.reach))
        opti.set_initial(p, guess_foot + front)
        opti.set_initial(step, lim.reach)
        guess_foot += lim.reach
    # captured: the capture point on the last sole
    opti.subject_to(x + v / w <= foot + front)
    opti.subject_to(dv >= 0)
    opti.minimize(-dv)
    opti.set_initial(dv, one_step_capture(lim))
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "max_iter": 3000, "tol": 1e-9})
    try:
        sol = opti.solve()
    except RuntimeError as exc:       # dv = 0 is always feasible: a failure is numbers the solver cannot take
        from ..errors import UserError
        why = str(exc).strip().splitlines()[-1] if str(exc).strip() else "no reason given"
        raise UserError(f"the bound's optimisation failed ({why}): a robot whose servos cannot swing a leg "
                        f"(stall torque {lim.hip_torque:.3g} / {lim.knee_torque:.3g} N m at hip / knee, swing "
                        f"{swing_time(lim, lim.reach):.3g} s) or whose soles carry no ZMP gives it no room") from None
    return {"delta_v_mps": float(sol.value(dv)), "steps": steps,
            "plan": [{"swing_s": float(sol.value(t)), "zmp_m": float(sol.value(p)), "step_m": float(sol.value(s))}
                     for t, p, s in plan],
            "one_step_closed_form_mps": one_step_capture(lim)}


def push_bounds(lim: LegLimits, steps: int = 3) -> dict[str, Any]:
    """From behind (the robot pushed forward) and from the front (pushed backward): the backward
    case is the forward one with the sole's back edge in front."""
    import dataclasses
    behind = push_bound(lim, steps)
    mirrored = dataclasses.replace(lim, sole_front=lim.sole_back, sole_back=lim.sole_front)
    front = push_bound(mirrored, steps)
    return {"from_behind": behind, "from_the_front": front}


def speed_bound(lim: LegLimits) -> dict[str, Any]:
    """The largest sustained forward speed [m/s]: step / swing_time(step) over steps up to the
    reach (a periodic LIPM gait with instantaneous double support), and its Froude number."""
    steps = np.linspace(lim.reach / 200, lim.reach, 200)
    speeds = steps / swing_times(lim, steps)
    k = int(np.argmax(speeds))
    v = float(speeds[k])
    return {"speed_mps": v, "step_m": float(steps[k]), "period_s": float(swing_time(lim, steps[k])),
            "froude": v * v / (GRAVITY * lim.z_c)}


def leg_limits(robot: Any, lift: float, reach_ratio: float = 0.8) -> LegLimits:
    """The bound's numbers of a loaded robot (``tuner.robots.load_robot``): mass, walking CoM height,
    soles, legs at the crouch, the leg servos' speed and torque."""
    from ..robots.mjcf_geometry import CROUCH
    model = robot.model()
    mass = float(np.sum(model.body_mass))
    leg = robot.leg
    z_c = CROUCH * leg.max_hip_height + leg.hip_offset_z + leg.com_above_pelvis
    length = float(robot.foot_size[0])
    centre = float(getattr(leg, "sole_forward", 0.0))
    servo = {k: robot.servos[robot.joint_map[f"l_{k}"][0]] for k in ("hip_pitch", "knee", "ankle_pitch")}
    crouch = CROUCH * (leg.thigh + leg.shank)
    from ..robots.mjcf_geometry import leg_masses
    _, m_thigh, m_calf, _ = leg_masses(robot)
    # point masses (ours): the thigh's at its middle, the calf and foot's at the shank's middle
    shank_inertia = m_calf * (leg.shank / 2) ** 2 + servo["knee"].armature
    leg_inertia = (m_thigh * (leg.thigh / 2) ** 2 + m_calf * (leg.thigh + leg.shank / 2) ** 2
                   + servo["hip_pitch"].armature)
    # a motor's torque-speed line: the torque it loses per rad/s (back-EMF and viscous friction), and
    # its dry friction; none for a pd servo (its stall torque holds at any speed)
    droop = {k: (s.back_emf + s.damping if s.back_emf > 0 else 0.0) for k, s in servo.items()}
    dry = {k: (s.frictionloss if s.back_emf > 0 else 0.0) for k, s in servo.items()}
    return LegLimits(mass=mass, z_c=z_c, sole_front=length / 2 + centre, sole_back=length / 2 - centre,
                     reach=reach_ratio * (leg.thigh + leg.shank), leg=crouch, thigh=leg.thigh, shank=leg.shank,
                     crouch_height=crouch, hip_speed=servo["hip_pitch"].speed, knee_speed=servo["knee"].speed,
                     ankle_torque=servo["ankle_pitch"].torque, knee_torque=servo["knee"].torque, lift=lift,
                     hip_torque=servo["hip_pitch"].torque, leg_inertia=leg_inertia, shank_inertia=shank_inertia,
                     hip_droop=droop["hip_pitch"], knee_droop=droop["knee"], hip_friction=dry["hip_pitch"],
                     knee_friction=dry["knee"])


def bottle_figures(delta_v: float, bottle_mass: float, robot_mass: float, rope: float) -> dict[str, float | None]:
    """What a Delta v [m/s] absorbed means in the challenge: the bottle's momentum at impact (an
    inelastic meeting: p_B = (m_B + m_R) Delta v), its drop H = (p_B / m_B)^2 / (2 g) and the release
    distance D = sqrt(L^2 - (L - H)^2) (None when H exceeds the rope: no release reaches it)."""
    momentum = (bottle_mass + robot_mass) * delta_v
    drop = (momentum / bottle_mass) ** 2 / (2 * GRAVITY)
    distance = math.sqrt(rope * rope - (rope - drop) ** 2) if drop <= rope else None
    return {"momentum_Ns": momentum, "drop_m": drop, "distance_m": distance}


def robot_bound(robot: Any, surface: Any, bottle_kg: float, rope: float, steps: int) -> dict[str, Any]:
    """``challenge bound``'s figures for a loaded robot and surface: the model's numbers, the pushes
    from behind and from the front with what they mean in the challenge (momentum, release
    distance, the 2025 rules' M where within them), the forward speed, what is left out, and which
    of the surface's terms the bound uses (its layer's height sets the swing's lift; the rest of the
    turf, its friction, stiffness and drag, is left out: a rigid floor)."""
    from .rules import rank_2025
    layer = float(getattr(surface, "layer_height", 0.0))
    lift = max(0.02, layer + 0.01)
    lim = leg_limits(robot, lift)
    swing = swing_time(lim, lim.reach)
    if not math.isfinite(swing) or swing > 5.0:
        from ..errors import UserError
        raise UserError(f"robot {robot.name}: its hip and knee servos cannot swing a leg (stall torque "
                        f"{lim.hip_torque:.3g} / {lim.knee_torque:.3g} N m, unloaded speed {lim.hip_speed:.3g} / "
                        f"{lim.knee_speed:.3g} rad/s): no step, so no bound")
    out: dict[str, Any] = {
        "robot": robot.name, "surface": surface.name, "bottle_kg": bottle_kg, "rope_m": rope,
        "model": {"mass_kg": lim.mass, "z_c_m": lim.z_c, "zmp_front_m": lim.zmp_front(), "zmp_back_m": lim.zmp_back(),
                  "reach_m": lim.reach, "lift_m": lift, "hip_speed_radps": lim.hip_speed,
                  "knee_speed_radps": lim.knee_speed, "hip_droop_Nms": lim.hip_droop, "knee_droop_Nms": lim.knee_droop},
        "surface_terms": (f"the lift: {surface.name}'s layer of {layer * 1000:.0f} mm cleared by 10 mm (at least 20 mm); "
                          f"its friction, stiffness and drag are left out (a rigid floor)"),
        "leaves_out": list(LEAVES_OUT)}
    for side, b in push_bounds(lim, steps).items():
        fig = bottle_figures(b["delta_v_mps"], bottle_kg, lim.mass, rope)
        d = fig["distance_m"]
        within = d is not None and d <= 0.75 * rope
        fig["within_rules"] = within
        fig["M"] = rank_2025(rope, d, bottle_kg, lim.mass, lim.z_c, lim.z_c) if within else None
        out[side] = {**b, **fig}
    out["speed"] = speed_bound(lim)
    return out
