"""Sets measured against each other and the field: compare, robustness, transfer, versus."""

from __future__ import annotations

import math
from pathlib import Path

import click

from gaits.files import write_files_atomic, make_folder

from ..errors import UserError
from ..search.workers import tuned_study
from ..params_io import resolve_drive, resolve_params
from ..sim.randomisation import DEFAULT_PUSHES
from .walks import _skipped_rows_note, _tail
from .options import OutPath, robot_option, surface_option, workers_option, JSON_OPTION, RECORD_OPTION, RUNS_OPTION, STABILISER_OPTION, COMMANDS_OPTION, TAIL_OPTION, CONTROLLER_OPTION, COMMAND_OPTION, parse_command, bar_options


@click.command()
@click.argument("params_specs", nargs=-1, required=True, metavar="PARAMS...")
@robot_option(None, "Built-in robot name or robot map YAML. Default: the --study's robot, else kidsize.")
@click.option("--surfaces", "surface_names", default="grass50,grass30,grass10,carpet4", show_default=True,
              help="Comma-separated surfaces (names or files).")
@click.option("--baselines/--no-baselines", default=True, show_default=True,
              help="Add the paper's baselines of the same family (EROS: x24 without/with).")
@click.option("--study", "study_file", help="Also plot this study's optimisation history, Pareto front "
              "and parameter importances.")
@RUNS_OPTION
@click.option("--out", "out_dir", default="runs/compare", show_default=True,
              type=OutPath(file_okay=False))
@workers_option("Processes walking the (set, surface) pairs; the results do not depend on it.")
@click.option("--random-rollouts", type=click.IntRange(0, 1000), default=10, show_default=True,
              help="Randomised walks per (set, surface) for the survival column (0: none).")
@click.option("--video", is_flag=True,
              help="Also film every set's own walk on every surface: --out/videos/SET--SURFACE.mp4 (H.264, "
                   "~10 s each to render).")
def compare(params_specs: tuple[str, ...], robot_name: str | None, surface_names: str, baselines: bool,
            study_file: str | None, runs_dir: Path, out_dir: Path, workers: int, random_rollouts: int,
            video: bool) -> None:
    """Compare parameter sets side by side: stability matrix, stability %, pitch, ZMP error, speed.

    Each set walks every surface at the EROS experiment's step distances (0-24 mm
    forward, 8-24 mm backward) with its other parameters as they are. Prints a
    table and writes compare.md and PNG plots into --out.
    """
    from tqdm import tqdm

    from ..report.compare import n_rows, run_compare

    names = [s for s in surface_names.split(",") if s]
    if not names:
        raise UserError("--surfaces: give at least one surface name or file")
    if study_file is not None:
        tuned_study(study_file, None, runs_dir)     # a study with no runs: one line, before any walk
    for spec in params_specs:
        resolve_params(spec, None, "set")
    from ..sim.surfaces import load_surface
    for name in names:
        load_surface(name)
    if robot_name is None:
        if study_file is not None:
            from ..search.study import load_study
            robot_name = load_study(study_file).robot
        else:
            robot_name = "kidsize"
    with tqdm(total=n_rows(list(params_specs), names, baselines), desc="compare", unit="set x surface",
              **bar_options()) as bar:
        text = run_compare(list(params_specs), robot_name, names, baselines, study_file, runs_dir, out_dir,
                           workers=workers, progress=bar.update, random_rollouts=random_rollouts)
    click.echo(text)
    if video:
        from ..report.compare import render_sets
        with tqdm(total=n_rows(list(params_specs), names, baselines), desc="videos", unit="video",
                  **bar_options()) as bar:
            paths = render_sets(list(params_specs), robot_name, names, baselines, out_dir, progress=bar.update)
        click.echo(f"wrote {len(paths)} videos in {out_dir / 'videos'}")


@click.command()
@click.option("--params", "params_spec", metavar="PATH|NAME",
              help="Parameter YAML file or shipped set (`gait-tuner sets`); or --controller.")
@robot_option()
@surface_option()
@click.option("--rollouts", "--walks", "rollouts", default=100, show_default=True, type=click.IntRange(1, 100_000),
              help="Randomised rollouts (walks) without pushes (--walks: the same, as transfer and versus say).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1),
              help="Evaluation seed: rollout i uses seed (SEED, i) of the evaluation stream, never the tuning one.")
@click.option("--randomisation", "randomisation_spec", metavar="PATH|none",
              help="YAML mapping overriding the default distributions (see tuner/sim/randomisation.py), or 'none'.")
@click.option("--pushes", default=",".join(f"{p:g}" for p in DEFAULT_PUSHES), show_default=True,
              help="Comma-separated push impulses [N s] for the push sweep ('' for none).")
@click.option("--push-rollouts", default=20, show_default=True, type=click.IntRange(1, 10_000),
              help="Rollouts per push size.")
@COMMAND_OPTION
@COMMANDS_OPTION
@TAIL_OPTION
@STABILISER_OPTION
@CONTROLLER_OPTION
@workers_option()
@JSON_OPTION
@click.option("--plot", "plot_dir", type=OutPath(file_okay=False),
              help="Write robustness.png into this directory.")
@RECORD_OPTION
@click.option("--no-foot-sensors", is_flag=True,
              help="Walk as a robot whose soles measure nothing (an OP3, a Darwin-OP): the controller gets no "
                   "foot_force reading (a robot map says so for good with foot_sensors: false).")
def robustness(params_spec: str | None, robot_name: str, surface_name: str, rollouts: int, seed: int,
               randomisation_spec: str | None, pushes: str, push_rollouts: int, command: str | None,
               commands_file: Path | None, duration: float | None, stabiliser: bool | None,
               controller_file: Path | None, workers: int, as_json: bool, plot_dir: Path | None,
               record_dir: Path | None, no_foot_sensors: bool) -> None:
    """Does a gait survive what differs between our model and your robot and field?

    Walks it ROLLOUTS times with masses, servos, backlash, latencies, sensor noise, friction, turf
    and ground tilt drawn afresh each time (tuner/sim/randomisation.py gives the defaults and why),
    then PUSH-ROLLOUTS times per push size. Prints survival, time to fall, pitch and speed
    spread and the largest push survived in 90% of rollouts. With --command or --commands every
    rollout walks that command or stream.
    """
    import json

    from tqdm import tqdm

    from ..sim.randomisation import randomisation_from_mapping
    from ..sim.robustness import evaluate
    from ..yaml_input import read_yaml_file

    if params_spec is None and controller_file is None:
        raise UserError("give --params (a gait set) or --controller (your own)")
    drive = resolve_drive(params_spec, None, stabiliser=stabiliser, command=parse_command(command),
                          commands_file=commands_file, tail=_tail(duration, commands_file),
                          controller=controller_file)
    _skipped_rows_note(drive)
    doc = randomisation_spec if randomisation_spec in (None, "none") else \
        read_yaml_file(Path(randomisation_spec), "randomisation")
    if randomisation_spec not in (None, "none") and doc is None:
        raise UserError(f"--randomisation {randomisation_spec}: the file is empty (give a mapping of "
                        f"fields to override, or leave --randomisation out for the defaults)")
    rnd = randomisation_from_mapping(doc, randomisation_spec or "--randomisation")
    try:
        sizes = tuple(float(v) for v in pushes.split(",") if v.strip())
    except ValueError:
        raise UserError(f"--pushes {pushes!r}: expected comma-separated impulses in N s, e.g. 0.5,1,2") from None
    if any(not (0 < v <= 50) for v in sizes):
        raise UserError(f"--pushes {pushes!r}: each impulse must be in (0, 50] N s")
    from ..robots import load_robot
    if not drive.online:
        drive.table(load_robot(robot_name), 0.01)      # a command the set cannot walk: one line, before any work
    else:                                              # an engine clips a command to its envelope: said
        from ..sim.walk import envelope_note
        said = envelope_note(drive, drive.controller(load_robot(robot_name), 0.01))
        if said:
            click.echo(said, err=True)
    total = rollouts + len(sizes) * push_rollouts
    with tqdm(total=total, desc="robustness", unit="rollout", **bar_options()) as bar:
        report = evaluate(robot_name, surface_name, drive, rollouts=rollouts, seed=seed, randomisation=rnd,
                          pushes=sizes, push_rollouts=push_rollouts, workers=workers, progress=bar.update,
                          record=record_dir, without=("foot_force",) if no_foot_sensors else ())
    if record_dir is not None:
        click.echo(f"recorded {total} walk(s) into {record_dir}", err=True)
    if as_json:
        click.echo(json.dumps(report.to_dict(), indent=2, allow_nan=False))
    else:
        click.echo(report.format())
    if plot_dir is not None:
        from ..report.plots import plot_robustness
        path = plot_robustness(report, plot_dir)
        if not as_json:
            click.echo(f"wrote {path}")


@click.command()
@click.argument("params_spec", metavar="SET")
@robot_option(default=None, help="The identified robot map (identify servos' robot.yaml).")
@click.option("--surface", "surface_name", required=True, metavar="SURFACE.yaml",
              help="The identified ground (identify ground's surface.yaml).")
@click.option("--default-robot", "default_robot", metavar="NAME|PATH",
              help="The robot as the tool knew it before (default: the same map).")
@click.option("--default-surface", "default_surface", metavar="NAME|PATH",
              help="The surface as the tool knew it before (default: the one the identification started "
                   "from, when its name says it: grass30-identified -> grass30).")
@click.option("--walks", "--rollouts", "walks", default=20, show_default=True, type=click.IntRange(1, 10_000),
              help="Randomised match walks per world (--rollouts: the same, as robustness says).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1))
@workers_option()
@JSON_OPTION
def transfer(params_spec: str, robot_name: str | None, surface_name: str, default_robot: str | None,
             default_surface: str | None, walks: int, seed: int, workers: int, as_json: bool) -> None:
    """The gap before the match: SET's randomised match walks (commands every 1-3 s, the default
    randomisation, tuner/sim/match_walks.py) in the identified world beside the default one: survival,
    torso pitch and tracking, so a team sees what its field will do to its walk before it tunes."""
    import json

    from tqdm import tqdm

    from ..report.transfer import transfer_lines, world_summary
    from ..robots import BUILTIN_ROBOTS, load_robot
    from ..sim.robustness import scenario_walks
    from ..sim.match_walks import MatchDistribution
    from ..sim.surfaces import SURFACES, load_surface
    if robot_name is None:
        raise UserError("transfer: give --robot (the identified robot map)")
    identified = load_surface(surface_name)
    if default_surface is None:
        stem = identified.name.removesuffix("-identified")
        if stem not in SURFACES:
            raise UserError(f"transfer: --surface {surface_name}'s name ({identified.name}) does not say which "
                            f"surface it started from; give --default-surface")
        default_surface = stem
    load_surface(default_surface)
    default_robot = default_robot or robot_name
    for name in (robot_name, default_robot):
        if name not in BUILTIN_ROBOTS:
            load_robot(name)
    drive = resolve_drive(params_spec, None, what="set")
    worlds = {"default": (default_robot, default_surface), "identified": (robot_name, surface_name)}
    out = {}
    with tqdm(total=2 * walks, desc="transfer", unit="walk", **bar_options()) as bar:
        for key, (robot, surface) in worlds.items():
            rows = scenario_walks(robot, surface, drive, MatchDistribution(), walks=walks, seed=seed,
                                  workers=workers, progress=bar.update)
            out[key] = (f"{load_robot(robot).name} on {load_surface(surface).name}", world_summary(rows))
    if as_json:
        click.echo(json.dumps({k: {"world": w, **s} for k, (w, s) in out.items()}, allow_nan=False))
        return
    for line in transfer_lines(drive.source or params_spec, out):
        click.echo(line)


@click.command()
@click.argument("walk_specs", metavar="WALK...", nargs=-1, required=True)
@robot_option()
@click.option("--surfaces", "surface_names", default="rigid,grass30", show_default=True,
              help="Comma-separated surfaces (names or files).")
@click.option("--speeds", default="0.2,0.1,0.1,0.5", show_default=True, metavar="FWD,BACK,SIDE,TURN",
              help="The command asked in each direction [m/s, m/s, m/s, rad/s]; 0 leaves a direction out.")
@click.option("--walks", "--rollouts", "walks", default=20, show_default=True, type=click.IntRange(0, 10_000),
              help="Randomised match walks per walk and surface (0: none; --rollouts: the same, as robustness says).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1),
              help="Seed of the match walks and of the challenge's pushes.")
@click.option("--challenge/--no-challenge", default=True, show_default=True,
              help="The push-recovery challenge by the 2025 rules (3 kg bottle, rope 1.5 m).")
@click.option("--out", "out_dir", default="runs/versus", show_default=True, type=OutPath(file_okay=False),
              help="Folder for versus.md, versus.json and versus.png.")
@workers_option()
@JSON_OPTION
def versus(walk_specs: tuple[str, ...], robot_name: str, surface_names: str, speeds: str, walks: int, seed: int,
           challenge: bool, out_dir: Path, workers: int, as_json: bool) -> None:
    """Walks side by side on one robot: sets, controllers, policies, placo.

    Each WALK is a shipped or tuned set, a parameter file, a controller file (class:) or a policy
    file (policy:, an ONNX model). On every surface each is commanded forward, backward, sideways
    and turning (the speed reached), walks randomised match streams (survival, pitch, tracking),
    takes the challenge (largest D, momentum, M), and its cost per tick is timed.
    tuner/report/versus.py says how each figure is measured.
    """
    import json

    from tqdm import tqdm

    from ..report.tables import json_finite
    from ..report.versus import DIRECTIONS, versus_cell, versus_markdown, versus_plots
    from ..robots import load_robot
    from ..sim.surfaces import load_surface
    names = [n.strip() for n in surface_names.split(",") if n.strip()]
    if not names:
        raise UserError("--surfaces: give at least one surface name or file")
    try:
        asked = [float(v) for v in speeds.split(",")]
    except ValueError:
        raise UserError(f"--speeds {speeds!r}: expected four numbers FWD,BACK,SIDE,TURN") from None
    if len(asked) != 4 or any(not math.isfinite(v) or v < 0 or v > 2.0 for v in asked):
        raise UserError(f"--speeds {speeds!r}: expected four numbers in [0, 2] (m/s, m/s, m/s, rad/s)")
    speed_of = {d: v for d, v in zip(DIRECTIONS, asked) if v > 0}
    if not speed_of and not walks and not challenge:
        raise UserError("versus: nothing to measure (--speeds all 0, --walks 0 and --no-challenge): ask for at "
                        "least one")
    robot = load_robot(robot_name)
    for n in names:
        load_surface(n)
    drives = [(Path(spec).stem if spec.endswith((".yaml", ".yml")) else spec, resolve_drive(spec, None, what="walk"))
              for spec in walk_specs]
    labels = [label for label, _ in drives]
    if len(set(labels)) != len(labels):
        raise UserError(f"versus: two walks share the name {next(x for x in labels if labels.count(x) > 1)!r}: "
                        f"rename one file")
    from ..sim.walk import envelope_note
    for _, drive in drives:              # a policy on other servos is refused here, one without gains said
        said = envelope_note(drive, drive.controller(robot, robot.sim.control_period)) if drive.online else None
        if said:
            click.echo(said, err=True)
    make_folder(out_dir)
    per_cell = len(speed_of) + walks + (1 if challenge else 0)
    cells = []
    with tqdm(total=len(drives) * len(names) * per_cell, desc="versus", unit="walk", **bar_options()) as bar:
        for label, drive in drives:
            for n in names:
                cells.append((label, load_surface(n).name,
                              versus_cell(robot_name, n, drive, speeds=speed_of, walks=walks, seed=seed,
                                          challenge=challenge, workers=workers, progress=bar.update)))
    text = versus_markdown(robot.name, cells, speed_of)
    doc = json_finite({"robot": robot.name, "speeds": speed_of, "seed": seed,
                    "cells": [{"walk": w, "surface": s, **c} for w, s, c in cells]})
    write_files_atomic({out_dir / "versus.md": text, out_dir / "versus.json": json.dumps(doc, indent=1)})
    versus_plots(out_dir, cells, speed_of)
    if as_json:
        click.echo(json.dumps(doc, allow_nan=False))
        return
    click.echo(text)
    click.echo(f"wrote {out_dir / 'versus.md'}, versus.json and versus.png")

