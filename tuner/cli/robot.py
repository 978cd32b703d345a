"""Robots: checked (robot check), written for the robot side (robot export), made a walk (init), served on a simulated bus (bus serve); the shipped studies, surfaces and sets listed."""

from __future__ import annotations

import sys
from pathlib import Path

import click

import gaits
from gaits import list_baselines, load_baseline
from gaits.files import write_files_atomic

from ..errors import UserError
from .options import OutPath, Span, robot_option, surface_option, JSON_OPTION


@click.group()
def robot() -> None:
    """Check a robot before you tune for it (the built-in `kidsize` or your robot map YAML)."""


@robot.command(name="export")
@click.argument("robot_spec", metavar="MAP|NAME")
@click.option("--out", "out", required=True, type=OutPath(dir_okay=False),
              help="The robot file to write (YAML, read by gaits.robot.robot_file on the robot).")
@JSON_OPTION
def robot_export(robot_spec: str, out: Path, as_json: bool) -> None:
    """Write the one robot file the robot side needs: leg geometry, soles, mass, joint order and
    signs, ranges, servo limits, and each joint's servo id, units, direction and offset (the map's
    servos: section), so the loop on the robot loads no robot model and copies no number by hand."""
    from gaits.robot.robot_file import save_robot_file
    from ..report.provenance import commit_of
    from ..robots import load_robot
    robot = load_robot(robot_spec)
    robot.require_robot_side_reads()
    rf = robot.robot_file()
    joints, held = rf.joints, rf.held
    source = robot.map_path or robot_spec
    save_robot_file(out, rf, f"gait-tuner robot file of {robot.name} (from {source}{commit_of(__file__)}); "
                             f"read by gaits.robot.robot_file.load_robot_file on the robot")
    with_servo = sum(j.servo is not None for j in joints.values())
    if as_json:
        import json
        click.echo(json.dumps({"robot": robot.name, "wrote": str(out), "joints": len(joints),
                               "with_servo_id": with_servo, "held": len(held), "mass_kg": float(rf.mass),
                               "without_servo_id": [n for n, j in joints.items() if j.servo is None]},
                              indent=2, allow_nan=False))
    else:
        click.echo(f"wrote {out}: {len(joints)} joints ({with_servo} with a servo id), {len(held)} held, "
                   f"{rf.mass:.2f} kg")
    if with_servo < len(joints):
        click.echo(f"note: {len(joints) - with_servo} joint(s) have no servo id: give the map a servos: section "
                   f"(id, ticks_per_turn or units_per_rad, centre, direction, offset) to drive them", err=True)


@robot.command(name="check")
@click.argument("robot_spec", metavar="MAP|NAME")
@JSON_OPTION
@click.option("--no-stand", is_flag=True, help="Skip the 2 s stand test on the rigid floor.")
@click.option("--duration", default=2.0, show_default=True, type=Span(0.1, 30.0),
              help="Length of the stand test [s].")
def robot_check(robot_spec: str, as_json: bool, no_stand: bool, duration: float) -> None:
    """Load a robot and print what was derived and from where.

    Leg geometry (from the joint axis lines), joint signs, mass and CoM, sole polygon and
    sensor coverage, the servo model and its source, held poses, what the adapter changed in
    the file, and a stand test: the robot held for 2 s in the walking crouch on the rigid floor.
    Exit 0 when the map is valid (also when the stand test falls: the report says why).
    """
    import json

    from ..robots import load_robot
    from ..report.robot_check import format_report, robot_report

    report = robot_report(load_robot(robot_spec), stand=not no_stand, duration=duration)
    click.echo(json.dumps(report, indent=2, allow_nan=False) if as_json else format_report(report))


@click.command(name="studies")
@JSON_OPTION
def studies_cmd(as_json: bool) -> None:
    """List the shipped studies."""
    import json

    from ..search.study import list_studies, load_study
    rows = []
    for path in list_studies():
        spec = load_study(str(path))
        rows.append({"name": path.stem, "gait": spec.gait, "surfaces": list(spec.surfaces), "trials": spec.trials,
                     "scenario": spec.kind, "objectives": list(spec.objectives), "description": spec.description})
    if as_json:
        click.echo(json.dumps(rows, indent=2, allow_nan=False))
        return
    for r in rows:
        click.echo(f"{r['name']:26s} {r['gait']:7s} {','.join(r['surfaces']):32s} {r['trials']:4d} trials  "
                   f"{r['description'][:60]}")


@click.command()
@click.option("--test", "run_tests", is_flag=True,
              help="Run the sports-turf test methods on each surface (the Artificial Athlete drop test: force "
                   "reduction, vertical deformation, energy restitution; the rotational resistance test) beside "
                   "the published bands and the Webots grass of the virtual league.")
@click.option("--surface", "surface_names", multiple=True,
              help="A built-in surface or a surface YAML (repeat; default: every built-in surface).")
@JSON_OPTION
def surfaces(run_tests: bool, surface_names: tuple[str, ...], as_json: bool) -> None:
    """List the built-in surfaces and their contact parameters (--test: the turf test methods on them)."""
    import json

    from ..sim.surfaces import SURFACES, load_surface
    chosen = [load_surface(n) for n in surface_names] or list(SURFACES.values())
    if not run_tests:
        if as_json:
            click.echo(json.dumps({s.name: s.to_mapping() for s in chosen}, indent=2, allow_nan=False))
            return
        from ..sim.ground import kind_of
        kinds = [kind_of(s) for s in chosen]
        for s, kind in zip(chosen, kinds):
            click.echo(f"{s.name:8s} {kind.name:7s} layer {s.layer_height * 1000:4.0f} mm  drag {s.drag:5.1f} N s/m  "
                       f"friction {s.friction:.2f}  {s.description}")
        if any(kind.runs_in_step for kind in kinds):
            from ..sim import native_step
            native_step.install()
            click.echo(f"\ngrass drag gate on this machine: {native_step.status()}")
        return
    from ..report.surface_tests import surface_tests
    from ..report.tables import format_surface_tests
    report = surface_tests(chosen)
    click.echo(json.dumps(report, indent=2, allow_nan=False) if as_json else format_surface_tests(report))


@click.command()
@JSON_OPTION
def baselines(as_json: bool) -> None:
    """List the papers' shipped parameter sets (`gait-tuner sets` lists the tuned ones too)."""
    import json
    rows = [{"name": name, "family": gf.family, "source": gf.description}
            for name, gf in ((n, load_baseline(n)) for n in list_baselines())]
    if as_json:
        click.echo(json.dumps(rows, indent=2, allow_nan=False))
        return
    for r in rows:
        click.echo(f"{r['name']:22s} {r['family']:7s} {r['source'][:90]}")


@click.command()
@JSON_OPTION
def sets(as_json: bool) -> None:
    """List every shipped parameter set: the papers' baselines and the tuned results, with where
    each comes from (a study, trial and commit for a tuned one) and how it walks."""
    import json

    from ..params_io import RESULTS_DIR, list_results
    rows = []
    for name in list_baselines():
        gf = load_baseline(name)
        rows.append({"name": name, "kind": "baseline", "family": gf.family, "online": gf.engine is not None,
                     "stabiliser": gf.stabiliser is not None, "source": gf.description})
    for name in list_results():
        gf = gaits.load_gait_file(RESULTS_DIR / f"{name}.yaml")
        rows.append({"name": name, "kind": "tuned", "family": gf.family, "online": gf.engine is not None,
                     "stabiliser": gf.stabiliser is not None, "source": gf.description})
    if as_json:
        click.echo(json.dumps(rows, indent=2))
        return
    for r in rows:
        how = "engine" if r["online"] else ("table+imu" if r["stabiliser"] else "table")
        click.echo(f"{r['name']:28s} {r['kind']:8s} {r['family']:7s} {how:9s} {r['source'][:80]}")


@click.command()
@robot_option(help="Built-in robot name or your robot map YAML.")
@surface_option()
@click.option("--for", "purpose", type=click.Choice(["match", "speed", "push"]), default="match", show_default=True,
              help="What the walk is for: match walks (the online engine), speed staircases (a table), the "
                   "push-recovery challenge (the engine stepping in place).")
@click.option("--speed", "top_speed", type=float, default=0.2, show_default=True,
              help="The fastest forward walk asked of the robot [m/s]: the starting steps and the study's walks "
                   "reach it.")
@click.option("--out", "out_dir", type=OutPath(file_okay=False), default=None,
              help="Folder for the study and its starting set [default: runs/init/ROBOT-SURFACE-PURPOSE].")
@JSON_OPTION
def init(robot_name: str, surface_name: str, purpose: str, top_speed: float, out_dir: Path | None,
         as_json: bool) -> None:
    """Make a walk for a robot: a starting set whose gait model has the robot's own masses, CoM
    height, stance and a step its knees' servos can carry, and the study that tunes it on the
    surface (tune it with `gait-tuner tune`, then `export`). Says where each number came from."""
    import yaml

    from ..robots import BUILTIN_ROBOTS, load_robot
    from ..search.initial import falls_standing, initial_walk
    from ..sim.surfaces import load_surface
    robot = load_robot(robot_name)
    robot.require_robot_side_reads()    # a walk made with sole forces the robot side cannot read
    surface = load_surface(surface_name)
    ref = robot_name if robot_name in BUILTIN_ROBOTS else str(Path(robot_name).resolve())
    name = f"{robot.name}-{surface.name}-{purpose}"
    out_dir = out_dir or Path("runs") / "init" / name
    iw = initial_walk(robot, ref, surface, purpose, name=name, start_file=f"{name}-start.yaml", top_speed=top_speed)
    desc = (f"gait-tuner init for {robot.name} on {surface.name} ({purpose}): "
            + "; ".join(f"{k} {iw.value(k):g} from {why}" for k, why in iw.sources.items()))
    start = out_dir / f"{name}-start.yaml"
    study = out_dir / f"{name}.yaml"
    files = {start: gaits.gait_file_text(iw.params, desc, None, iw.engine)}
    rungs = []
    for share, rung in iw.ladder:
        path = out_dir / f"{name}-start-{round(rung.period * 1000)}ms.yaml"
        files[path] = gaits.gait_file_text(rung, f"{desc}; then the period shortened to {rung.period:g} s (t1, t2 "
                                                 f"with it), whose swing asks the knee {share:.0%} of its speed",
                                           None, iw.engine)
        rungs.append(path.name)
    if rungs:
        iw.study["baselines"] = rungs
    walked = ref                        # the robot the study walks
    robot_file = None
    if robot.map_path:
        # the robot the study walks, beside it: a map that extends the team's (an edit to theirs
        # reaches it) with the legs' gains init sized to the robot's weight, if it sized them; every
        # later command (robustness, simulate, the bus) walks the set on it
        from ..robots.robot_map import extending
        robot_file = out_dir / f"{name}-robot.yaml"
        said = (f"with the legs' servo gains sized to the robot's weight by gait-tuner init\n# ({iw.servo_source})"
                if iw.servo else "as it is (its servos state their gains)")
        files[robot_file] = (f"# the robot study {name} walks: {Path(robot.map_path).name} {said};\n# edit "
                             f"your map for the robot, this file for what the study changes of it\n"
                             + yaml.safe_dump(extending(Path(robot.map_path), out_dir,
                                                        {"legs": iw.servo} if iw.servo else {}), sort_keys=False))
        iw.study["robot"] = robot_file.name
        walked = str(robot_file)
    stream_file = None
    if purpose == "match":
        # a held-out match stream of the walks the study tunes for (its speeds, another seed): what
        # to hold the tuned set to after (robustness --commands)
        from ..search.initial import held_out_stream
        stream_file = out_dir / f"{name}-stream.csv"
        files[stream_file] = held_out_stream(iw.study["scenario"], f"{robot.name} on {surface.name}")
    iw.study["runs"] = "runs"           # its journal beside it: tune, export, trials find it from any folder
    files[study] = ("# written by gait-tuner init; edit the space and the budget as you like (the scoring -\n"
                    "# robot, surfaces, scenario, objectives - is kept with the trials: a change of it is a new name)\n"
                    + yaml.safe_dump(iw.study, sort_keys=False))
    write_files_atomic(files)
    best = out_dir / "best.yaml"
    if not as_json:                     # the words first: the stand test below takes a second
        _said_init(robot, surface, purpose, iw, files, study, best, walked, stream_file)
    fell = falls_standing(walked, surface, str(start))
    if as_json:
        import json
        nxt = {"tune": f"gait-tuner tune {study} --workers 2", "export": f"gait-tuner export {study} --out {best}"}
        if stream_file is not None:
            nxt["robustness"] = (f"gait-tuner robustness --robot {walked} --params {best} --surface {surface.name} "
                                 f"--commands {stream_file}")
        click.echo(json.dumps({
            "robot": robot.name, "surface": surface.name, "purpose": purpose,
            "values": {k: {"value": iw.value(k), "from": why} for k, why in iw.sources.items()},
            "t1": iw.params.t1, "t2": iw.params.t2,
            "also_tried": [{"period_s": rung.period, "knee_speed_share": share} for share, rung in iw.ladder],
            "servo": {"legs": dict(iw.servo) if iw.servo else None, "from": iw.servo_source},
            "study": str(study), "start": str(start), "robot_file": None if robot_file is None else str(robot_file),
            "stream": None if stream_file is None else str(stream_file), "wrote": [str(p) for p in files],
            "next": nxt, "falls_standing": fell}, indent=2, allow_nan=False))
    if fell is not None:
        click.echo(f"warning: standing still in the start set's pose the robot falls ({fell}): a study from it "
                   f"will keep nothing; give its legs servos that hold its weight (the map's servo:, "
                   f"`gait-tuner robot check`)", err=True)


def _said_init(robot, surface, purpose, iw, files, study, best, walked, stream_file) -> None:
    """init's account in words: each number and where it came from, the files, what to run next."""
    click.echo(f"{robot.name} on {surface.name}, for {purpose}:")
    for k, why in iw.sources.items():
        click.echo(f"  {k:11s} {iw.value(k):8.4g}  from {why}")
    click.echo(f"  {'t1, t2':11s} {iw.params.t1:.3g}, {iw.params.t2:.3g}  TKU-X's shares of the step")
    for share, rung in iw.ladder:
        click.echo(f"  {'also tried':11s} {rung.period:8.4g}  the period whose swing asks the knee {share:.0%} of its speed")
    if iw.servo:
        key, value = next(iter(iw.servo.items()))
        click.echo(f"  {'legs ' + key:11s} {value:8.4g}  {iw.servo_source}")
    else:
        click.echo(f"  {'servo gains':11s} {'':8s}  {iw.servo_source}")
    click.echo("".join(f"wrote {p}\n" for p in files) + f"tune it: gait-tuner tune {study} --workers 2")
    click.echo(f"then:    gait-tuner export {study} --out {best}")
    if stream_file is not None:
        click.echo(f"and:     gait-tuner robustness --robot {walked} --params {best} --surface {surface.name} "
                   f"--commands {stream_file}")


@click.group()
def bus() -> None:
    """A simulated Dynamixel bus: the robot-side code (gait-tuner-loop) drives the simulated robot
    through real Protocol 2.0 packets on a pseudo-terminal (tuner/sim/bus.py)."""


@bus.command(name="serve")
@robot_option(help="Built-in robot name or a robot map YAML (with a servos: section).")
@surface_option()
@click.option("--link", metavar="PATH[,PATH...]", default=None,
              help="Also make this path a link to the bus's pseudo-terminal (a fixed name for the client); a robot "
                   "on several buses (its map's port:): one path a bus, comma-separated.")
@click.option("--baud", default="1000000", show_default=True,
              type=click.Choice(["57600", "115200", "1000000", "2000000", "3000000", "4000000"]))
@click.option("--duration", default=600.0, show_default=True, type=Span(0.1, 86400.0),
              help="Longest walk [s] of simulated time.")
@click.option("--idle", default=5.0, show_default=True, type=Span(0.5, 600.0),
              help="End once the client has been silent this long [s] (counted from its first byte).")
@click.option("--wait", default=300.0, show_default=True, type=Span(0.5, 86400.0),
              help="How long the bus waits for its client's first byte [s] (you start the loop in another shell).")
@click.option("--hang", is_flag=True, help="The robot hangs in a harness (for a sweep: gait-tuner-loop --sweep).")
@click.option("--randomisation", "randomisation_spec", metavar="YAML|default|none", default="none", show_default=True,
              help="Perturb the simulated robot and field as `robustness` does (default: its defaults; a YAML "
                   "overrides fields): walk I of --seed S is robustness's rollout I of the same seed.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1),
              help="With --randomisation: the evaluation seed.")
@click.option("--walk", "walk_index", default=0, show_default=True, type=click.IntRange(0, 999_999),
              help="With --randomisation: which of the seed's walks (robustness's rollout number).")
def bus_serve(robot_name: str, surface_name: str, link: str | None, baud: str, duration: float, idle: float,
              wait: float, hang: bool, randomisation_spec: str, seed: int, walk_index: int) -> None:
    """Serve ROBOT's servos and IMU on a pseudo-terminal, answered by MuJoCo in lockstep (a tick of
    physics per sync write of goal positions). Prints the bus's path, then what the walk did.
    With --hang the robot hangs in a harness (its torso held, feet off the ground): play a sweep
    on it (gait-tuner-loop --sweep) and record what identify servos fits."""
    ctx = click.get_current_context()
    chosen = [f"--{o.replace('_index', '')}" for o in ("seed", "walk_index")
              if ctx.get_parameter_source(o).name != "DEFAULT"]
    if chosen and randomisation_spec == "none":
        raise UserError(f"{' and '.join(chosen)} choose a randomised walk: give --randomisation default (or a YAML) "
                        f"too")
    from ..robots import load_robot
    from ..sim.bus import serve
    from ..sim.rollout import Simulator
    from ..sim.surfaces import load_surface
    robot = load_robot(robot_name)
    rf = robot.robot_file()
    missing = [o for o, j in rf.joints.items() if j.servo is None]
    if missing:
        raise UserError(f"{robot_name}: no servo id for {', '.join(missing)}: give the map a servos: section")
    robot.require_robot_side_reads()
    if hang:
        from ..identify.harness import Harness, HangingSim
        sim = HangingSim(Harness(robot))
    else:
        sim = Simulator(robot, load_surface(surface_name))
    perturb = None
    if randomisation_spec != "none":
        if hang:
            raise UserError("--randomisation is for a walk on the ground, not --hang")
        from ..sim.randomisation import EVALUATE, draw, randomisation_from_mapping
        from ..yaml_input import read_yaml_file
        doc = None if randomisation_spec == "default" else read_yaml_file(Path(randomisation_spec), "randomisation")
        perturb = draw(randomisation_from_mapping(doc, randomisation_spec), (seed, walk_index), *sim.n_random(),
                       namespace=EVALUATE)

    boards = ([f"IMU id {rf.imu.id} ({rf.imu.protocol})"] if rf.imu is not None else ["no IMU"]) + \
        ([f"sole boards {rf.soles[0].id} left, {rf.soles[1].id} right ({rf.sole_protocol})"]
         if rf.foot_sensors and rf.soles is not None else [])

    def ready(paths: list[str]) -> None:
        click.echo(f"bus of {robot.name} on {sim.surface.name} at {','.join(paths)} ({baud} baud, "
                   f"{len(rf.joints)} servos, {', '.join(boards)})", err=False)
        sys.stdout.flush()
    links = None if link is None else [p.strip() for p in link.split(",")]
    out = serve(sim, rf, baudrate=int(baud), link=links, idle=idle, wait=wait,
                duration=duration, ready=ready, perturb=perturb)
    click.echo(f"served {out['ticks']} ticks ({out['ticks'] * sim.control_period:.2f} s); ended: {out['ended']}"
               + (f"; the walk: {out['outcome']}" if out["outcome"] else "")
               + (f"; the torso went {out['travel'][0]:.2f} m ({out['travel'][1]:.3f} m/s)" if out["travel"] else "")
               + (f"; {out['ignored']} packet(s) not answered" if out["ignored"] else "")
               + (f"; {out['held']} tick(s) the client read again without writing (the goals held)"
                  if out["held"] else "")
               + (f"; randomised: seed {seed}, walk {walk_index}" if perturb is not None else ""))
    if out["ticks"]:
        click.echo(f"on the wire: {out['bytes_per_tick']:.0f} bytes a tick, {out['wire_ms_per_tick']:.2f} ms at {baud} "
                   f"baud (a real bus adds this, and each servo's return delay, to every tick's latency)")

