"""The RoboCup Humanoid League's push-recovery challenge, simulated: the rules since 2025
(:func:`challenge_2025`, the default of ``challenge push``) and the 2019 KidSize trial
(:func:`challenge`, ``--rules 2019``).

By the 2025 rules (Section III, push recovery, revision of 2025-02-13): a bottle of 3, 5 or 10 kg
on a rope of 1.5-2 m measured to its centre of mass, released from D (declared, at most 0.75 L),
meeting the robot when the rope is vertical at the robot's CoM height; a trial is a push from the
front, one from behind and one from either; fully successful when all three are absorbed,
partially at two; M = sqrt(H) / h_c * m_B / m_R * h_i / h_c. Ours where they leave it open: see
:data:`PUSH_TIMES_2025`, :func:`absorbed` and ``scene.BOTTLES`` (the bottles' sizes).

By the 2019 rules: a 1 kg pendulum (a bottle with up to 1 cm of foam) on a rope of a fixed
length L between 1 and 2 m, the bottle's bottom at the robot's CoM height, released from a
ground-projected distance D; the robot walks in place; a trial is three pushes from random
directions, fully successful when the robot is standing or walking after all three; the rank is
sqrt(H) / (m_robot H_com) with H = L - sqrt(L^2 - D^2), the bottle's drop.

Ours, where the rules leave it open: the rope is measured to the bottle's middle (so H is the drop
of its centre of mass and it meets the robot at sqrt(2 g H)); the bottle hangs, at rest, just
touching the robot on the side it comes from (``scene.add_pendulum``: a capsule 9 cm across with a
soft 15 ms contact for the foam); the pushes come at 3, 7 and 11 s of a 14 s walk in place, each
from a direction drawn uniformly around the robot's heading at that moment, the bottle released a
quarter of its (exact, large-angle) period before; after each push the pendulum is taken away.
:func:`challenge` raises D in steps of ``step`` until a trial fails and reports the largest D fully
successful. A set with the walk engine steps in place (``idle: step``); any other set walks a zero
command stream (a table planned per step, or a controller of the user's own).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable, Sequence
from pathlib import Path

import mujoco
import numpy as np

import gaits
from gaits import CommandStream

from ..sim.record import recording, recording_stem
from ..sim.rollout import Simulator
from ..sim.scene import BOTTLE_2019, BOTTLE_LENGTH, BOTTLE_MASS, PREFIX

__all__ = ["challenge", "push_trial", "push_by_direction", "drop_height", "impact_momentum", "rank", "PUSH_TIMES_S", "TRIAL_S"]

PUSH_TIMES_S = (3.0, 7.0, 11.0)   # [s] when the three pushes meet the robot
TRIAL_S = 14.0                     # [s] one trial
GRAVITY = 9.81
GAP = 0.005                        # [m] between the resting bottle and the robot


def drop_height(rope: float, distance: float) -> float:
    """H = L - sqrt(L^2 - D^2) [m]: how far the bottle falls from its release (the rules' H)."""
    return rope - math.sqrt(max(rope * rope - distance * distance, 0.0))


def impact_momentum(rope: float, distance: float, mass: float = BOTTLE_MASS) -> float:
    """[N s] The bottle's momentum as it meets the robot: m sqrt(2 g H) for a release from D."""
    return mass * math.sqrt(2 * GRAVITY * drop_height(rope, distance))


def rank(rope: float, distance: float, robot_mass: float, com_height: float) -> float:
    """The 2019 rules' rank sqrt(H) / (m_robot H_com)."""
    return math.sqrt(drop_height(rope, distance)) / (robot_mass * com_height)


def rank_2025(rope: float, distance: float, bottle_mass: float, robot_mass: float, com_height: float,
              impact_height: float) -> float:
    """The 2025 rules' M = sqrt(H) / h_c * m_B / m_R * h_i / h_c: H the bottle's drop [m], h_c the
    robot's CoM height [m], h_i the height the bottle meets it at [m], m_B the bottle's and m_R the
    robot's mass [kg]."""
    return (math.sqrt(drop_height(rope, distance)) / com_height * bottle_mass / robot_mass
            * impact_height / com_height)


def _quarter_period(rope: float, angle: float) -> float:
    """[s] from release at ``angle`` to the bottom (a pendulum's exact quarter period)."""
    from scipy.special import ellipk      # here: scipy.special costs 0.4 s of every start
    return math.sqrt(rope / GRAVITY) * float(ellipk(math.sin(angle / 2) ** 2))


def _reach(m: mujoco.MjModel, d: mujoco.MjData, sim: Simulator, u: np.ndarray, z_lo: float, z_hi: float) -> float:
    """How far the robot's geoms reach along the horizontal unit vector ``u`` from the torso, over
    the heights the bottle spans (each geom's bounding box, as axis-aligned in the world)."""
    root = m.body_rootid[sim._torso]
    centre = d.xpos[sim._torso, :2]
    best = 0.0
    for g in range(m.ngeom):
        if m.body_rootid[m.geom_bodyid[g]] != root or not m.geom_contype[g]:
            continue
        R = d.geom_xmat[g].reshape(3, 3)
        half = np.abs(R) @ m.geom_aabb[g, 3:]
        c = d.geom_xpos[g] + R @ m.geom_aabb[g, :3]
        if c[2] + half[2] < z_lo or c[2] - half[2] > z_hi:
            continue
        best = max(best, float((c[:2] - centre) @ u) + abs(u[0]) * half[0] + abs(u[1]) * half[1])
    return best


def push_trial(sim: Simulator, drive: gaits.Drive, distance: float, seed: int, keep_trace: bool = False,
               pushes: Sequence[tuple[float, float]] | None = None, record: Path | None = None) -> dict[str, Any]:
    """One trial of three pushes at ``distance`` [m]; returns success and each push's record
    (``keep_trace``: and the walk's trace, under ``trace``; ``record``: an MCAP file the walk is
    recorded into, ``record.py``).

    ``pushes`` (ours, for analysis; not the rules' trial): the pushes as (time [s], direction [deg]
    against the robot's heading, 0 the bottle moving the way the robot faces, 90 to its left)
    instead of the rules' three random ones (``seed`` then unused); the walk lasts until 3 s after
    the last."""
    m = sim.model
    rope = sim.rope
    bottle = getattr(sim, "bottle", BOTTLE_2019)
    if pushes is None:
        rng = np.random.default_rng(np.random.SeedSequence([0xC4A1, int(seed), int(round(distance * 1000))]))
        times = PUSH_TIMES_S
        rel = rng.uniform(0.0, 2 * math.pi, len(PUSH_TIMES_S))
        duration = TRIAL_S
    else:
        if not pushes:
            raise ValueError("push_trial: pushes, when given, needs at least one (time, direction)")
        times = tuple(float(t) for t, _ in pushes)
        if any(b - a < 4.0 - 1e-9 for a, b in zip(times, times[1:])) or times[0] < PUSH_TIMES_S[0] - 1e-9:
            raise ValueError(f"push_trial: pushes at {times} s: the first at {PUSH_TIMES_S[0]:g} s or later "
                             f"(stepping in place by then), each 4 s or more after the one before (the "
                             f"bottle swings in and is parked 1.5 s after its push), as the rules' trial")
        rel = np.radians([float(d) for _, d in pushes])
        duration = times[-1] + 3.0
    angle0 = math.asin(min(distance / rope, 1.0))
    quarter = _quarter_period(rope, angle0)
    jnt = m.joint(PREFIX + "rope").id
    qadr, vadr = m.jnt_qposadr[jnt], m.jnt_dofadr[jnt]
    mocap = m.body(PREFIX + "pivot").mocapid[0]
    dt = sim.control_period
    records: list[dict[str, Any]] = []
    state = {"com_height": None}

    def release(i: int) -> Callable:
        def fn(model: mujoco.MjModel, data: mujoco.MjData) -> None:
            torso = data.xpos[sim._torso]
            R = data.xmat[sim._torso].reshape(3, 3)
            heading = math.atan2(R[1, 0], R[0, 0])
            phi = heading + rel[i]
            u = np.array([math.cos(phi), math.sin(phi)])          # the way the bottle moves
            h_com = state["com_height"]
            if bottle.centred:        # the bottle's centre of mass meets the robot's CoM height
                z_lo, z_hi = h_com - bottle.length / 2, h_com + bottle.length / 2
                pivot_z = h_com + rope
            else:                     # the 2019 trial as the tool has always run it
                z_lo, z_hi = h_com, h_com + BOTTLE_LENGTH
                pivot_z = h_com + BOTTLE_LENGTH / 2 + rope
            rest = torso[:2] - u * (_reach(model, data, sim, -u, z_lo, z_hi) + bottle.radius + GAP)
            data.mocap_pos[mocap] = [rest[0], rest[1], pivot_z]
            axis = np.array([-u[1], u[0], 0.0])                     # z x u: the bottle swings back along -u
            data.qpos[qadr:qadr + 4] = [math.cos(angle0 / 2), *(axis * math.sin(angle0 / 2))]
            data.qvel[vadr:vadr + 3] = 0.0
            records.append({"t_s": float(times[i]), "direction_deg": float(math.degrees(rel[i]) % 360),
                            "release_tick": None, "pivot": data.mocap_pos[mocap].copy()})
        return fn

    def park(model: mujoco.MjModel, data: mujoco.MjData) -> None:
        data.mocap_pos[mocap] = [0.0, 0.0, 50.0]
        data.qvel[vadr:vadr + 3] = 0.0

    def measure_com(model: mujoco.MjModel, data: mujoco.MjData) -> None:
        state["com_height"] = float(data.subtree_com[sim._torso][2])

    hooks = {0: measure_com}
    for i, t in enumerate(times):
        k = int(round((t - quarter) / dt))
        hooks[k] = release(i)
        hooks[int(round((t + 1.5) / dt))] = park
    walk = _in_place(drive, duration)
    notes = (f"gait-tuner challenge push: D {distance:g} m, rope {rope:g} m, pushes at "
             f"{', '.join(f'{t:g} s' for t in times)} from {', '.join(f'{math.degrees(r) % 360:.0f}' for r in rel)} deg")
    with recording(walk.controller(sim.robot, dt), sim, walk, record, "push-recovery", notes) as controller:
        trace = sim.run(controller, hooks=hooks, record_qpos=True, **{**walk.run_options(), "duration": duration})
    # the bottle's speed before it met the robot: its fastest over the swing (the drop's energy, less
    # nothing until contact), from the recorded joint angle about the known pivot
    for i, rec in enumerate(records):
        k0 = int(round((times[i] - quarter) / dt)) + 2       # the rows after the release
        k1 = min(len(trace.t), k0 + int(round(1.6 * quarter / dt)))
        if k1 - k0 < 3:
            rec["measured_Ns"] = None
            continue
        quats = trace.qpos[k0:k1, qadr:qadr + 4]
        pos = np.array([rec["pivot"] + _rotate(q, np.array([0.0, 0.0, -rope])) for q in quats])
        speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) / dt
        rec["measured_Ns"] = float(bottle.mass * speed.max())
        rec["pivot"] = [float(v) for v in rec["pivot"]]
    ok = trace.survived
    out = {"distance_m": distance, "success": ok, "reason": trace.reason, "pushes": records,
           "com_height_m": state["com_height"]}
    if keep_trace:
        out["trace"] = trace
    return out


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    out = np.zeros(3)
    mujoco.mju_rotVecQuat(out, v, np.asarray(q, dtype=float))
    return out


def _in_place(drive: gaits.Drive, duration: float = TRIAL_S) -> gaits.Drive:
    """The drive walking in place for ``duration`` [s]: the engine steps at a zero command, others
    walk a zero command stream."""
    still = CommandStream(np.array([0.0]), np.zeros((1, 3)), tail=duration)
    if drive.engine is not None:
        return dataclasses.replace(drive, engine=dataclasses.replace(drive.engine, idle="step"), stream=still,
                                   command=None)
    return dataclasses.replace(drive, stream=still, command=None)


def challenge(sim: Simulator, drive: gaits.Drive, *, seed: int = 0, start: float = 0.05, step: float = 0.05,
              progress: Callable[[dict], None] | None = None, record: Path | None = None) -> dict[str, Any]:
    """Raise D from ``start`` by ``step`` [m] until a trial fails (module docstring); with ``record``
    (a folder) each trial's walk is recorded there, one MCAP file per trial."""
    rope = sim.rope
    robot_mass = float(sim.model.body_subtreemass[sim._torso])
    trials = []
    best = None
    distance = start
    com_height = None
    while distance < 0.95 * rope + 1e-9:
        path = None if record is None else \
            Path(record) / f"{recording_stem(drive)}--{sim.surface.name}--D{round(distance, 4):.2f}.mcap"
        trial = push_trial(sim, drive, round(distance, 4), seed, record=path)
        com_height = trial["com_height_m"]
        trials.append(trial)
        if progress is not None:
            progress(trial)
        if not trial["success"]:
            break
        best = round(distance, 4)
        distance += step
    H = drop_height(rope, best) if best is not None else 0.0
    return {"rope_m": rope, "best_distance_m": best,
            "momentum_Ns": impact_momentum(rope, best) if best is not None else None,
            "drop_m": H if best is not None else None,
            "rank": rank(rope, best, robot_mass, com_height) if best is not None else None,
            "robot_mass_kg": robot_mass, "com_height_m": com_height, "trials": trials}


def push_by_direction(sim: Simulator, drive: gaits.Drive, *, directions: Sequence[float] = tuple(range(0, 360, 45)),
                      push_times: Sequence[float] = (3.0, 3.1), start: float = 0.4, step: float = 0.1,
                      progress: Callable[[dict], None] | None = None) -> list[dict[str, Any]]:
    """Ours, for analysis (not the rules' trial): per direction [deg] against the robot's heading,
    single pushes at each of ``push_times`` [s] (a push meets a walk at a different point of its
    step at each), D raised from ``start`` by ``step`` [m] until one of them fails; returns per
    direction the largest D every push time survived, its momentum, and the first failure's time.
    The rules' trial takes the worst of three random directions, so this says which one binds."""
    rope = sim.rope
    rows = []
    for direction in directions:
        best, failed = None, None
        distance = start
        while distance < 0.95 * rope + 1e-9 and failed is None:
            for t in push_times:
                trial = push_trial(sim, drive, round(distance, 4), 0, keep_trace=True, pushes=[(t, direction)])
                if not trial["success"]:
                    failed = {"distance_m": round(distance, 4), "push_s": float(t),
                              "fell_s": float(trial["trace"].t_fall) if trial["trace"].fell else None,
                              "reason": trial["reason"]}
                    break
            else:
                best = round(distance, 4)
                distance += step
        row = {"direction_deg": float(direction) % 360, "best_distance_m": best,
               "momentum_Ns": impact_momentum(rope, best) if best is not None else None,
               "first_failure": failed}
        rows.append(row)
        if progress is not None:
            progress(row)
    return rows


#: the 2025 trial's pushes (ours where the rules leave it open): the first from the front (the
#: bottle moving backward, 180 deg against the heading), the second from behind (0 deg), the third
#: from either; each at a base time plus up to a step period (0.6 s) drawn from the push seed, so
#: that the pushes meet the walk at different points of its step, and within 10 deg of its side
PUSH_TIMES_2025 = (3.0, 7.6, 12.2)
FRONT, BACK = 180.0, 0.0
THIRDS = ("both", "front", "back")


def pushes_2025(seed: int, distance: float, third: str) -> list[tuple[float, float]]:
    """The three pushes (time [s], direction [deg] against the heading) of a 2025 trial."""
    if third not in ("front", "back"):
        raise ValueError(f"third push {third!r}: expected front or back")
    rng = np.random.default_rng(np.random.SeedSequence([0xC4A2, int(seed), int(round(distance * 1000))]))
    jitter_t = rng.uniform(0.0, 0.6, 3)
    jitter_d = rng.uniform(-10.0, 10.0, 3)
    dirs = (FRONT, BACK, FRONT if third == "front" else BACK)
    return [(t + j, d + e) for t, j, d, e in zip(PUSH_TIMES_2025, jitter_t, dirs, jitter_d)]


def absorbed(trial: dict[str, Any]) -> list[bool]:
    """Per push of a trial: absorbed when the robot was still up when the next push came (the last:
    at the walk's end, 3 s after it). Ours: the rules' "a stable walking cycle in place" is read as
    standing and stepping until then."""
    times = [p["t_s"] for p in trial["pushes"]]
    t_fall = trial.get("t_fall_s")
    ends = times[1:] + [math.inf]
    return [t_fall is None or t_fall >= end - 1e-9 for end in ends]


def trial_2025(sim: Simulator, drive: gaits.Drive, distance: float, seed: int, third: str,
               record: Path | None = None) -> dict[str, Any]:
    """One 2025 trial at ``distance`` [m]: front, back, then ``third``; which pushes were absorbed,
    fully successful (all three) or partially (two)."""
    trial = push_trial(sim, drive, distance, seed, keep_trace=True, pushes=pushes_2025(seed, distance, third),
                       record=record)
    trace = trial.pop("trace")
    # a walk that did not end standing ended when it fell, or when it diverged or became impossible
    # (then not ``fell``, but no push after that moment was absorbed)
    trial["t_fall_s"] = None if trace.survived else float(trace.t_fall if trace.fell else trace.t[-1])
    trial["outcome"] = trace.outcome
    trial["third"] = third
    got = absorbed(trial)
    for p, ok in zip(trial["pushes"], got):
        p["absorbed"] = ok
    trial["absorbed"] = sum(got)
    trial["success"] = trial["absorbed"] == 3
    trial["partial"] = trial["absorbed"] >= 2
    return trial


def challenge_2025(sim: Simulator, drive: gaits.Drive, *, seed: int = 0, start: float = 0.05, step: float = 0.05,
                   third: str = "both", progress: Callable[[dict], None] | None = None,
                   record: Path | None = None) -> dict[str, Any]:
    """The push-recovery challenge as the 2025 rules run it (module docstring): D raised from
    ``start`` by ``step`` [m] up to 0.75 L while a trial is at least partially successful; with
    ``third`` "both", each D is tried with the third push from the front and from behind and counts
    as its worse (the referee may choose either). Returns the largest D fully and partially
    successful with their momenta and M."""
    if third not in THIRDS:
        raise ValueError(f"third push {third!r}: expected one of {', '.join(THIRDS)}")
    rope = sim.rope
    bottle = getattr(sim, "bottle", BOTTLE_2019)
    if not bottle.centred:
        raise ValueError(f"challenge_2025: the simulator's bottle ({bottle.mass:g} kg) is the 2019 trial's; build it "
                         f"with bottle=scene.BOTTLES[3, 5 or 10]")
    robot_mass = float(sim.model.body_subtreemass[sim._torso])
    trials: list[dict] = []
    best_full = best_partial = None
    com_height = None
    distance = start
    while distance <= 0.75 * rope + 1e-9:
        d = round(distance, 4)
        at_d = []
        for which in (("front", "back") if third == "both" else (third,)):
            path = None if record is None else \
                Path(record) / f"{recording_stem(drive)}--{sim.surface.name}--D{d:.2f}-{which}.mcap"
            trial = trial_2025(sim, drive, d, seed, which, record=path)
            com_height = trial["com_height_m"]
            at_d.append(trial)
            trials.append(trial)
            if progress is not None:
                progress(trial)
            if not trial["partial"]:
                break
        if all(t["success"] for t in at_d):
            best_full = d
        if all(t["partial"] for t in at_d):
            best_partial = d
        else:
            break
        distance += step

    def figures(best: float | None) -> dict[str, Any]:
        if best is None:
            return {"distance_m": None, "momentum_Ns": None, "drop_m": None, "M": None}
        return {"distance_m": best, "momentum_Ns": impact_momentum(rope, best, bottle.mass),
                "drop_m": drop_height(rope, best),
                "M": rank_2025(rope, best, bottle.mass, robot_mass, com_height, com_height)}
    return {"rules": "2025", "rope_m": rope, "bottle_kg": bottle.mass, "third": third,
            "max_distance_m": 0.75 * rope, "full": figures(best_full), "partial": figures(best_partial),
            "robot_mass_kg": robot_mass, "com_height_m": com_height, "impact_height_m": com_height,
            "trials": trials}
