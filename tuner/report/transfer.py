"""The gap before the match: one set's randomised match walks in the identified world beside the
default one (`gait-tuner transfer`), so a team sees what its field will do to its walk."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["world_summary", "transfer_lines"]


def world_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Survival, falls, mean torso pitch RMS [deg] and mean tracking errors of match walks
    (``tuner.sim.robustness.scenario_walks`` rows)."""
    def mean(vals):
        vals = [v for v in vals if v is not None and math.isfinite(v)]
        return float(np.mean(vals)) if vals else None
    tk = [r["tracking"] or {} for r in rows]
    return {"walks": len(rows), "survival": float(np.mean([r["survived"] for r in rows])) if rows else 0.0,
            "falls": int(sum(not r["survived"] for r in rows)),
            "pitch_rms_deg": mean(r["pitch_rms_deg"] for r in rows),
            "vx_rmse_mps": mean(t.get("vx_rmse_mps") for t in tk),
            "vy_rmse_mps": mean(t.get("vy_rmse_mps") for t in tk),
            "wz_rmse_radps": mean(t.get("wz_rmse_radps") for t in tk)}


def transfer_lines(source: str, worlds: dict[str, tuple[str, dict[str, Any]]]) -> list[str]:
    """One screen: per world (name -> (what it is, summary)) the survival, pitch and tracking."""
    def f(v, fmt):
        return "-".rjust(int(fmt.split(".")[0])) if v is None else format(v, fmt)
    lines = [f"{source}: randomised match walks per world", f"  {'world':12s} {'survival':>9s} {'falls':>6s} "
             f"{'pitch RMS':>10s} {'vx RMSE':>9s} {'vy RMSE':>9s} {'wz RMSE':>9s}   what",
             f"  {'':12s} {'':>9s} {'':>6s} {'[deg]':>10s} {'[m/s]':>9s} {'[m/s]':>9s} {'[rad/s]':>9s}"]
    for name, (what, s) in worlds.items():
        lines.append(f"  {name:12s} {s['survival'] * 100:8.0f}% {s['falls']:3d}/{s['walks']:<3d}"
                     f"{f(s['pitch_rms_deg'], '10.2f')} {f(s['vx_rmse_mps'], '9.3f')} {f(s['vy_rmse_mps'], '9.3f')} "
                     f"{f(s['wz_rmse_radps'], '9.3f')}   {what}")
    names = list(worlds)
    if len(names) == 2:
        a, b = worlds[names[0]][1], worlds[names[1]][1]
        d = (b["survival"] - a["survival"]) * 100
        lines.append(f"  the {names[1]} world {'loses' if d < 0 else 'gains'} {abs(d):.0f} points of survival "
                     f"against the {names[0]} one")
    return lines
