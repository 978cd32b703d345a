"""``gait-tuner train``: a set's residual trained in the closed loop (``tuner/search/train.py``)."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import UserError
from .options import JSON_OPTION, OutPath, Span, parse_command, robot_option, surface_option, workers_option

__all__ = ["train"]


@click.command()
@click.argument("set_spec", metavar="SET")
@robot_option()
@surface_option(help="A surface (name or file), or several comma-separated: an evaluation's rollouts take "
                     "them in turn.")
@click.option("--objective", type=click.Choice(["match", "command", "push"]), default="match", show_default=True,
              help="match: randomised match walks (survival, tracking); command: --command held 10 s under the "
                   "randomisation; push: the 2025 challenge's trial at about --distance.")
@click.option("--command", "command_text", default="0.3,0,0", show_default=True, metavar="VX,VY,WZ",
              help="command: the walk command held [m/s, m/s, rad/s].")
@click.option("--distance", type=Span(0.05, 1.125), default=0.5, show_default=True,
              help="push: the bottle's release distance D [m].")
@click.option("--iterations", type=click.IntRange(1, 10_000), default=30, show_default=True,
              help="Random-search iterations.")
@click.option("--directions", type=click.IntRange(1, 256), default=8, show_default=True,
              help="Random directions walked per iteration (each both ways).")
@click.option("--top", type=click.IntRange(1, 256), default=4, show_default=True,
              help="The directions kept per iteration (at most --directions).")
@click.option("--noise", type=Span(1e-4, 1.0), default=0.03, show_default=True,
              help="A direction's size [rad per unit feature].")
@click.option("--step", type=Span(1e-4, 1.0), default=0.02, show_default=True, help="The step along the kept "
                                                                                    "directions.")
@click.option("--walks", type=click.IntRange(1, 100), default=3, show_default=True,
              help="Rollouts per evaluation (the same ones for each sign of a direction).")
@click.option("--limit", type=Span(0.01, 1.0), default=None,
              help="The most a correction moves a joint [rad] (default: the set's residual's, else 0.3).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1),
              help="Seed of the directions and the rollouts (tuning seeds: never an evaluation walk).")
@click.option("--out", "out_path", required=True, type=OutPath(dir_okay=False),
              help="The set to write (rewritten after every iteration: an interrupted run keeps its last).")
@workers_option()
@JSON_OPTION
def train(set_spec: str, robot_name: str, surface_name: str, objective: str, command_text: str, distance: float,
          iterations: int,
          directions: int, top: int, noise: float, step: float, walks: int, limit: float | None, seed: int,
          out_path: Path, workers: int, as_json: bool) -> None:
    """Train a set's residual (a linear correction on the walk engine's leg targets) in the simulator's
    closed loop: random search over randomised match walks or push trials, the set written after
    every iteration.

    The correction is a map from the IMU, the gyro, the command, the step's progress and the CoM's
    error (gaits/engine/residual.py), searched by augmented random search (ARS) in the simulator's own
    loop (tuner/search/train.py).

    SET is an engine set (tlipfm with an engine: section); a residual it holds is the start, so
    `train OUT --out OUT --seed N` goes on from where a run stopped (a new seed walks new rollouts;
    the same seed walks the first run's again). Measure the result with `versus`, `robustness` or
    `challenge` on seeds it was not trained on (theirs are evaluation seeds, train's tuning ones).
    """
    import json

    from ..params_io import resolve_drive
    from ..robots import load_robot
    from ..search.train import TrainSettings, save_trained, train as run_train
    from ..sim.surfaces import load_surface
    if top > directions:
        raise UserError(f"--top {top}: at most --directions ({directions})")
    command = parse_command(command_text)
    settings = TrainSettings(iterations=iterations, directions=directions, top=top, noise=noise, step=step,
                             walks=walks, objective=objective, distance=distance, seed=seed,
                             command=tuple(float(v) for v in command.as_array()))
    drive = resolve_drive(set_spec, None, what="set")
    if drive.user is not None:
        raise UserError(f"{set_spec}: a controller or policy file: train needs an engine set")
    robot = load_robot(robot_name)
    names = [n.strip() for n in surface_name.split(",") if n.strip()]
    if not names:
        raise UserError("--surface: give a surface name or file (or several, comma-separated)")
    if len(names) > walks:
        raise UserError(f"--surface: {len(names)} surfaces but --walks {walks}: give each surface a walk at least")
    shown = ", ".join(load_surface(n).name for n in names)
    what = (f"{objective} ({walks} walk(s) an evaluation" + (f", D {distance:g} m" if objective == "push" else "")
            + (f", command {command_text}" if objective == "command" else "") + ")")

    def write(residual, done: int) -> None:
        save_trained(out_path, drive, residual, f"{drive.source}: its residual trained by gait-tuner train on "
                                                f"{robot.name} / {shown}, {what}, seed {seed}: {done} of "
                                                f"{iterations} iterations")

    from gaits.files import probe_folder
    probe_folder(out_path.parent)        # a place the set cannot be written: said before any other line

    def progress(it: int, reward: float, stood: float) -> None:      # on stderr: --json's stdout stays one object
        click.echo(f"iteration {it}/{iterations}: reward {reward:.3f}, stood {stood:.0%} of its "
                   f"{walks} walk(s)", err=True)

    click.echo(f"train {set_spec} on {robot.name} / {shown}: {what}, {iterations} iterations of "
               f"{2 * directions + 1} evaluations, {workers} worker(s); writing {out_path}", err=True)
    result = run_train(drive, robot_name, names, settings, workers=workers, limit=limit, progress=progress,
                       checkpoint=write)
    if as_json:
        click.echo(json.dumps({"out": str(out_path), "rewards": result.rewards, "stood": result.stood,
                               "residual": result.residual.to_mapping()}, allow_nan=False))
        return
    click.echo(f"wrote {out_path}: measure it on evaluation seeds, e.g. gait-tuner versus {out_path} "
               f"--robot {robot_name} --surfaces {surface_name}")
