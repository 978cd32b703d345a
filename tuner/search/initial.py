"""A walk made for a team's robot (``gait-tuner init``, ours): the starting set and the study that
tunes it, from the robot's own model, each number saying where it came from.

The TLIPFM model takes the robot's masses (the paper's three: the upper body, the support leg's
thigh and its calf with the foot; the upper body is the robot less both legs, as TKU-X's 3.05 +
2 (0.2 + 0.75) = 4.95 kg), its CoM height at the walking crouch (hips at 0.85 the straight hip
height, the CoM above them by the model's own masses), a stance with the feet under the hips (at
least a sole's width and 10 mm apart), and a step no faster than the knees' servos carry: the
cycloid swing's highest foot speed, pi h_z / t_ssp, asks the knee for about that over the shorter
leg link, and the rule (ours) keeps it under half the knee servo's speed, so the single support
is at least pi h_z / (0.5 speed l) and the step that over TKU-X's share of single support
(0.34 / 0.64). The lift clears the surface's layer by 10 mm (at least 20 mm).

Servo gains, when nothing states them (a URDF has none; ``RobotModel.preset_gains``): a position
servo gives way by torque / kp, and the stance ankle holds the whole robot as an inverted pendulum
whose toppling stiffness is m g z_c [N m/rad]. The legs' kp is ``GAIN_MARGIN`` times that (ours:
TKU-X's MX-64 at 40 N m/rad is 4.3 times the built-in robot's 4.95 kg x g x 0.19 m; Rhoban's 7.6 kg
Sigmaban, 4 x 23.4 = 94, walks placo's example at 80 and falls at the MX-64 preset's 40), kv keeps
the preset's damping ratio (it grows as the square root of kp), rounded to 5 and 0.05.

The study searches around those numbers for the purpose asked: ``match`` (the online engine on
match walks, ``scenario:``), ``speed`` (a table on speed staircases, ``speed:``), ``push`` (the
engine in the push-recovery challenge, ``challenge:``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gaits import TlipfmParams
from gaits.engine import EngineParams

from ..servos import MotorServo
from ..errors import UserError
from ..robots.mjcf_geometry import leg_masses

__all__ = ["InitialWalk", "initial_walk", "PURPOSES", "leg_masses", "leg_gains", "GAIN_MARGIN", "falls_standing"]

PURPOSES = ("match", "speed", "push")
#: TKU-X's Table 2 step timing, as shares of the step (t1, t2 of T = 0.64 s)
T1_SHARE, T2_SHARE = 0.15 / 0.64, 0.49 / 0.64
#: the knee may be asked half its servo's speed by the swing (ours: headroom for the stance, the sway)
KNEE_SHARE = 0.5
#: the longest step the start set plans for the top speed [thigh + shank] and the margin on that speed (ours)
REACH_MAX, SPEED_MARGIN = 0.6, 1.1
#: the most of the knee servo's speed a swing may ask when the top speed needs short periods (ours)
KNEE_MAX = 0.9
#: the knee's shares of speed at which the study also tries the start (shorter periods; ours)
LADDER_SHARES = (0.7, 0.9)
#: the share of each servo's speed the engine's targets may move (``EngineParams.servo_share``; ours)
SERVO_SHARE = 0.95
#: the legs' kp as a multiple of the robot's toppling stiffness m g z_c (ours, see the module docstring)
GAIN_MARGIN = 4.0
#: a servo that gives way more than this on one foot in the start pose [rad] has the engine put its give
#: and its lag back into the targets (``engine.load_share``, ``lag_share``: gaits/engine/servo_load.py; ours:
#: the built-in robot's knee gives 6.8 deg on BAM's MX-64 and walks its sets without; Wolfgang-OP's 13.7
#: deg on Bit-Bots' training servos falls in every direction without)
GIVE_LIMIT = math.radians(8.0)
#: the start's shares of the give and the lag (ours: the best of Wolfgang-OP's first study on Bit-Bots'
#: training servos, docs/walk.md) and the ranges searched
LOAD_SHARE, LAG_SHARE = 0.6, 0.1
LOAD_RANGE, LAG_RANGE = (0.3, 1.2), (0.0, 0.6)
#: such a robot's step lasts at least this many times its knee servo's lag, damping / kp (ours: Wolfgang-OP
#: on Bit-Bots' training servos, 81 ms, walks at 0.30-0.34 s and falls at the knee rule's 0.25 s)
LAG_STEPS = 4.0
#: ... and the study searches no step shorter than this many lags (ours)
LAG_STEPS_MIN = 3.0
#: the single support a study draws at least, of its shortest period, as far as t2's range still reaches
#: TKU-X's share of that period (ours: without it a study of Wolfgang-OP on Bit-Bots' servos kept a
#: "walk" with 7 ms of single support, t2 drawn just past t1, that never stepped)
SSP_MIN = 0.3


@dataclass
class InitialWalk:
    params: TlipfmParams
    engine: EngineParams | None
    study: dict
    sources: dict[str, str]
    #: the legs' servo fields to write into the robot's map (empty: the file's or the map's own are kept)
    servo: dict[str, float] = field(default_factory=dict)
    servo_source: str = ""
    #: the start at shorter periods, tried first too (the study's ``baselines``): (the knee's share, set).
    #: A start whose period is too long for the robot's balance (Bit-Bots' Wolfgang-OP falls sideways at
    #: the knee rule's 0.72 s, its hip roll servos at their torque, and walks at 0.45 s) leaves a study
    #: no trial that stands to learn from; these are other places to start (on Wolfgang they fell too:
    #: docs/robots.md).
    ladder: list[tuple[float, TlipfmParams]] = field(default_factory=list)

    def value(self, name: str) -> float:
        """A number ``sources`` explains: the start set's, or its engine's."""
        return getattr(self.params, name) if hasattr(self.params, name) else getattr(self.engine, name)


def initial_walk(robot: Any, robot_ref: str, surface: Any, purpose: str = "match", name: str | None = None,
                 start_file: str = "start.yaml", top_speed: float = 0.2) -> InitialWalk:
    """The starting set (and its engine) and the study document for ``robot`` on ``surface``;
    ``top_speed`` [m/s] the fastest forward walk asked of it (the study's walks ask it too)."""
    if not (math.isfinite(top_speed) and 0.05 <= top_speed <= 1.0):
        raise UserError(f"--speed {top_speed!r} m/s: expected a number in [0.05, 1.0] m/s")
    from ..robots.mjcf_geometry import CROUCH
    if purpose not in PURPOSES:
        raise UserError(f"--for {purpose!r}: expected one of {', '.join(PURPOSES)}")
    leg = robot.leg
    upper, m_t, m_c, sources = leg_masses(robot)
    if upper <= 0.05:
        raise UserError(f"robot {robot.name}: its legs weigh as much as the whole robot: the upper body's mass "
                        f"({upper:.3f} kg) leaves no three-mass model")
    z_c = CROUCH * leg.max_hip_height + leg.hip_offset_z + leg.com_above_pelvis
    sources["z_c"] = (f"the hips at {CROUCH} x the straight hip height {leg.max_hip_height * 1000:.0f} mm, the CoM "
                      f"{(leg.hip_offset_z + leg.com_above_pelvis) * 1000:.0f} mm above them (the model's masses)")
    width = float(robot.foot_size[1])
    half = max(leg.hip_offset_y, (width + 0.01) / 2)
    sources["half_width"] = (f"the feet under the hips ({leg.hip_offset_y * 1000:.0f} mm each side)"
                             if half == leg.hip_offset_y else
                             f"the soles {width * 1000:.0f} mm wide and 10 mm apart (wider than the hips)")
    knee = robot.servos.get(robot.joint_map["l_knee"][0])
    speed = float(knee.speed) if knee is not None else 6.5
    layer = float(getattr(surface, "layer_height", 0.0))
    h_z = max(0.02, layer + 0.01)
    sources["h_z"] = f"the {surface.name} layer ({layer * 1000:.0f} mm) cleared by 10 mm, at least 20 mm"
    lever = min(leg.thigh, leg.shank)
    ssp = math.pi * h_z / (KNEE_SHARE * speed * lever)
    period = round(max(0.25, ssp / (T2_SHARE - T1_SHARE)), 3)
    sources["period"] = (f"the knee servo's {speed:g} rad/s: the swing's foot speed pi h_z / t_ssp over the "
                         f"{lever * 1000:.0f} mm link at most half of it, t_ssp >= {ssp:.3f} s")
    legs = leg.thigh + leg.shank
    longest = round(REACH_MAX * legs / (SPEED_MARGIN * top_speed), 3)
    if period > longest:
        # the walk's top speed needs shorter steps than the knee rule's: the swing asks more of the knee
        share = KNEE_SHARE * period / longest
        if share > KNEE_MAX:
            raise UserError(f"robot {robot.name}: {top_speed:g} m/s forward needs a step every {longest:.3f} s "
                            f"(steps of {REACH_MAX:g} leg lengths, {legs * 1000:.0f} mm), whose {h_z * 1000:.0f} mm "
                            f"lift asks the knee servo for {share * speed:.1f} rad/s of its {speed:g}: ask less "
                            f"speed of the walk, or say the servos' speed in the map (servo: {{legs: {{speed: ...}}}})")
        period = longest
        sources["period"] = (f"steps of at most {REACH_MAX:g} leg lengths at {SPEED_MARGIN:g} x the walk's "
                             f"{top_speed:g} m/s top speed; its swing (pi h_z / t_ssp over the {lever * 1000:.0f} mm "
                             f"link) asks the knee for {share:.0%} of its servo's {speed:g} rad/s")
    reach = min(0.8, max(0.45, round(SPEED_MARGIN * top_speed * period / legs, 3)))
    sources["reach_forward"] = (f"the longest step ahead, {SPEED_MARGIN:g} x {top_speed:g} m/s x the period over "
                                f"the legs' {legs * 1000:.0f} mm (at least TKU-X's 0.45)")
    try:
        params = TlipfmParams(mass_upper=round(upper, 4), mass_thigh=round(m_t, 4), mass_calf=round(m_c, 4),
                              z_c=round(z_c, 4), half_width=round(half, 4), h_z=round(h_z, 4), period=period,
                              t1=round(T1_SHARE * period, 4), t2=round(T2_SHARE * period, 4), step_length=0.0,
                              d1=0.0, d2=0.0, a=0.004, reach_forward=reach)
    except Exception as exc:  # noqa: BLE001 - the derived numbers outside TLIPFM's ranges
        raise UserError(f"robot {robot.name}: its walk model does not fit TLIPFM's ranges: {exc}") from None
    servo, servo_source = leg_gains(robot, upper + 2 * (m_t + m_c), z_c)
    # the engine caps its targets' moves at 95 % of each servo's speed: its tables play on the servos
    engine = None if purpose == "speed" else EngineParams(idle="step" if purpose == "push" else "stand",
                                                          servo_share=SERVO_SHARE)
    give = None if engine is None or servo else servo_give(robot, params)
    lag = knee_lag(robot)
    if give is not None and give[1] > GIVE_LIMIT:
        engine = engine.replace(load_share=LOAD_SHARE, lag_share=LAG_SHARE)
        if LAG_STEPS * lag > period:
            period = round(LAG_STEPS * lag, 3)
            params = params.replace(period=period, t1=round(T1_SHARE * period, 4), t2=round(T2_SHARE * period, 4))
            sources["period"] = (f"{LAG_STEPS:g} x the knee servo's lag, damping / kp = {lag * 1000:.0f} ms (a servo "
                                 f"that gives way this far needs a step several times its lag to follow it)")
        sources["load_share"] = (f"the servos give way {math.degrees(give[1]):.1f} deg ({give[0]}) on one foot in "
                                 f"the start pose, more than {math.degrees(GIVE_LIMIT):g}: the engine puts "
                                 f"{LOAD_SHARE:g} of it back into its targets, and leads them by {LAG_SHARE:g} of "
                                 f"their lag (damping / kp)")
    name = name or f"{robot.name}-{surface.name}-{purpose}"
    # the shortest period searched asks the knee KNEE_MAX of its speed for the start's lift: the knee
    # rule's period is a ceiling for the swing, not a good step for every robot (Bit-Bots' Wolfgang-OP,
    # 6.1 kg, falls sideways at its 0.72 s, its hip roll servos at their torque, and walks at 0.45 s)
    # k / share: the period whose swing asks the knee that share of its servo's speed
    k = math.pi * h_z / ((T2_SHARE - T1_SHARE) * lever * speed)
    fastest = k / KNEE_MAX
    # t1 and t2 range over TKU-X's shares of every period searched
    span = _around(period, min(1.0, fastest / period), 1.1, 0.1, 3.0)
    if engine is not None and engine.load_share > 0:
        # a servo that gives way this far cannot follow a step shorter than a few of its lags
        span["low"] = round(min(max(span["low"], LAG_STEPS_MIN * lag), period), 4)
    # t1 and t2 searched as shares of the period drawn (of: period): every draw has t1 < t2 < period (as
    # absolute times, 6-20 % of a study's draws put t2 past a short period and were rejected) and a
    # single support (t2 - t1) of at least SSP_MIN of its period
    t1 = {"low": round(T1_SHARE * 0.5, 4), "high": round(T1_SHARE * 1.5, 4), "of": "period"}
    t2 = {"low": round(max(T2_SHARE * 0.85, t1["high"] + SSP_MIN), 4), "high": round(min(T2_SHARE * 1.15, 0.95), 4),
          "of": "period"}
    space = {"period": span, "t1": t1, "t2": t2,
             "h_z": _around(h_z, 0.6, 1.3, 0.005, 0.1),
             "z_c": _around(z_c, 0.85, 1.05, 0.08, 0.5), "half_width": _around(half, 0.9, 1.3, 0.02, 0.12),
             # the longest step [leg lengths] sets the envelope's forward speed (reach / period): searched,
             # never below what the top speed needs at the starting period
             "reach_forward": {"low": min(reach, 0.76), "high": 0.8}}
    study: dict[str, Any] = {
        "name": name,
        "description": f"made by gait-tuner init for {robot.name} on {surface.name} ({purpose}): the starting "
                       f"set's numbers from the robot's own model (see the set's description)",
        "robot": robot_ref, "surfaces": [surface.name], "gait": "tlipfm", "base": start_file}
    if engine is not None and engine.load_share > 0:
        space.update({"engine.load_share": {"low": LOAD_RANGE[0], "high": LOAD_RANGE[1]},
                      "engine.lag_share": {"low": LAG_RANGE[0], "high": LAG_RANGE[1]}})
    if purpose == "match":
        space.update({"engine.k_vel": {"low": 0.0, "high": 1.0}, "engine.replan_error": {"low": 0.03, "high": 0.15},
                      "engine.step_weight": {"low": 0.001, "high": 1.0, "log": True},
                      "engine.accel_vx": {"low": 0.2, "high": 1.5}})
        study.update({"engine": {"servo_share": SERVO_SHARE}, "space": space,
                      # a first study's match walks, milder than the shipped ones' and with room to fall
                      # (a trial below min_survival stops at once and teaches the sampler nothing)
                      # servo_share: a set whose walks ask a servo for more than its speed is infeasible
                      # (the engine caps at SERVO_SHARE; a searched engine.servo_share of 0 would not)
                      "scenario": {"walks": 6, "min_survival": 0.5, "servo_share": 1.0, "duration": 12.0,
                                   "forward": top_speed,
                                   "backward": 0.1, "sideways": 0.05, "turn": 0.5}})
    elif purpose == "push":
        space.update({"engine.k_vel": {"low": 0.0, "high": 1.0}, "engine.replan_error": {"low": 0.03, "high": 0.15},
                      "engine.step_weight": {"low": 0.001, "high": 1.0, "log": True}})
        study.update({"engine": {"idle": "step", "servo_share": SERVO_SHARE}, "space": space,
                      "challenge": {"seeds": [0, 1, 2]}})
    else:
        study.update({"space": space, "speed": {"directions": {"forward": {"top": 0.3, "weight": 1.0},
                                                               "backward": {"top": 0.2, "weight": 1.0},
                                                               "left": {"top": 0.1, "weight": 2.0},
                                                               "turn_left": {"top": 1.0, "weight": 0.2}}}})
    study.update({"trials": 200, "enqueue": ["casadi", "baselines"], "sampler_seed": 0})
    # the start at shorter periods, tried first too
    # (no shorter than the start's own 0.25 s floor)
    ladder = []
    for share in LADDER_SHARES:
        rung = round(k / share, 3)
        if 0.25 <= rung < period - 1e-3:
            ladder.append((share, params.replace(period=rung, t1=round(T1_SHARE * rung, 4),
                                                 t2=round(T2_SHARE * rung, 4))))
    return InitialWalk(params, engine, study, sources, servo, servo_source, ladder)


def knee_lag(robot: Any) -> float:
    """The left knee servo's lag [s]: its velocity terms over its position gain (0 without a servo)."""
    knee = robot.servos.get(robot.joint_map["l_knee"][0])
    if knee is None:
        return 0.0
    p = knee.pieces()
    return (p.kv + p.back_emf + p.damping) / p.kp if p.kp > 0 else 0.0


def servo_give(robot: Any, params: TlipfmParams) -> tuple[str, float] | None:
    """The joint that gives way most (our name) and how far [rad], standing on one foot in the start
    pose of ``params`` (``WalkEngine.predicted_give``); None for a robot that states no servo gains."""
    import gaits
    from gaits.engine import WalkEngine
    limits = gaits.family("tlipfm").step_limits(params, robot)
    give = WalkEngine(params, EngineParams(), robot, robot.sim.control_period, limits).predicted_give()
    if give is None:
        return None
    i = int(np.argmax(np.abs(give)))
    return gaits.JOINT_NAMES[i], float(abs(give[i]))


def leg_gains(robot: Any, mass: float, z_c: float) -> tuple[dict[str, float], str]:
    """The legs' gains sized to the robot's weight when its gains are a preset's (see the module
    docstring), with the sentence saying so; ({}, why not) otherwise. A dc-motor servo gets the P
    register that gives that stiffness at its voltage (its back-EMF damps it); a pd servo a kp and
    a kv that keeps the preset's damping ratio."""
    if "legs" not in getattr(robot, "preset_gains", ()):
        return {}, "the robot's own (its file or its map states them)"
    preset = robot.servos[robot.joint_map["l_knee"][0]]
    stiffness = mass * 9.81 * z_c
    kp = max(5.0, 5.0 * round(GAIN_MARGIN * stiffness / 5.0))
    head = (f"sized to the weight (nothing states the legs' gains): {GAIN_MARGIN:g} x the toppling stiffness "
            f"m g z_c = {mass:.2f} kg x 9.81 x {z_c:.3f} m = {stiffness:.1f} N m/rad")
    if isinstance(preset, MotorServo):
        p_gain = round(kp / (preset.gain / preset.p_gain), 1)
        return {"p_gain": float(p_gain)}, (f"{head}: kp {kp:g} N m/rad is P {p_gain:g} on the {preset.preset or 'servo'}'s "
                                           f"firmware at {preset.voltage:g} V")
    kv = round(preset.kv * math.sqrt(kp / preset.kp), 2)
    why = (f"{head}; kv {kv:g} keeps the preset's damping ratio (its kp {preset.kp:g}, kv {preset.kv:g})")
    return {"kp": float(kp), "kv": float(kv)}, why


def _around(value: float, lo: float, hi: float, floor: float, ceil: float) -> dict[str, float]:
    """A search range from ``lo`` to ``hi`` times ``value``, within the parameter's [floor, ceil]."""
    return _range(value * lo, value * hi, floor, ceil)


def _range(low: float, high: float, floor: float, ceil: float) -> dict[str, float]:
    """A search range from ``low`` to ``high`` within the parameter's [floor, ceil]."""
    low, high = max(floor, low), min(ceil, high)
    return {"low": round(low, 4), "high": round(max(high, low * 1.05), 4)}


def falls_standing(robot_ref: str, surface: Any, start: str, seconds: float = 3.0) -> str | None:
    """How the robot falls standing in a start set's pose with no command (the engine holding it for
    ``seconds``), or None when it stands (or the set is a table, which has no standing). A robot that
    falls standing leaves a study nothing to keep: its servos cannot hold its weight (ours)."""
    import numpy as np

    from ..params_io import resolve_drive
    from ..sim.cache import simulator
    drive = resolve_drive(start, None, command=np.zeros(3))
    if not drive.online:
        return None
    sim = simulator(robot_ref, surface)
    trace = sim.run(drive.controller(sim.robot, sim.control_period), **{**drive.run_options(), "duration": seconds})
    return None if trace.survived else str(trace.reason)


#: [s] how long init's held-out match stream asks (ours: five of the study's 12 s walks)
HELD_OUT_S = 60.0


def held_out_stream(scenario: dict[str, Any], what: str, seed: int = 0) -> str:
    """A match stream (``t,vx,vy,wz`` CSV) drawn from a study's ``scenario:`` speeds, as long as
    :data:`HELD_OUT_S`, from the evaluation draws (never a walk the study tunes on): the stream to
    hold its best set to (``robustness --commands``)."""
    from ..sim.randomisation import EVALUATE
    from ..sim.match_walks import SCENARIO_FIELDS, MatchDistribution, draw_scenario
    fields = {k: v for k, v in scenario.items() if k in SCENARIO_FIELDS}
    fields.update(duration=HELD_OUT_S, push_rate=0.0)
    d = MatchDistribution(**fields)
    stream, _ = draw_scenario(d, seed, namespace=EVALUATE)
    rows = [f"# a held-out match stream of {what} (gait-tuner init): segments of {d.segment_min:g}-{d.segment_max:g} s "
            f"up to {d.forward:g} m/s forward, {d.backward:g} back,",
            f"# {d.sideways:g} sideways, {d.turn:g} rad/s, and stops, drawn as the study's walks are but from the "
            f"evaluation seeds (seed {seed}); t [s], vx [m/s], vy [m/s], wz [rad/s]", "t,vx,vy,wz"]
    for t, c in zip(stream.t, stream.commands):
        rows.append(",".join(f"{v:.4g}" for v in (t, *c)))
    return "\n".join(rows) + "\n"
