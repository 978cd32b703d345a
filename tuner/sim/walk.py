"""One walk asked for by name: a drive's controller on the simulator, recorded if asked, with what a
user should be told of it (``simulate``, ``render``, ``view``, ``export --format servo``).

The command line only prints: what a user is told comes back through ``note``, a line at a time, as
it is to be printed (on stderr).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Callable

import numpy as np

import gaits

__all__ = ["walk", "envelope_excess", "envelope_note", "engine_targets"]


def _silent(line: str) -> None:
    return None


def envelope_excess(drive: Any, controller: Any) -> list[str]:
    """The directions in which an engine's stream or command asks more than its envelope (the engine
    walks it clipped there, ``gaits/engine/``): "forward 0.5 m/s (envelope 0.35)", ...; empty for a
    controller that is not an engine or a walk within it."""
    engine = getattr(controller, "inner", controller)
    stream = drive.the_stream()
    if stream is None or not hasattr(engine, "envelope"):
        return []
    e = engine.envelope()
    c = np.asarray(stream.commands, dtype=float)
    over = []
    for name, k, sign in (("forward", 0, 1), ("backward", 0, -1), ("left", 1, 1), ("right", 1, -1),
                          ("turn_left", 2, 1), ("turn_right", 2, -1)):
        asked = float(np.max(sign * c[:, k])) if len(c) else 0.0
        if asked > e[name] + 1e-9:
            unit = "rad/s" if k == 2 else "m/s"
            over.append(f"{name} {asked:g} {unit} (envelope {e[name]:.3g})")
    return over


def envelope_note(drive: Any, controller: Any) -> str | None:
    """The lines that tell a user what a controller does that they may not expect, or None: their
    commands walked clipped to an engine's envelope (:func:`envelope_excess`); a policy that states no
    servo gains run on the robot's servos unchecked (``gaits.policy.gains_unstated``)."""
    from gaits.policy import PolicySpec, gains_unstated
    lines = []
    over = envelope_excess(drive, controller)
    if over:
        lines.append(f"note: {drive.source}: the engine walks these commands clipped to its envelope: {', '.join(over)}")
    policy = controller
    while not isinstance(getattr(policy, "spec", None), PolicySpec) and getattr(policy, "inner", None) is not None:
        policy = policy.inner              # a recording's, a stabiliser's wrapper (a user's code forwards)
    if isinstance(getattr(policy, "spec", None), PolicySpec) and gains_unstated(policy.spec):
        lines.append(f"note: {policy.source}: the policy states no servo gains (policy.gains): it runs on this robot's "
                     f"servos as they are, unchecked against the servos it was trained with")
    return "\n".join(lines) or None


def walk(drive: Any, robot: Any, sim: Any, duration: float | None, record_qpos: bool = False,
         record: Path | None = None, note: Callable[[str], None] = _silent) -> Any:
    """The rollout of a drive on the simulator (the controller it names, for ``duration`` or its own
    length); with ``record`` (a folder) every tick the controller saw and asked is recorded there as
    an MCAP file (``gaits/robot/recorder.py``), whose path is noted. A held command's velocity window is
    set in the trace's meta: from 2 s after the first step to the stop."""
    from .record import recording, recording_stem
    options = drive.run_options()
    if duration is not None:
        options["duration"] = duration
    path = None if record is None else record / f"{recording_stem(drive)}--{sim.surface.name}.mcap"
    try:
        with recording(drive.controller(robot, sim.control_period), sim, drive, path, "walk") as controller:
            said = envelope_note(drive, controller)
            if said:
                note(said)
            table = getattr(getattr(controller, "inner", controller), "traj", None)    # planned in advance: checked
            if table is not None:
                problem = sim.range_error(table.q_ref, table.t)
                if problem is not None:   # said, not refused: the papers' own EROS tables ask the built-in robot so
                    note(f"note: {drive.source}: {problem}")
            trace = sim.run(controller, record_qpos=record_qpos, **options)
    finally:
        if path is not None and path.exists():
            note(f"recorded {path}")
    if drive.online and drive.command is not None:
        start = float(getattr(drive.engine, "t_stand", 0.0) or 0.0) + 2.0
        trace.meta["steady"] = (start, float(drive.the_stream().t[-1]))
    return trace


def engine_targets(drive: Any, robot: Any, surface_name: str,
                   note: Callable[[str], None] = _silent) -> gaits.GaitTrajectory:
    """The targets an engine set sends walking its command (or a stop: standing) in the simulator on
    ``surface_name``, as a joint table (the robot's unmapped joints at zero: held), with the walk's
    references; a fall is noted (the table ends there)."""
    from .rollout import Simulator
    from .surfaces import load_surface
    if drive.command is None and drive.stream is None:
        drive = dataclasses.replace(drive, command=gaits.WalkCommand(0.0, 0.0, 0.0))
    sim = Simulator(robot, load_surface(surface_name))
    trace = walk(drive, robot, sim, None, note=note)
    if trace.fell:
        note(f"note: the engine's walk fell ({trace.reason}): the table ends there")
    q = np.zeros((len(trace.t), len(gaits.JOINT_NAMES)))
    for j, name in enumerate(sim.joint_names):
        if name in gaits.JOINT_NAMES:               # a robot's extra joints: held, not in a joint table
            q[:, gaits.JOINT_NAMES.index(name)] = trace.q_ref[:, j]
    return gaits.GaitTrajectory("engine", trace.t - trace.t[0], q, trace.p_torso, trace.p_com,
                                np.asarray(trace.zmp_ref)[:, :2], trace.p_sole_l, trace.p_sole_r,
                                np.asarray(trace.support, dtype=int), meta={"engine": True})
