"""``gait-tuner compare``: tuned gaits beside the papers' baselines, on the EROS experiment's grid.

An online set (one with an ``engine:`` section) is compared as its gait's table: with no command the
engine would stand where it started; the table is labelled "(its table)".

For every parameter set and surface: the set's own walk (pitch vibration as the
EROS +- figure and RMS, ZMP error, speed, fell) and an EROS-style stability
matrix: the same set at the paper's step distances (0-24 mm forward, 8-24 mm
backward; EROS: step X, TLIPFM: S_L with d_1 = d_2 = S_L/2, cosine: S), STABLE
when the walk ends without a fall. Stability % is stable cells / 10.
EROS baselines are added as the calibrated experiment walks them (foot lift x
0.2, see ``gait-tuner experiment eros``), labelled so.
"""

from __future__ import annotations

import dataclasses

import warnings
from pathlib import Path
from typing import Callable

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gaits  # noqa: E402
from gaits.files import make_folder, probe_folder, write_text_atomic  # noqa: E402

from ..errors import UserError  # noqa: E402
from .experiments import EROS_STEPS_MM  # noqa: E402
from .plots import save_figure  # noqa: E402
from ..sim.metrics import summarize  # noqa: E402
from ..params_io import resolve_params  # noqa: E402
from ..process_pool import map_in_order  # noqa: E402
from ..sim.randomisation import EVALUATE, Randomisation, draw  # noqa: E402
from ..robots import load_robot  # noqa: E402
from ..sim.cache import simulator  # noqa: E402
from ..sim.surfaces import load_surface  # noqa: E402

__all__ = ["with_step", "n_rows", "run_compare", "BASELINES_FOR"]

BASELINES_FOR = {f.name: f.baselines for f in gaits.all_families()}
#: The staircases of the speed column: the shipped speed studies' (8 stairs of 4 steps up to these
#: tops, a stair held when the robot is up and tracks >= 70% of it; tuner/sim/walk_speed.py).
SPEED_STAIRS = {"forward": 0.48, "backward": 0.32, "left": 0.16, "turn_left": 1.6}


def retitle(ax, title: str) -> None:
    """Our title on one of Optuna's plots, in place of its own (Optuna sets it on the left: a title
    of ours beside it drew the two over each other)."""
    for loc in ("left", "right"):
        ax.set_title("", loc=loc)
    ax.set_title(title, fontsize=10)


def speed_per_direction(sim, params: gaits.GaitParams, stabiliser=None) -> dict[str, float | None]:
    """The highest stair held per direction (None for a direction the family does not walk)."""
    from ..sim.walk_speed import speed_test
    return {d: (speed_test(sim, params, gaits.SpeedStaircase(d, top, levels=8, steps_per_level=4),
                           tolerance=0.3, stabiliser=stabiliser).reached
                if gaits.walks_direction(params.FAMILY, d) else None)
            for d, top in SPEED_STAIRS.items()}


def with_step(params: gaits.GaitParams, step: float) -> gaits.GaitParams:
    """The same gait at another signed step length [m] (the family's step rule)."""
    return gaits.family_of(params).with_step(params, step)


def _sets(specs: list[str], baselines: bool) -> list[gaits.Drive]:
    """The drive of every compared set (its stabiliser as its file says), then the papers' baselines."""
    out = []
    families = []
    for s in specs:
        d = gaits.Drive.of(resolve_params(s, None, "set"), source=s)
        if d.engine is not None:   # an online set walks its gait's table here: no command, it would stand
            d = dataclasses.replace(d, engine=None, source=f"{s} (its table)")
        out.append(d)
        families.append(out[-1].family)
    if baselines:
        for fam in dict.fromkeys(families):
            for name in BASELINES_FOR[fam]:
                if name in specs:
                    continue                      # already compared under its own name
                out.append(gaits.Drive.of(gaits.load_baseline(name), source=f"paper:{name}"))
    return out


def _row(task: tuple) -> dict:
    """One (set, surface): its own walk and the 10 EROS grid walks (runs in a worker process)."""
    robot_name, surface, drive, n_random = task
    sim = simulator(robot_name, surface)
    robot = sim.robot
    traj = drive.table(robot, sim.control_period)
    own = summarize(sim.run(drive.controller(robot, sim.control_period, table=traj)))
    # robustness: the own walk under the default randomisation, evaluation seeds (0, i)
    survived = [summarize(sim.run(drive.controller(robot, sim.control_period, table=traj), perturb=draw(
        Randomisation(), (0, i), *sim.n_random(), namespace=EVALUATE))).survived for i in range(n_random)]
    survival = 100.0 * float(np.mean(survived)) if survived else float("nan")
    plan = float(traj.p_world_pelvis[-1, 0] - traj.p_world_pelvis[0, 0])
    covered = 100.0 * own.distance_m / plan if abs(plan) > 1e-3 else float("nan")
    cells = []
    for direction, steps in EROS_STEPS_MM.items():
        for mm in steps:
            cell = drive.with_params(with_step(drive.params, (1 if direction == "forward" else -1) * mm / 1000))
            try:
                m = summarize(sim.run(cell.controller(robot, sim.control_period)))
                cells.append(m.survived)
            except (gaits.ParamError, gaits.UnreachableTargetError):
                cells.append(False)
    return {"set": drive.source, "surface": surface.name, "cells": cells,
            "stability": 100.0 * sum(cells) / len(cells), "own": own, "covered": covered,
            "survival": survival, "n_random": n_random,
            "speeds": speed_per_direction(sim, drive.params, drive.stabiliser)}


def render_sets(specs: list[str], robot_name: str, surface_names: list[str], baselines: bool, out_dir: Path,
                progress: Callable[[int], None] | None = None) -> list[Path]:
    """A video of every compared set's own walk on every surface: ``out_dir/videos/SET--SURFACE.mp4``.

    Rendered one after another in this process: one OpenGL context, never one per forked worker."""
    import re

    from .video import VideoOptions, render_trace
    written = []
    for drive in _sets(specs, baselines):
        for surface in (load_surface(s) for s in surface_names):
            sim = simulator(robot_name, surface)
            trace = sim.run(drive.controller(sim.robot, sim.control_period), record_qpos=True)
            label = drive.source
            stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(label).stem if label.endswith(".yaml") else label)
            out = out_dir / "videos" / f"{stem}--{surface.name}.mp4"
            render_trace(sim, trace, out, VideoOptions(), title=f"{label} | {sim.robot.name} | {surface.name}")
            written.append(out)
            if progress is not None:
                progress(1)
    return written


def _speeds_text(speeds: dict[str, float | None]) -> str:
    return " / ".join("-" if v is None else f"{v:.2f}" for v in speeds.values())


def n_rows(specs: list[str], surface_names: list[str], baselines: bool) -> int:
    """How many (set, surface) rows ``run_compare`` will walk (for a progress bar)."""
    return len(_sets(specs, baselines)) * len(surface_names)


def run_compare(specs: list[str], robot_name: str, surface_names: list[str], baselines: bool,
                study_file: str | None, runs_dir: Path, out_dir: Path, workers: int = 1,
                progress: Callable[[int], None] | None = None, random_rollouts: int = 10) -> str:
    """Walk every set on every surface (``workers`` processes; the rows do not depend on it)
    and write the table and plots; ``progress(1)`` after each (set, surface)."""
    robot = load_robot(robot_name)                            # a bad robot fails here, once
    surfaces = [load_surface(s) for s in surface_names]
    sets = _sets(specs, baselines)
    tasks = [(robot_name, surface, drive, random_rollouts) for drive in sets
             for surface in surfaces]
    probe_folder(out_dir)                                     # said before the walks, not after them
    rows = map_in_order(_row, tasks, workers, progress)
    make_folder(out_dir)
    lines = ["| set | surface | stability % | matrix fwd 0..24 / bwd 8..24 | pitch +- [deg] | pitch RMS [deg] "
             "| ZMP err x/y [cm] | speed [m/s] | covered % of plan | own walk | survival % randomised "
             "| stair held fwd / bwd / left [m/s] / turn [rad/s] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        o = r["own"]
        mat = "".join("S" if c else "." for c in r["cells"][:7]) + " / " + "".join(
            "S" if c else "." for c in r["cells"][7:])
        lines.append(f"| {r['set']} | {r['surface']} | {r['stability']:.0f} | `{mat}` | {o.pitch_pm_deg:.2f} "
                     f"| {o.pitch_rms_deg:.2f} | {o.zmp_error_x_cm:.2f}/{o.zmp_error_y_cm:.2f} "
                     f"| {o.speed_mps:.4f} | {r['covered']:.0f} | {'stable' if o.survived else o.outcome} "
                     f"| {'-' if r['n_random'] == 0 else format(r['survival'], '.0f')} "
                     f"| {_speeds_text(r['speeds'])} |")
    summary = ["", "| set | mean stability % |", "|---|---|"]
    for label in (d.source for d in sets):
        vals = [r["stability"] for r in rows if r["set"] == label]
        summary.append(f"| {label} | {np.mean(vals):.0f} |")
    from .provenance import commit_of
    study_label = f"study {Path(study_file).stem}{commit_of(study_file)}" if study_file else "no study"
    heading = (f"Robot {robot.name} ({robot_name}); surfaces {', '.join(s.name for s in surfaces)}; "
               f"{study_label}.\n")
    text = heading + "\n" + "\n".join(lines + summary)
    defs = ("\nStability %: cells of the 10-cell EROS grid walked without a fall. Pitch +-: half the "
            "peak-to-peak torso pitch per gait cycle (EROS). ZMP error: mean |measured - reference| "
            "relative to the support foot. Covered %: torso distance / planned distance of the own "
            "walk (a gait that slides in place stays up but covers little). Survival % randomised: of "
            f"{random_rollouts} walks under the default randomisation (tuner/sim/randomisation.py, evaluation seeds), "
            "the share that did not fall (`gait-tuner robustness` gives more). Stair held: per direction, "
            "the highest stair of a staircase (8 stairs of 4 steps up to "
            + ", ".join(f"{d} {v:g}" for d, v in SPEED_STAIRS.items())
            + "; held = still up and at least 70% of the command measured on it, as the speed studies score), "
            "'-' for a direction the family does not walk (the cosine law walks forward and backward only).")
    write_text_atomic(out_dir / "compare.md", text + "\n" + defs + "\n")
    _plots(rows, sets, surfaces, out_dir, f"robot {robot.name}; {study_label}; surfaces "
           f"{', '.join(s.name for s in surfaces)}")
    if study_file:
        _study_plots(study_file, runs_dir, out_dir)
    return text + "\n" + defs + f"\nwrote {out_dir / 'compare.md'} and PNG plots"


PANELS = (("stability", "stability % (10-cell EROS grid)", "%"),
          ("pitch", "torso pitch RMS of its own walk [deg]", "deg"),
          ("speed", "forward speed of its own walk [m/s]", "m/s"),
          ("covered", "distance covered, % of plan", "%"))
FOOTNOTE = ("Own walk: each set's own gait, once per surface. Stability: share of the 10 EROS cells "
            "(0-24 mm forward, 8-24 mm backward) walked without a fall. Covered: torso distance / planned "
            "distance; above 100% the feet slid or the torso swayed forward of the plan, below it the "
            "steps slipped or the robot fell. A bar of 0 is drawn as a short stub marked 0.")


def _plots(rows, sets, surfaces, out_dir: Path, title: str) -> None:
    fig, axes = plt.subplots(1, len(PANELS), figsize=(19, 5))
    width = 0.8 / max(len(sets), 1)
    x = np.arange(len(surfaces))
    for i, label in enumerate(d.source for d in sets):
        mine = [next(r for r in rows if r["set"] == label and r["surface"] == s.name) for s in surfaces]
        values = {"stability": [r["stability"] for r in mine], "pitch": [r["own"].pitch_rms_deg for r in mine],
                  "speed": [0.0 if not r["own"].survived else r["own"].speed_mps for r in mine],
                  "covered": [r["covered"] for r in mine]}
        for ax, (key, _, _) in zip(axes, PANELS):
            bars = ax.bar(x + i * width, values[key], width, label=label, color=f"C{i}")
            for bar, v in zip(bars, values[key]):
                if v == 0 or not np.isfinite(v):        # an empty bar is invisible: mark it
                    ax.plot([bar.get_x(), bar.get_x() + bar.get_width()], [0, 0], color=f"C{i}", lw=4)
                    ax.annotate("0", (bar.get_x() + bar.get_width() / 2, 0), textcoords="offset points",
                                xytext=(0, 3), ha="center", fontsize=8, color=f"C{i}")
    for ax, (_, panel_title, _) in zip(axes, PANELS):
        ax.set_xticks(x + width * (len(sets) - 1) / 2, [s.name for s in surfaces])
        ax.set_title(panel_title, fontsize=10)
        ax.grid(alpha=0.3, axis="y")
    handles, labels = axes[0].get_legend_handles_labels()   # one legend, above the panels, off the bars
    fig.legend(handles, labels, loc="upper center", ncol=min(len(sets), 4), fontsize=8,
               bbox_to_anchor=(0.5, 0.935), frameon=False)
    fig.suptitle(title)
    fig.text(0.01, 0.01, FOOTNOTE, fontsize=7, wrap=True)
    fig.tight_layout(rect=(0, 0.06, 1, 0.88))
    save_figure(fig, out_dir / "compare.png", 110)
    plt.close(fig)


def history_plot(study, path: Path, title: str, feasible: Callable, target_name: str, maximise: bool) -> Path:
    """Each trial's first objective against its number: feasible trials on their own scale with
    the best-so-far line, trials that fell or were infeasible as marks along the top (their
    penalised scores would flatten the scale), pruned ones as grey marks."""
    from optuna.trial import TrialState
    done = [t for t in study.get_trials(deepcopy=False) if t.state in (TrialState.COMPLETE, TrialState.PRUNED)]
    good = [t for t in done if t.state == TrialState.COMPLETE and feasible(t)]
    bad = [t for t in done if t.state == TrialState.COMPLETE and not feasible(t)]
    pruned = [t for t in done if t.state == TrialState.PRUNED]
    fig, ax = plt.subplots(figsize=(9, 5))
    if good:
        ax.plot([t.number for t in good], [t.values[0] for t in good], "o", ms=4, color="C0",
                label=f"feasible trial ({len(good)})")
        best, xs, ys = None, [], []
        for t in sorted(good, key=lambda t: t.number):
            v = t.values[0]
            best = v if best is None else (max(best, v) if maximise else min(best, v))
            xs.append(t.number)
            ys.append(best)
        ax.step(xs + [max(t.number for t in done)], ys + [ys[-1]], where="post", color="C3", lw=2,
                label="best so far")
    ymin, ymax = ax.get_ylim() if good else (0.0, 1.0)
    top = ymax + 0.05 * (ymax - ymin)
    if bad:
        ax.plot([t.number for t in bad], [top] * len(bad), "x", color="0.3",
                label=f"fell or infeasible ({len(bad)}; score off scale)")
    if pruned:
        ax.plot([t.number for t in pruned], [top] * len(pruned), "|", color="0.6", ms=10,
                label=f"pruned early ({len(pruned)})")
    ax.set_ylim(ymin, top + 0.05 * (ymax - ymin))
    ax.set_xlabel("trial number")
    ax.set_ylabel(target_name)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, 100)
    plt.close(fig)
    return path


def _study_plots(study_file: str, runs_dir: Path, out_dir: Path) -> None:
    import optuna
    from optuna.visualization import matplotlib as ovm

    from ..search.workers import load_tuned_study, runs_of
    from ..search.study import load_study

    spec = load_study(study_file)
    try:
        study = load_tuned_study(spec, None, runs_of(spec, runs_dir))
    except UserError as exc:
        raise UserError(f"--study {study_file}: {exc}") from None
    from ..search.trials import trial_feasible
    from .provenance import commit_of
    maximise = study.directions[0] == optuna.study.StudyDirection.MAXIMIZE
    target = spec.scenario_room.target_label(spec.settings)
    where = (f"study {spec.name}{commit_of(spec.source)}: robot {Path(spec.robot).stem}, "
             f"{', '.join(spec.surfaces)}")
    history_plot(study, out_dir / "study_history.png", where, trial_feasible, target, maximise)
    titles = {"importances": f"parameter importances (fANOVA), {where}", "pareto": f"Pareto front, {where}"}
    plots = {"importances": lambda: ovm.plot_param_importances(study, target=lambda t: t.values[0],
                                                               target_name=target)}
    if len(spec.objectives) > 1:
        plots["pareto"] = lambda: ovm.plot_pareto_front(study, target_names=["pitch score [deg]", "speed [m/s]"])
    notes = []
    for name, make in plots.items():
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")      # Optuna marks its matplotlib plots experimental
                ax = make()
            fig = ax.figure if hasattr(ax, "figure") else ax[0].figure
            retitle(ax if hasattr(ax, "set_title") else ax[0], titles[name])
            fig.set_size_inches(8, 5)
            fig.tight_layout()
            save_figure(fig, out_dir / f"study_{name}.png", 100)
            plt.close(fig)
        except (ValueError, RuntimeError) as exc:
            notes.append(f"{name}: not drawn ({exc})")
    if notes:
        write_text_atomic(out_dir / "study_plots.txt", "\n".join(notes) + "\n")
