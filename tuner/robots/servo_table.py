"""Joint tables a robot can play: a map's ``servos:`` section (servo IDs and position units) and
the check of a table against each servo's speed and range.

Map format (every field optional but ``id``; ``default`` gives the others for every joint)::

    servos:
      default: {ticks_per_turn: 4096, centre: 2048, direction: 1, offset: 0.0}
      HipYaw_L: {id: 7}
      Knee_L: {id: 14, direction: -1, offset: 0.02}   # offset [rad]: the servo's zero, in the file's angle
      Knee_R: {id: 13, port: 1}                      # port: its bus (0 the first; the map's bus: section)

A joint angle q [rad, the robot file's convention] is sent as
``ticks = centre + direction * (q + offset) * ticks_per_turn / (2 pi)``, rounded to the nearest
tick (``units_per_rad`` may replace ``ticks_per_turn``). Pure numpy; the CLI writes the file.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from gaits.robot.robot_file import MAX_PORTS, ServoUnit, from_units, to_units   # the one definition (the robot side's)

from ..errors import UserError

__all__ = ["ServoUnit", "read_servo_units", "to_units", "from_units", "check_table", "check_positions", "servo_columns",
           "too_fast", "turn_units", "SERVO_UNIT_FIELDS", "MIN_TICKS_PER_TURN"]

SERVO_UNIT_FIELDS = ("id", "ticks_per_turn", "units_per_rad", "centre", "direction", "offset", "port")
#: [ticks] the coarsest servo a table is written for (ours: 1.4 deg a tick; hobby servos give
#: 1024 over 300 deg, Dynamixel 4096 a turn)
MIN_TICKS_PER_TURN = 256


def _number(v: Any, where: str, lo: float, hi: float, unit: str, strict_low: bool = False) -> float:
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    if not ok or (v <= lo if strict_low else v < lo) or v > hi:
        raise UserError(f"{where} = {v!r}: expected a number in {'(' if strict_low else '['}{lo:g}, {hi:g}] {unit}")
    return float(v)


def _unit(doc: Any, where: str, base: dict[str, Any]) -> dict[str, Any]:
    if not isinstance(doc, Mapping):
        raise UserError(f"{where}: expected a mapping of {', '.join(SERVO_UNIT_FIELDS)}")
    out = dict(base)
    if "ticks_per_turn" in doc and "units_per_rad" in doc:
        raise UserError(f"{where}: give ticks_per_turn or units_per_rad, not both (one sets the other: "
                        f"units_per_rad = ticks_per_turn / 2 pi)")
    for k, v in doc.items():
        if k not in SERVO_UNIT_FIELDS:
            raise UserError(f"{where}: unknown field {k!r} (allowed: {', '.join(SERVO_UNIT_FIELDS)})")
        if k == "id":
            if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= 253:
                raise UserError(f"{where}.id = {v!r}: expected an integer in [0, 253]")
            out["id"] = v
        elif k == "ticks_per_turn":
            out["units_per_rad"] = _number(v, f"{where}.ticks_per_turn", MIN_TICKS_PER_TURN, 1e7, "ticks") / (2 * math.pi)
        elif k == "units_per_rad":
            out["units_per_rad"] = _number(v, f"{where}.units_per_rad", MIN_TICKS_PER_TURN / (2 * math.pi), 1e7,
                                           "units/rad")
        elif k == "centre":
            out["centre"] = _number(v, f"{where}.centre", -1e7, 1e7, "units")
        elif k == "port":
            if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v < MAX_PORTS:
                raise UserError(f"{where}.port = {v!r}: expected a bus number in [0, {MAX_PORTS - 1}] (0 the first)")
            out["port"] = v
        elif k == "direction":
            if v not in (1, -1) or isinstance(v, bool):
                raise UserError(f"{where}.direction = {v!r}: must be 1 or -1")
            out["direction"] = int(v)
        else:
            out["offset"] = _number(v, f"{where}.offset", -math.pi, math.pi, "rad")
    return out


def read_servo_units(doc: Any, joints: tuple[str, ...], source: str) -> dict[str, ServoUnit]:
    """The map's ``servos:`` section -> {file joint name: ServoUnit} (``joints``: the file's actuated
    joints); IDs must be unique."""
    if doc is None:
        return {}
    if not isinstance(doc, Mapping):
        raise UserError(f"{source}: servos must be a mapping of joint name: {{id: N, ...}} (and default:)")
    base = _unit(doc.get("default", {}), f"{source}: servos.default", {})
    if "id" in base:
        raise UserError(f"{source}: servos.default: an id belongs to one joint")
    out: dict[str, ServoUnit] = {}
    for k, v in doc.items():
        if k == "default":
            continue
        if k not in joints:
            raise UserError(f"{source}: servos: {k!r} is not an actuated joint of the robot file")
        fields = _unit(v, f"{source}: servos.{k}", base)
        if "id" not in fields:
            raise UserError(f"{source}: servos.{k}: missing id")
        out[k] = ServoUnit(**fields)
    ids = [u.id for u in out.values()]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise UserError(f"{source}: servos: id {dup[0]} given to more than one joint")
    return out


def turn_units(u: ServoUnit) -> int:
    """The positions one turn of the servo holds (its position register: 0 to this less one)."""
    return int(round(u.units_per_rad * 2 * math.pi))


def check_positions(ticks: np.ndarray, t: np.ndarray, names: tuple[str, ...], units: list[ServoUnit]) -> None:
    """Every position (N, J) a servo can be sent: within 0 .. one turn less one of its units (a
    ``centre`` or ``offset`` that puts the table outside is one line naming joint, time and value)."""
    for j, (name, u) in enumerate(zip(names, units)):
        top = turn_units(u) - 1
        bad = np.flatnonzero((ticks[:, j] < 0) | (ticks[:, j] > top))
        if bad.size:
            i = int(bad[0])
            raise UserError(f"servos: joint {name} (id {u.id}) would be sent position {int(ticks[i, j])} at "
                            f"t = {t[i]:.2f} s, outside its 0..{top} (one turn of {top + 1}; centre {u.centre:g}, "
                            f"direction {u.direction:+d}, offset {u.offset:g} rad): correct its servos: entry")


def too_fast(q: np.ndarray, t: np.ndarray, speed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rate (N-1, J) [rad/s] of each move between rows, mask of the moves faster than ``speed``)."""
    rate = np.abs(np.diff(np.asarray(q, dtype=float), axis=0)) / np.diff(t)[:, None]
    return rate, rate > speed[None, :] * (1 + 1e-6) + 1e-9


def check_table(q: np.ndarray, t: np.ndarray, names: tuple[str, ...], speed: np.ndarray, lo: np.ndarray,
                hi: np.ndarray, clip: bool) -> tuple[np.ndarray, list[str]]:
    """A joint table (N, J) [rad] against each joint's servo speed [rad/s] and range [rad].

    Without ``clip``: the first target a servo cannot follow (a move faster than its speed between
    two rows, or outside the range) is a UserError naming joint, time and rate. With ``clip``: the
    table the servos would play, moved at most ``speed * dt`` a row and clipped into the range (as
    the simulator's servo does, tuner/sim/rollout.py), and one line per joint it changed."""
    q = np.asarray(q, dtype=float)
    dt = np.diff(t)
    if not clip:
        rate, over = too_fast(q, t, speed)
        out_lo, out_hi = q < lo - 1e-6, q > hi + 1e-6
        if over.any():
            i, j = (int(v[0]) for v in np.nonzero(over))
            k = np.flatnonzero(over[:, j])
            raise UserError(f"joint {names[j]} is asked to move at {rate[i, j]:.2f} rad/s at t = {t[i + 1]:.2f} s "
                            f"where its servo gives {speed[j]:g} rad/s ({len(k)} row(s) too fast for it; the fastest "
                            f"{rate[k, j].max():.2f} rad/s): --clip writes the table the servo can play")
        if out_lo.any() or out_hi.any():
            bad = out_lo | out_hi
            i, j = (int(v[0]) for v in np.nonzero(bad))
            raise UserError(f"joint {names[j]} is asked for {q[i, j]:+.3f} rad at t = {t[i]:.2f} s, outside its "
                            f"range [{lo[j]:+.3f}, {hi[j]:+.3f}] rad: --clip clips it")
        return q, []
    out = q.copy()
    for i in range(1, len(q)):
        step = speed * dt[i - 1]
        out[i] = np.clip(np.clip(q[i], out[i - 1] - step, out[i - 1] + step), lo, hi)
    out[0] = np.clip(out[0], lo, hi)
    notes = []
    changed = np.abs(out - q) > 1e-9
    for j in np.flatnonzero(changed.any(axis=0)):
        notes.append(f"clipped {names[j]}: {int(changed[:, j].sum())} of {len(q)} rows, at most "
                     f"{np.abs(out[:, j] - q[:, j]).max():.3f} rad from the plan")
    return out, notes


def servo_columns(units: Mapping[str, ServoUnit], names: tuple[str, ...]) -> list[ServoUnit]:
    """The units of a table's columns, in order; a column without a servo entry is one line."""
    missing = [n for n in names if n not in units]
    if missing:
        raise UserError(f"servos: no id for joint(s) {', '.join(missing)} of the table (give each "
                        f"servos.JOINT: {{id: N}} in the robot map)")
    return [units[n] for n in names]

