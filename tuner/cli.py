"""The ``gait-tuner`` command line: one subcommand per verb.

Exit codes: 0 done; 1 internal error (a bug: please report it); 2 bad input
(a file, a name or a value; the one-line message says which).
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

import gaits
from gaits import ParamError, UnreachableTargetError, families, family_class, list_baselines, load_baseline

from .errors import EXIT_INTERNAL, EXIT_USAGE, UserError
from .params_io import DEFAULT_BASELINE, resolve_params

__all__ = ["cli", "main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="gait-tuner")
def cli() -> None:
    """Tune the walking gaits of kid-size humanoid robots in simulation, per ground surface.

    Gait families: eros (quarter-circle trajectory, heel strike, landing
    deceleration), tlipfm (natural ZMP on the three-mass LIPM plus flywheel;
    lipm and dlipm as its comparisons), cosine (5-DoF cosine-law walking diagram).
    """


@cli.command()
@click.option("--gait", "family", type=click.Choice(["eros", "tlipfm", "cosine"]),
              help="Gait family (taken from the parameter file if omitted).")
@click.option("--params", "params_spec", metavar="PATH|BASELINE",
              help="Parameter YAML file or shipped baseline name (see `gait-tuner baselines`). "
                   "Default: the family's paper baseline.")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory for joints.csv, references.png and params.yaml.")
@click.option("--dt", default=0.01, show_default=True, type=float,
              help="Control period of the joint table [s].")
@click.option("--model", type=click.Choice(["lipm", "dlipm", "tlipfm"]),
              help="tlipfm only: override the parameter file's CoM model.")
@click.option("--no-plot", is_flag=True, help="Skip the PNG.")
def trajectory(family: str | None, params_spec: str | None, out_dir: Path, dt: float,
               model: str | None, no_plot: bool) -> None:
    """Generate a gait's joint table q_ref(t) and its Cartesian references.

    Writes OUT/joints.csv (time, 20 joint targets [rad], CoM, ZMP reference,
    pelvis and feet [m], support phase), OUT/params.yaml (the exact parameters
    used) and OUT/references.png.
    """
    gait_file = resolve_params(params_spec, family)
    params = gait_file.params
    if model is not None:
        if params.FAMILY != "tlipfm":
            raise UserError("--model applies to the tlipfm family only")
        params = params.replace(model=model)
    traj = gaits.generate(params, dt=dt)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = traj.to_csv(out_dir / "joints.csv")
    yaml_path = gaits.save_gait_file(out_dir / "params.yaml", params, gait_file.description)
    click.echo(f"{traj.family}: {len(traj.t)} samples every {dt:g} s, {traj.duration:.2f} s, "
               f"walked {traj.p_world_com[-1, 0] - traj.p_world_com[0, 0]:+.3f} m")
    click.echo(f"wrote {csv_path}")
    click.echo(f"wrote {yaml_path}")
    if not no_plot:
        from .plots import plot_references
        png = plot_references(traj, out_dir / "references.png",
                              title=f"{traj.family} ({params_spec or DEFAULT_BASELINE[params.FAMILY]})")
        click.echo(f"wrote {png}")


@cli.command()
def baselines() -> None:
    """List the papers' shipped parameter sets."""
    for name in list_baselines():
        gf = load_baseline(name)
        click.echo(f"{name:22s} {gf.family:7s} {gf.description[:90]}")


@cli.command(name="params")
@click.argument("family", type=click.Choice(["eros", "tlipfm", "cosine"]))
def params_cmd(family: str) -> None:
    """Print a family's parameters: name, default, unit, allowed range, paper symbol."""
    for row in family_class(family).field_table():
        paper = row["paper"] or ""
        click.echo(f"{row['name']:22s} {str(row['default']):>12.12s}  {row['range']:28s} "
                   f"{paper:8s} {row['doc']}")


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turn bad input into one line on stderr and exit code 2."""
    assert families()  # the registry is filled on import of gaits
    try:
        cli.main(args=argv, prog_name="gait-tuner", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.Abort:
        click.echo("gait-tuner: interrupted", err=True)
        return 130
    except click.ClickException as exc:
        exc.show()
        return EXIT_USAGE
    except (UserError, ParamError, UnreachableTargetError) as exc:
        click.echo(f"gait-tuner: error: {exc}", err=True)
        return EXIT_USAGE
    except Exception as exc:  # noqa: BLE001 - last resort: one line, not a traceback
        click.echo(f"gait-tuner: internal error: {exc.__class__.__name__}: {exc} "
                   f"(please report it)", err=True)
        return EXIT_INTERNAL
    return 0


if __name__ == "__main__":
    sys.exit(main())


def run() -> None:
    """Console-script entry: exit with :func:`main`'s code."""
    sys.exit(main())
