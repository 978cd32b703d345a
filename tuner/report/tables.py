"""Output formatting of the command line in one place: metric tables and summaries as text.

The CLI verbs compute; this module says how a result reads on a terminal. ``--json`` output is
the verbs' own (strict JSON of the same numbers).
"""

from __future__ import annotations

import math
from typing import Any, Mapping

__all__ = ["format_metrics", "format_value", "format_surface_tests", "json_finite"]


def json_finite(x: Any) -> Any:
    """``x`` with every non-finite number as None, through dicts, lists and tuples (strict JSON)."""
    if isinstance(x, dict):
        return {k: json_finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def format_value(value) -> str:
    """A metric as a table cell: '-' for none (or a number that is not one), three decimals for a number."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.3f}" if isinstance(value, float) else str(value)


def format_metrics(metrics, definitions: Mapping[str, str]) -> str:
    """One line per metric: name, value, what it means (``tuner.sim.metrics.DEFINITIONS``)."""
    return "\n".join(f"  {key:16s} {format_value(getattr(metrics, key)):>10s}   {text}"
                     for key, text in definitions.items())


def format_surface_tests(report: Mapping) -> str:
    """``surfaces --test`` as a table: each surface's four figures, the bands each falls in, and the
    two scales (``tuner.report.surface_tests``)."""
    from .surface_tests import FIGURES
    bands = report["bands"]
    lines = ["sports-turf test methods, simulated (tuner/sim/turf_tests.py); bands for football turf:"]
    for key, unit, what in FIGURES:
        b = bands.get(key) or {}
        lines.append(f"  {what} [{unit}]: " + (", ".join(f"{m} {lo:g}-{hi:g}" for m, (lo, hi) in b.items())
                                              or "no published band in our sources"))
    w = max([14, *(len(n) + 1 for n in report["surfaces"])])       # the names' column
    head = (f"{'surface':{w}s}{'layer':>7s}{'FR %':>8s}{'VD mm':>8s}{'ER %':>8s}{'RR N m':>8s}{'sole mm':>9s}"
            f"{'roll':>8s}  in bands")
    lines += ["", head, "-" * len(head)]
    for name, row in report["surfaces"].items():
        cells = [format_value(row[k]) if row[k] is None else f"{row[k]:.1f}" for k, _, _ in FIGURES]
        inb = "; ".join(f"{k.split('_')[0]}: {', '.join(v)}" for k, v in row["in_bands"].items() if v) or "none"
        layer = "-" if row["layer_mm"] is None else f"{row['layer_mm']:g}"
        sink = format_value(row["robot_sole_sink_mm"]) if row["robot_sole_sink_mm"] is None else \
            f"{row['robot_sole_sink_mm']:.2f}"
        roll = row.get("robot_sole_roll_Nm_per_rad")
        roll = "-" if roll is None else f"{roll:.0f}"
        lines.append(f"{name:{w}s}{layer:>7s}" + "".join(f"{c:>8s}" for c in cells) + f"{sink:>9s}{roll:>8s}  {inb}")
    sc = report["scale"]
    lines += ["", f"FR force reduction, VD vertical deformation, ER energy restitution (drop test); RR rotational "
                  f"resistance; sole: depth a {sc['robot_mass_kg']:g} kg robot's {sc['robot_sole_m'][0] * 100:g} x "
                  f"{sc['robot_sole_m'][1] * 100:g} cm sole settles at, at rest; roll: how stiffly that sole, "
              f"carrying the robot, is held against rolling [N m/rad] (below m g h = "
              f"{sc['robot_topple_Nm_per_rad']:g} N m/rad, at a {sc['robot_com_height_m']:g} m CoM, a robot with still "
              f"ankles topples sideways on one foot)",
              f"scale: the drop test presses its foot with {sc['drop_test_static_kPa']:g} kPa at rest and "
              f"~{sc['drop_test_peak_kPa']:g} kPa at its peak on concrete; the robot's sole presses "
              f"{sc['robot_sole_kPa']:g} kPa standing on it"]
    for name, row in report["surfaces"].items():
        if row.get("note"):
            lines.append(f"note: {name}: {row['note']}")
    return "\n".join(lines)
