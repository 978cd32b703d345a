"""``gait-tuner robot check MAP``: what was derived from a robot file and from where, and a stand test.

The stand test holds the walking crouch (hips at ``CROUCH`` x the straight hip height, soles
under the hips, the CoM over the soles' centre) for ``duration`` seconds on the rigid floor
and reports whether the robot stays up, its lean, where the CoM ends relative to the feet,
and how much of the robot's weight the sole sensors see (the whole of it when the force
sensing covers the whole sole).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gaits import GaitTrajectory
from gaits.trajectory import assemble

from ..robots.mjcf_geometry import CROUCH
from ..robots.robot_model import GROUPS, RobotModel, joint_group

__all__ = ["robot_report", "stand_test", "stand_trajectory", "format_report"]


def stand_trajectory(robot: RobotModel, duration: float, dt: float) -> GaitTrajectory:
    """The walking crouch held still for ``duration`` [s]: soles under the hips, CoM over them."""
    L = robot.leg
    n = int(round(duration / dt)) + 1
    t = np.arange(n) * dt
    y = L.hip_offset_y + L.sole_outward
    feet = [np.tile([0.0, s * y, 0.0], (n, 1)) for s in (1, -1)]
    pelvis = np.tile([0.0, 0.0, CROUCH * L.max_hip_height + L.hip_offset_z], (n, 1))
    return assemble("stand", t, L, p_world_pelvis=pelvis, p_world_foot_l=feet[0], p_world_foot_r=feet[1],
                    support=np.zeros(n, dtype=int), meta={"cycle_time": 1.0})


def stand_test(robot: RobotModel, duration: float = 2.0) -> dict[str, Any]:
    """Stand the robot in the walking crouch on the rigid floor; what happened, as numbers."""
    from ..sim.rollout import Simulator
    from ..sim.surfaces import SURFACES
    sim = Simulator(robot, SURFACES["rigid"])
    trace = sim.rollout(stand_trajectory(robot, duration, sim.control_period))
    weight = float(np.sum(sim.model.body_mass)) * 9.81
    last = max(1, int(round(0.5 / sim.control_period)))
    feet_x = (trace.p_sole_l[-last:, 0] + trace.p_sole_r[-last:, 0]) / 2
    feet_y = (trace.p_sole_l[-last:, 1] + trace.p_sole_r[-last:, 1]) / 2
    sag = np.mean(trace.q[-last:] - trace.q_cmd[-last:], axis=0)
    k = int(np.argmax(np.abs(sag)))
    tau = float(np.mean(trace.tau[-last:, k]))
    return {"stays_up": trace.survived, "reason": trace.reason,
            "duration_s": float(trace.t[-1]),
            "pitch_deg": float(np.degrees(np.mean(trace.pitch[-last:]))),
            "roll_deg": float(np.degrees(np.mean(trace.roll[-last:]))),
            "com_ahead_of_feet_mm": float(1000 * np.mean(trace.p_com[-last:, 0] - feet_x)),
            "com_left_of_feet_mm": float(1000 * np.mean(trace.p_com[-last:, 1] - feet_y)),
            "sensed_weight_fraction": float(np.mean(trace.force[-last:].sum(axis=1)) / weight),
            "largest_sag": {"joint": trace.joint_names[k], "deg": float(np.degrees(sag[k])), "torque_nm": tau}}


def _servo_groups(robot: RobotModel) -> dict[str, dict[str, Any]]:
    ours_of = {theirs: ours for ours, (theirs, _) in robot.joint_map.items()}
    out = {}
    for g in GROUPS:
        joints = [j for j in robot.servos if joint_group(ours_of.get(j)) == g]
        if not joints:
            continue
        fields = {}
        for f in ("kp", "kv", "torque", "speed", "armature", "damping", "frictionloss", "back_emf"):
            vals = sorted({getattr(robot.servos[j], f) for j in joints})
            fields[f] = vals[0] if len(vals) == 1 else [vals[0], vals[-1]]
        fields["law"] = sorted({robot.servos[j].law for j in joints})
        out[g] = {"joints": joints, **fields, "source": robot.sources.get(f"servos.{g}", "")}
    return out


def _leg_ik(leg: Any) -> dict[str, Any]:
    """Which IK the legs get and why; for the numerical one, its time per leg and tick on this
    machine (p99 over a crouched stepping cycle of 400 ticks, each warm-started from the one before:
    as the walk engine calls it; a figure, not a check: a loaded machine reads more)."""
    if leg.chains is None:
        return {"kind": leg.ik, "why": "the hip's three axes meet, the ankle's two meet, and the knee and ankle "
                                       "lie straight below the hip at the zero pose: the papers' closed form",
                "p99_ms": None}
    import time
    from gaits.leg_kinematics import leg_ik_pose
    times = []
    for side in (1, -1):
        hip = leg.hip_in_pelvis(side)
        q = None
        for k in range(400):
            ph = 2 * np.pi * k / 100
            target = hip + np.array([0.04 * np.sin(ph), 0.0, -0.85 * leg.max_hip_height + 0.02 * max(np.sin(ph), 0)])
            t0 = time.perf_counter()
            try:
                q = leg_ik_pose(target, np.eye(3), leg, side, q)
            except ValueError:
                q = None
                continue
            times.append(time.perf_counter() - t0)
    return {"kind": leg.ik, "why": leg.chains.reason,
            "p99_ms": float(np.percentile(times, 99) * 1000) if times else None}


def robot_report(robot: RobotModel, *, stand: bool = True, duration: float = 2.0) -> dict[str, Any]:
    """Everything ``robot check`` shows, as plain data (strict-JSON friendly)."""
    model = robot.model()
    L = robot.leg
    soles = {}
    for i, (side, fname, hull, centre) in enumerate(zip(("left", "right"), robot.feet, robot.sole_hulls,
                                                        robot.soles)):
        length, width = robot.foot_size_of(i)
        soles[side] = {"body": fname, "centre_mm": [round(1000 * c, 2) for c in centre],
                       "size_mm": [round(1000 * length, 1), round(1000 * width, 1)],
                       "hull_mm": [[round(1000 * x, 2), round(1000 * y, 2)] for x, y in hull],
                       "source": robot.sources.get(f"sole.{side}", "built-in sole box"),
                       "touch_sensors": ("4 quadrants of the sole's bounding box, 2.5 mm past each edge"
                                         if getattr(robot, "foot_sensors", True) else
                                         "none on this robot (the map's foot_sensors: false): a controller gets "
                                         "no foot_force; the simulator's touch sites feed only its metrics")}
    report: dict[str, Any] = {
        "robot": robot.name, "map": robot.map_path,
        "mjcf": robot.mjcf_path or ("built-in" if robot.urdf_path is None else None), "urdf": robot.urdf_path,
        "mass_kg": float(np.sum(model.body_mass)), "bodies": int(model.nbody - 1),
        "leg_mm": {k: round(1000 * getattr(L, k), 2) for k in
                   ("hip_offset_x", "hip_offset_y", "hip_offset_z", "thigh", "shank", "ankle_height",
                    "sole_forward", "sole_outward")},
        "straight_hip_height_mm": round(1000 * L.max_hip_height, 2),
        "leg_ik": _leg_ik(L),
        "com_mm": {"forward": round(1000 * L.com_forward, 2), "lateral": round(1000 * L.com_lateral, 2),
                   "above_pelvis": round(1000 * L.com_above_pelvis, 2),
},
        "sources": dict(robot.sources),
        "joints": {ours: {"mjcf": robot.joint_map[ours][0], "sign": robot.joint_map[ours][1]}
                   for ours in robot.servo_joints},
        "held_joints": {j: round(robot.pose.get(j, 0.0), 4) for j in robot.servos
                        if joint_group({t: o for o, (t, _) in robot.joint_map.items()}.get(j)) != "legs"},
        "soles": soles, "servos": _servo_groups(robot),
        # what init, a study, robot export and bus serve refuse (the loop could not read the soles)
        "notes": list(robot.notes) + ([gap.split(": ", 1)[1]] if (gap := robot.sensing_gap()) else []),
        "sim": {"control_period_s": robot.sim.control_period, "timestep_s": robot.sim.timestep,
                "max_tilt_deg": robot.sim.max_tilt_deg, "min_height_ratio": robot.sim.min_height_ratio},
    }
    if stand:
        report["stand"] = stand_test(robot, duration)
    return report


def _fmt(v: Any) -> str:
    if isinstance(v, list):
        return f"{v[0] + 0.0:g}..{v[1] + 0.0:g}"
    return f"{v + 0.0:g}"


def format_report(r: dict[str, Any]) -> str:
    """The report as text for a terminal."""
    L, c = r["leg_mm"], r["com_mm"]
    lines = [f"robot {r['robot']}  (map {r['map'] or '-'}; " +
             (f"urdf {r['urdf']}, read into MJCF)" if r.get("urdf") else f"mjcf {r['mjcf']})"),
             f"  mass {r['mass_kg']:.3f} kg in {r['bodies']} bodies",
             f"leg geometry [{r['sources'].get('leg', '')}]",
             f"  hip offset y {L['hip_offset_y']:.1f} mm, hip below torso origin {L['hip_offset_z']:.1f} mm"
             + (f", hip ahead of torso origin {L['hip_offset_x']:+.1f} mm" if L.get("hip_offset_x") else "") + ", "
             f"thigh {L['thigh']:.1f} mm, shank {L['shank']:.1f} mm, ankle height {L['ankle_height']:.1f} mm "
             f"(straight-leg hip height {r['straight_hip_height_mm']:.1f} mm)",
             f"  sole centre {L['sole_forward']:+.1f} mm ahead of / {L['sole_outward']:+.1f} mm outboard of the ankle",
             f"  leg IK: {r['leg_ik']['kind']}: {r['leg_ik']['why']}"
             + (f" (p99 {r['leg_ik']['p99_ms']:.3f} ms a leg on this machine, warm-started)"
                if r["leg_ik"].get("p99_ms") is not None else ""),
             f"CoM [{r['sources'].get('com', '')}]",
             f"  {c['forward']:+.1f} mm ahead, {c['lateral']:+.1f} mm left, {c['above_pelvis']:+.1f} mm above "
             f"the torso origin; the gait plans the CoM, the pelvis follows",
             "joints (ours -> file, sign)"]
    items = [f"{o} -> {j['mjcf']} ({j['sign']:+d})" for o, j in r["joints"].items()]
    for k in range(0, len(items), 3):
        lines.append("  " + "   ".join(items[k:k + 3]))
    lines.append("soles")
    for side, s in r["soles"].items():
        lines.append(f"  {side} {s['body']}: {s['size_mm'][0]:.0f} x {s['size_mm'][1]:.0f} mm, centre "
                     f"({s['centre_mm'][0]:.1f}, {s['centre_mm'][1]:.1f}, {s['centre_mm'][2]:.1f}) mm in the foot "
                     f"frame, {len(s['hull_mm'])}-vertex hull [{s['source']}]; touch: {s['touch_sensors']}")
    lines.append("servos")
    for g, s in r["servos"].items():
        lines.append(f"  {g} ({len(s['joints'])}, {'/'.join(s['law'])} law): kp {_fmt(s['kp'])} N m/rad, kv "
                     f"{_fmt(s['kv'])} N m s/rad, torque {_fmt(s['torque'])} N m at rest, speed {_fmt(s['speed'])} rad/s, "
                     f"back-EMF {_fmt(s['back_emf'])} N m s/rad, armature {_fmt(s['armature'])} kg m^2, damping "
                     f"{_fmt(s['damping'])} N m s/rad, friction {_fmt(s['frictionloss'])} N m")
        lines.append(f"      [{s['source']}]")
    held = ", ".join(f"{j} {v:+.3f}" for j, v in r["held_joints"].items()) or "none"
    lines.append(f"held pose [rad] [{r['sources'].get('pose', 'zero')}]")
    lines.append(f"  {held}")
    sim = r["sim"]
    lines.append(f"simulation: control every {sim['control_period_s'] * 1000:g} ms, physics step "
                 f"{sim['timestep_s'] * 1000:g} ms, a fall is tilt > {sim['max_tilt_deg']:g} deg or torso below "
                 f"{sim['min_height_ratio']:.0%} of its start height")
    for note in r["notes"]:
        lines.append(f"note: {note}")
    if "stand" in r:
        s = r["stand"]
        verdict = "stays up" if s["stays_up"] else f"does NOT stay up: {s['reason']}"
        lines.append(f"stand test (rigid floor, {s['duration_s']:.1f} s, walking crouch): {verdict}")
        lines.append(f"  last 0.5 s: torso pitch {s['pitch_deg']:+.2f} deg, roll {s['roll_deg']:+.2f} deg; CoM "
                     f"{s['com_ahead_of_feet_mm']:+.1f} mm ahead of and {s['com_left_of_feet_mm']:+.1f} mm left of "
                     f"the feet's centre; sole sensors carry {s['sensed_weight_fraction']:.1%} of the weight")
        g = s["largest_sag"]
        lines.append(f"  largest servo sag under the load: {g['joint']} {g['deg']:+.2f} deg from its target at "
                     f"{g['torque_nm']:+.2f} N m (position servos give way by torque / kp; a lean comes from "
                     f"these sags adding up from ankle to hip)")
    return "\n".join(lines)
