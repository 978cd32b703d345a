"""Walks side by side (`gait-tuner versus`): any mix of shipped or tuned sets, controllers of a
team's own, learned policies (policy files) and placo's walk, on one robot and its surfaces, each
measured the same way (ours):

* **speed reached** per direction: the walk commanded forward, backward, sideways and turning
  (``--speeds``), deterministic, its mean velocity in its own heading frame over a window of
  steady walking (online walks 4-9.5 s of their 10 s; a table its plan's steady cycles), or
  ``fell``;
* **match walks**: ``--walks`` randomised match streams (``tuner/sim/match_walks.py``, the default
  randomisation, evaluation seeds), survival, torso pitch RMS and forward tracking RMSE;
* **the challenge** by the 2025 rules (3 kg bottle, rope 1.5 m, ``--seed``): the largest D fully
  successful, its momentum and M;
* **cost per tick**: the controller's ``step`` time on this machine (median and p99 over the
  forward walk; a figure, not a check: a loaded machine reads more).

The table is Markdown (``versus.md``) and the plots PNG in ``--out``.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

import gaits
from gaits.drive import ONLINE_DURATION_S
from gaits.walk_command import WalkCommand

__all__ = ["DIRECTIONS", "speed_walk", "versus_cell", "versus_markdown", "versus_plots"]

#: A velocity the walk was not asked for that the table names beside the one it was (ours: about a
#: tenth of the speeds asked): m/s for vx, vy; rad/s for wz.
DRIFT_SAID = (0.02, 0.02, 0.1)
AXES = ("vx", "vy", "wz")

#: Each direction's command for a unit speed (vx, vy, wz), and the default speed asked.
DIRECTIONS = {"forward": ((1.0, 0.0, 0.0), 0.2), "backward": ((-1.0, 0.0, 0.0), 0.1),
              "sideways": ((0.0, 1.0, 0.0), 0.1), "turning": ((0.0, 0.0, 1.0), 0.5)}


class _Timed:
    """A controller whose ``step`` calls are timed (everything else its own)."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self.times: list[float] = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def step(self, m: Any, command: Any = None) -> Any:
        t0 = time.perf_counter()
        out = self._inner.step(m, command)
        self.times.append(time.perf_counter() - t0)
        return out

    def computing(self) -> list[float]:
        """The times of the ticks the controller computed in: a controller slower than the loop (a
        50 Hz policy in a 100 Hz loop: ``every`` 2) holds its targets between, and those ticks'
        times (a copy) would halve the median."""
        every = getattr(self._inner, "every", 1)
        every = every if isinstance(every, int) and every >= 1 else 1
        return self.times[::every]


def speed_walk(sim: Any, drive: gaits.Drive, direction: str, speed: float) -> dict[str, Any]:
    """One deterministic walk of ``drive`` commanded ``speed`` along ``direction``: the velocity it
    reached along it (None when it did not end standing: ``outcome`` says how), its pitch RMS and its ``step`` times [s]."""
    from ..sim.metrics import heading_velocity, pitch_rms
    unit, _ = DIRECTIONS[direction]
    command = WalkCommand(*(speed * u for u in unit))
    walk = dataclasses.replace(drive, command=command, stream=None)
    window = (4.0, ONLINE_DURATION_S - 0.5) if walk.online else None      # a table: its plan's steady cycles
    timed = _Timed(walk.controller(sim.robot, sim.control_period))
    trace = sim.run(timed, **walk.run_options())
    if window is None:
        steady = trace.meta.get("steady")
        window = tuple(steady) if steady else (0.4 * float(trace.t[-1]), 0.9 * float(trace.t[-1]))
    reached = velocity = drift = None
    if trace.survived:
        v = heading_velocity(trace.t, trace.p_com, trace.yaw if trace.yaw is not None else np.zeros(len(trace.t)),
                             *window)
        if np.all(np.isfinite(v)):
            reached, velocity = float(np.dot(v, unit)), [float(x) for x in v]
            # the largest velocity it was not asked for (beyond DRIFT_SAID): a walk asked sideways that
            # drifts forward does not read as a slow sideways walk alone
            off = [(abs(v[k]) / DRIFT_SAID[k], k) for k in range(3) if unit[k] == 0 and abs(v[k]) > DRIFT_SAID[k]]
            if off:
                k = max(off)[1]
                drift = {"axis": AXES[k], "value": float(v[k])}
    return {"direction": direction, "asked": float(speed), "reached": reached, "velocity": velocity,
            "drift": drift, "fell": not trace.survived, "outcome": trace.outcome, "reason": trace.reason,
            "pitch_rms_deg": float(np.degrees(pitch_rms(trace.pitch))) if trace.survived else None,
            "step_times": timed.computing()}


def versus_cell(robot_name: str, surface_name: str, drive: gaits.Drive, *, speeds: dict[str, float], walks: int,
                seed: int, challenge: bool, workers: int, progress: Callable[[int], None] | None = None
                ) -> dict[str, Any]:
    """Everything the table shows for one walk on one surface (module docstring)."""
    from ..robots import load_robot
    from ..sim.rollout import Simulator
    from ..sim.surfaces import load_surface
    from .transfer import world_summary
    robot, surface = load_robot(robot_name), load_surface(surface_name)
    sim = Simulator(robot, surface)
    out: dict[str, Any] = {"speeds": {}}
    times: list[float] = []
    for direction, speed in speeds.items():
        r = speed_walk(sim, drive, direction, speed)
        if direction == "forward":
            times = r.pop("step_times")
            out["pitch_rms_deg"] = r["pitch_rms_deg"]
        else:
            r.pop("step_times")
        out["speeds"][direction] = r
        if progress is not None:
            progress(1)
    out["tick_ms"] = {"median": float(np.median(times) * 1000), "p99": float(np.percentile(times, 99) * 1000)} \
        if times else None
    if walks:
        from ..sim.robustness import scenario_walks
        from ..sim.match_walks import MatchDistribution
        rows = scenario_walks(robot_name, surface_name, drive, MatchDistribution(), walks=walks, seed=seed,
                              workers=workers, progress=progress)
        out["match"] = world_summary(rows)
    if challenge:
        from ..challenge.rules import challenge_2025
        from ..sim.scene import BOTTLES
        csim = Simulator(robot, surface, pendulum=1.5, bottle=BOTTLES[3])
        rep = challenge_2025(csim, dataclasses.replace(drive, command=None, stream=None), seed=seed, step=0.05)
        full = rep.get("full") or {}           # none: not even the first D fully successful
        out["challenge"] = {"full_m": full.get("distance_m") or 0.0, "momentum_Ns": full.get("momentum_Ns") or 0.0,
                            "M": full.get("M") or 0.0}
        if progress is not None:
            progress(1)
    return out


def _f(v: Any, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def _reached(r: dict[str, Any] | None) -> str:
    """A speed cell: the velocity along the command, the other way's said, a drift named."""
    if r is None or r.get("reached") is None:
        return "-"
    text = f"{r['reached']:.3f}" + (" (the other way)" if r["reached"] < -DRIFT_SAID[0] else "")
    d = r.get("drift")
    if d:
        text += f", drifts {d['axis']} {d['value']:+.3f}"
    return text


def versus_markdown(robot: str, cells: Sequence[tuple[str, str, dict[str, Any]]], speeds: dict[str, float]) -> str:
    """The Markdown table: one row per (walk, surface)."""
    heads = [f"{d} ({s:g} {'rad/s' if d == 'turning' else 'm/s'})" for d, s in speeds.items()]
    cols = ["walk", "surface", *heads, "match survival", "pitch RMS [deg]", "vx RMSE [m/s]", "challenge D [m]",
            "momentum [N s]", "M", "tick median / p99 [ms]"]
    lines = [f"Walks side by side on robot {robot}", "", "| " + " | ".join(cols) + " |",
             "|" + "|".join("---" for _ in cols) + "|"]
    for walk, surface, c in cells:
        row = [walk, surface]
        for d in speeds:
            r = c["speeds"].get(d)
            row.append(r["outcome"] if r and r["fell"] else _reached(r))   # fell, diverged, ...
        m = c.get("match")
        row += [f"{m['survival'] * 100:.0f} % of {m['walks']}" if m else "-", _f(c.get("pitch_rms_deg"), ".2f"),
                _f(m and m["vx_rmse_mps"], ".3f")]
        ch = c.get("challenge")
        if ch and not ch["full_m"]:          # not even the first D fully successful: no figure, not 0.00
            row += ["none", "-", "-"]
        else:
            row += [_f(ch and ch["full_m"], ".2f"), _f(ch and ch["momentum_Ns"], ".2f"), _f(ch and ch["M"], ".3f")]
        t = c.get("tick_ms")
        row.append(f"{t['median']:.3f} / {t['p99']:.3f}" if t else "-")
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", VERSUS_COLUMNS]
    return "\n".join(lines) + "\n"


#: What each column of the table means (written under it).
VERSUS_COLUMNS = (
    "Columns: per direction, the speed reached along that command while it was held (m/s, rad/s; negative: "
    "the other way; the walk's outcome where it fell), and the largest velocity it was not asked for where "
    "over 0.02 m/s or 0.1 rad/s ('drifts vx +0.154': forward while asked sideways); match survival, the "
    "share of randomised match walks that did not fall; pitch RMS, the torso's pitch over those walks; vx RMSE, the forward speed's error against the command over the walks "
    "that survived; challenge D, the largest bottle release distance of the 2025 push challenge (3 kg, rope "
    "1.5 m) fully successful ('none': not even the first), with its momentum and rank M; tick, the walk's "
    "controller call time on this machine (median / p99) over the ticks it computes in (a policy slower than "
    "the 100 Hz loop holds its targets between: those ticks are left out).")


def versus_plots(out: Path, cells: Sequence[tuple[str, str, dict[str, Any]]], speeds: dict[str, float]) -> list[Path]:
    """Bar charts: the speed reached per direction, match survival and the challenge's D, per walk
    and surface."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plots import save_figure
    labels = [f"{w}\n{s}" for w, s, _ in cells]
    x = np.arange(len(cells))
    panels = [(d, [(c["speeds"].get(d) or {}).get("reached") or 0.0 for _, _, c in cells],
               f"{d} reached [{'rad/s' if d == 'turning' else 'm/s'}] (asked {speeds[d]:g})") for d in speeds]
    if any("match" in c for _, _, c in cells):
        panels.append(("survival", [100 * c["match"]["survival"] if "match" in c else 0.0 for _, _, c in cells],
                       "match-walk survival [%]"))
    if any("challenge" in c for _, _, c in cells):
        panels.append(("challenge", [(c.get("challenge") or {}).get("full_m") or 0.0 for _, _, c in cells],
                       "challenge: largest D fully successful [m]"))
    fig, axes = plt.subplots(len(panels), 1, figsize=(max(6, 1.4 * len(cells)), 2.4 * len(panels)), squeeze=False)
    for ax, (_, vals, title) in zip(axes[:, 0], panels):
        ax.bar(x, vals, color="tab:blue")
        ax.set_title(title, fontsize=9)
        ax.set_xticks(x, labels, fontsize=7)
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    path = Path(out) / "versus.png"
    save_figure(fig, path, 110)
    plt.close(fig)
    return [path]
