"""The papers' experiments in simulation (experiment) and the surfaces' calibration against EROS (calibrate)."""

from __future__ import annotations

import os
from pathlib import Path

import click

from gaits.files import probe_folder, write_text_atomic

from ..errors import UserError
from ..report.provenance import commit_of
from ..params_io import resolve_params
from .options import OutPath, Span, robot_option, surface_option, workers_option, JSON_OPTION, bar_options


@click.command()
@click.argument("paper", type=click.Choice(["eros", "tlipfm"]))
@robot_option("kidsize-pd", help="Built-in robot name or a robot map YAML (default: the built-in robot on round "
                                "one's servos, which the papers' figures and the surfaces' calibration were made "
                                "on; kidsize for its real servos).")
@surface_option("rigid", help="tlipfm only: the surface of the Table 3 walk.")
@click.option("--lift-scale", default=1.0, show_default=True, type=Span(0.05, 1.0),
              help="eros only: multiply the paper's foot lift (Z = 90-100 mm) by this (1: the paper's own).")
@click.option("--double-support", type=Span(0.0, 0.6), metavar="SHARE",
              help="eros only: share of each step with both feet loaded (ours; default: the baselines' 0.4). "
                   "0 is the paper's literal cycle, which falls sideways at the full lift.")
@click.option("--steps", "long_steps", default=40, show_default=True, type=click.IntRange(2, 500),
              help="eros only: steps of the distance-to-fall walks on pedestal 1.")
@workers_option("eros only: processes walking the matrix cells.")
@click.option("--tuned", "tuned_spec", metavar="PARAMS",
              help="eros only: also walk Table 8's cells with this EROS set's heel gain, C_DC, n and "
                   "double-support share (e.g. the export of the eros-paper study).")
@click.option("--pedestal", "pedestal_specs", multiple=True, metavar="N=SURFACE",
              help="eros only: walk pedestal N (1-4: grass50, grass30, grass10, carpet4) on another surface, a "
                   "built-in name or a surface YAML (repeat), e.g. 1=examples/surfaces/grass50-blades.yaml.")
@JSON_OPTION
@click.option("--out", "out_dir", type=OutPath(file_okay=False),
              help="Also write the report as Markdown (report.md) here.")
def experiment(paper: str, robot_name: str, surface_name: str, lift_scale: float, double_support: float | None,
               long_steps: int, workers: int, tuned_spec: str | None, pedestal_specs: tuple[str, ...], as_json: bool,
               out_dir: Path | None) -> None:
    """Run a paper's experiment in simulation and print it beside the paper's numbers.

    eros: the stability matrix of Tables 7-8 (4 pedestals x 10 step settings,
    without and with the optimisation) beside both readings of Table 7 (its
    cells and its text) and Table 8, per-pedestal and mean stability, pitch
    vibration, and the text's distance-to-fall walks on pedestal 1. tlipfm:
    Table 3 (ZMP error of LIPM, DLIPM and TLIPFM).
    """
    import json

    from tqdm import tqdm

    from ..report import experiments as ex
    from ..robots import load_robot
    from ..sim.surfaces import SURFACES, load_surface

    if paper != "eros" and (as_json or tuned_spec or pedestal_specs):
        raise UserError(f"{'--json' if as_json else '--tuned' if tuned_spec else '--pedestal'}: only the eros "
                        f"experiment takes it")
    tuned = None if tuned_spec is None else resolve_params(tuned_spec, "eros", "--tuned").params
    robot = load_robot(robot_name)
    if out_dir is not None:                   # said before the walks, not after them
        probe_folder(out_dir)
    if paper == "eros":
        surfaces = {p: SURFACES[name] for p, name in ex.PEDESTALS.items()}
        for spec in pedestal_specs:
            num, sep, name = spec.partition("=")
            if not sep or num.strip() not in {str(p) for p in ex.PEDESTALS} or not name.strip():
                raise UserError(f"--pedestal {spec!r}: expected N=SURFACE with N one of "
                                f"{', '.join(map(str, ex.PEDESTALS))} (e.g. 1=grass30)")
            name = name.strip()
            if name not in SURFACES and not os.path.lexists(name):
                raise UserError(f"--pedestal {spec!r}: {name!r} is not a built-in surface ({', '.join(SURFACES)}) "
                                f"and no such file")
            surfaces[int(num)] = load_surface(name)
        ds = ex.eros_params(8, False).double_support if double_support is None else double_support
        n = (2 + (tuned is not None)) * len(surfaces) * sum(len(v) for v in ex.EROS_STEPS_MM.values())
        with tqdm(total=n, desc="EROS matrix", unit="walk", **bar_options()) as bar:
            matrices = ex.eros_matrices(robot_name, surfaces, lift_scale=lift_scale, double_support=ds,
                                        workers=workers, progress=bar.update, tuned=tuned)
        without, with_ = matrices[:2]
        tuned_cells = matrices[2] if tuned is not None else None
        distance = ex.distance_to_fall(robot, surfaces[1], long_steps, lift_scale, ds)
        report = None
        if as_json:
            report = ex.eros_report(without, with_, distance, lift_scale, ds, tuned_cells)
            if tuned is not None:
                report["tuned"]["params"] = {k: getattr(tuned, k) for k in ex.TUNED_KNOBS}
                report["tuned"]["source"] = tuned_spec
            report["surfaces"] = {ex.PEDESTALS[p]: surfaces[p].name for p in sorted(surfaces)}
        text = (f"robot {robot.name}; foot lift: the paper's Z x {lift_scale:g}; double support "
                f"{ds:.0%} of each step (ours{'; 0 = the literal cycle' if ds == 0 else ''})\n"
                + ex.format_eros(without, False) + "\n\n" + ex.format_eros(with_, True) + "\n\n")
        if tuned_cells is not None:
            knobs = ", ".join(f"{k} {getattr(tuned, k):.3g}" for k in ex.TUNED_KNOBS)
            text += ex.format_eros(tuned_cells, True, f"Table 8 cells, tuned knobs from {tuned_spec} "
                                                      f"({knobs})") + "\n\n"
        text += ex.format_distance(distance, surfaces[1].name)
    else:
        report = None
        surface = load_surface(surface_name)
        text = f"robot {robot.name}\n" + ex.format_table3(ex.tlipfm_table3(robot, surface), surface.name)
    if out_dir is not None:                   # the report as Markdown, with --json too
        write_text_atomic(out_dir / "report.md", "```\n" + text + "\n```\n")
    if report is not None:                    # strict JSON: nothing else on stdout
        click.echo(json.dumps({"robot": robot.name, **report}, allow_nan=False))
        return
    click.echo(text)
    if out_dir is not None:
        click.echo(f"wrote {out_dir / 'report.md'}")


@click.command()
@workers_option()
@click.option("--lift-scale", default=1.0, show_default=True, type=Span(0.05, 1.0))
@click.option("--layer", type=click.Choice(["contact", "blades"]), default="contact", show_default=True,
              help="contact: grid the built-in pedestals' contact layer; blades: grid the blade layer's "
                   "creep and jams on the grass pedestals (the carpet keeps its contact layer).")
@click.option("--out", "out_dir", type=OutPath(file_okay=False), metavar="DIR",
              help="Also write each chosen pedestal as a surface file DIR/<name>.yaml, for "
                   "`experiment eros --pedestal N=DIR/<name>.yaml`.")
def calibrate(workers: int, lift_scale: float, layer: str, out_dir: Path | None) -> None:
    """Re-derive the pedestals' ground numbers from the EROS Tables 7-8 (slow: tens of minutes).

    Prints, per pedestal, the grid point whose simulated stability matrix agrees
    with the most table cells, and how much better it does than the built-in
    surface; tuner/sim/surfaces.py holds the values in use (--layer blades: the
    blade layer's grid, written with --out; the built-ins stay as they are).
    """
    from tqdm import tqdm

    from ..report import calibration as cal
    from ..report import experiments as ex
    from ..sim.surfaces import SURFACES

    if out_dir is not None:                   # said before tens of minutes of work, not after
        probe_folder(out_dir)
    n = len(cal.calibration_tasks(layer=layer))
    with tqdm(total=n, desc="calibration", unit="grid point", **bar_options()) as bar:
        gain, best, every = cal.calibrate(workers=workers, lift_scale=lift_scale, progress=bar.update, layer=layer)
    click.echo(f"layer: {layer}; heel gain (shared): {gain:g} rad/m; cells in Table 7 order, S = stable, . = fell")
    for ped in ex.PEDESTALS:
        now = cal.evaluate((ped, {}, (gain,), lift_scale, "contact"))[0]
        free = max((c for c in every if c.pedestal == ped and c.heel_gain == gain), key=lambda c: c.agree)
        c = best.get(ped)
        toe = (f"; toe test: landing pitch peak/final {now.toe[0]:.1f}/{now.toe[1]:.1f} deg"
               if ped in cal.TOE_STICKING else "")
        click.echo(f"P{ped} {ex.PEDESTALS[ped]:8s} built-in: agrees {now.agree}/20  without {now.without}  "
                   f"with {now.with_}{toe}")
        if c is None:
            click.echo(f"   no grid point keeps the toe-sticking test; the best without it: {free.values} "
                       f"agrees {free.agree}/20 (landing pitch {free.toe[0]:.1f}/{free.toe[1]:.1f} deg)")
        else:
            click.echo(f"   chosen: {c.values}  agrees {c.agree}/20  without {c.without}  with {c.with_}"
                       + (f"  (the best without the toe test: {free.values}, {free.agree}/20)"
                          if free.agree > c.agree else ""))
    click.echo("paper    without " + " | ".join(cal._paper_pattern(False, p) for p in ex.PEDESTALS)
               + "   with " + " | ".join(cal._paper_pattern(True, p) for p in ex.PEDESTALS))
    if out_dir is not None:
        made = f"gait-tuner calibrate --layer {layer} --lift-scale {lift_scale:g}{commit_of(__file__)}"
        for ped, c in best.items():
            surface = cal.pedestal_surface(ped, c.values, layer)
            if surface == SURFACES[ex.PEDESTALS[ped]]:
                click.echo(f"P{ped}: its built-in layer, nothing to write")
                continue
            header = (f"EROS pedestal {ped} ({ex.PEDESTALS[ped]}), chosen by {made}:\n"
                      f"agrees with {c.agree} of Tables 7-8's 20 cells (without {c.without}, with {c.with_}) at "
                      f"the heel gain {gain:g} rad/m.\nNothing of a real turf is measured: the tables choose "
                      f"among the grid's numbers.")
            path = write_text_atomic(out_dir / f"{surface.name}.yaml", cal.surface_yaml(surface, header))
            click.echo(f"wrote {path}")

