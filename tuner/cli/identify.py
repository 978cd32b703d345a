"""Recordings and identification: what a recording holds (log info), a sweep to record (excite), servos and ground fitted (identify servos, identify ground)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from gaits.files import probe_folder

from ..errors import UserError
from .options import OutPath, Span, robot_option, surface_option, JSON_OPTION, RECORDING_OPTION, TOPICS_OPTION, running_total

#: [rad] the encoders' noise a servo fit takes unless told: a walk's fit takes it from each sensor's
#: own (tuner/identify/ground.py NOISE, the randomisation's defaults), so on a walk only this value is
#: accepted; written here, not imported, so the verb's start imports no simulator (a test ties the two)
ENCODER_NOISE = 0.001


@click.group()
def log() -> None:
    """Recordings of what a robot (or the simulator) did: MCAP files in the RoboCup HumanoidDataset
    layout (gaits/robot/recorder.py)."""


@log.command(name="info")
@click.argument("recording", type=click.Path(dir_okay=False, path_type=Path))
@JSON_OPTION
def log_info(recording: Path, as_json: bool) -> None:
    """Say what RECORDING holds: its robot, task and controller, its duration, and per channel the
    messages, the rate and the gaps (intervals over three times the median) or times that go back."""
    import json

    from gaits.files import MAX_BYTES, read_bytes_checked
    from gaits.robot.recorder import read_recording, recording_info
    read_bytes_checked(recording, "recording", 1000 * MAX_BYTES["csv"], UserError)     # a regular file of a sane size
    try:
        info = recording_info(read_recording(recording))
    except ValueError as exc:
        raise UserError(str(exc)) from None
    if as_json:
        click.echo(json.dumps(info, allow_nan=False))
        return
    meta = info["meta"]
    click.echo(f"{recording}: robot {meta['robot']}, task {meta['task']}, "
               f"{'simulated' if meta['simulated'] else 'on the robot'}"
               + (f" on {meta['surface']}" if meta["surface"] else "") + f"; {info['duration_s']:.2f} s"
               + ("; the file is cut short: what it held up to the cut" if info["truncated"] else ""))
    if meta["controller"]:
        click.echo(f"  controller: {meta['controller']}")
    for topic, c in info["channels"].items():
        rate = "-" if c["rate_hz"] is None else f"{c['rate_hz']:.1f} Hz"
        extra = (f"; {len(c['gaps'])} gap(s), the longest {max(g[1] for g in c['gaps']):.3f} s at "
                 f"{max(c['gaps'], key=lambda g: g[1])[0]:.2f} s" if c["gaps"] else "")
        extra += f"; time goes back at {c['backwards'][0]:.3f} s" if c["backwards"] else ""
        click.echo(f"  {topic:18s} {c['messages']:7d} messages  {rate:>9s}{extra}")


@click.command()
@robot_option(help="Built-in robot name or a robot map YAML.")
@click.option("--out", required=True, type=OutPath(dir_okay=False), metavar="SWEEP.csv",
              help="Where to write the sweep: t, then target.<joint> per servo joint [rad, our names and signs].")
@click.option("--duration", default=30.0, show_default=True, type=Span(5.0, 600.0), help="Length of the sweep [s].")
@click.option("--f-max", default=2.5, show_default=True, type=Span(0.5, 20.0),
              help="Highest frequency of the chirp [Hz] (it rises from 0.2 Hz).")
@click.option("--amplitude", default=0.4, show_default=True, type=Span(0.01, 1.5),
              help="Largest swing of a joint about the middle of its range [rad].")
@click.option("--steps/--no-steps", default=True, show_default=True,
              help="After the sweep, large steps one joint at a time (held 0.4 s each): they drive the motors at "
                   "full duty along their torque-speed line, which tells the stall torque from the back-EMF.")
@click.option("--step-size", default=0.6, show_default=True, type=Span(0.05, 1.5),
              help="The steps' size [rad] (less where a joint's range or its limbs leave less room).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1),
              help="The joints' phases.")
@click.option("--simulate", "simulate_to", type=OutPath(dir_okay=False), metavar="REC.mcap",
              help="Also play the sweep on the simulated robot in its harness and write the recording "
                   "a robot would make of it (the map's servos, 1 mrad encoder noise).")
@JSON_OPTION
def excite(robot_name: str, out: Path, duration: float, f_max: float, amplitude: float, steps: bool, step_size: float,
           seed: int, simulate_to: Path | None, as_json: bool) -> None:
    """Write the joint sweep to play on the robot hanging in a harness (feet off the ground), the
    recording to identify its servos from: a chirp per joint within its range, at most 60 % of its
    servo's speed and, played on the simulated harness, 80 % of its torque. Play it with
    `gait-tuner-loop --sweep SWEEP.csv --port ... --robot robot.yaml --record sweep.mcap`."""
    import json

    from gaits.files import write_text_atomic

    from ..robots import load_robot
    from ..identify.harness import ENCODER_TICKS_LEAST, Harness, plan_sweep, record_sweep
    if simulate_to is not None and simulate_to.resolve() == out.resolve():
        raise UserError(f"--simulate {simulate_to} is --out's path too: the recording would overwrite the sweep; "
                        f"give it its own name (e.g. {out.with_suffix('.mcap').name})")
    robot = load_robot(robot_name)
    h = Harness(robot)
    try:
        sweep = plan_sweep(h, duration=duration, f_max=f_max, amplitude=amplitude, steps=steps, step_size=step_size,
                           seed=seed)
    except ValueError as exc:
        raise UserError(f"excite: {exc}") from None
    write_text_atomic(out, sweep.csv_text())
    info = {"robot": robot.name, "sweep": str(out), **sweep.info()}
    if sweep.below_encoder:
        small = ", ".join(f"{j} {a * 1000:.2f} mrad" for j, a in sweep.below_encoder.items())
        click.echo(f"note: {len(sweep.below_encoder)} joint(s) swing less than 3 encoder ticks "
                   f"({ENCODER_TICKS_LEAST * 1000:.1f} mrad) in the sweep: it tells the fit nothing of their servos "
                   f"({small})", err=True)
    if simulate_to is not None:
        record_sweep(h, sweep.targets, h.servo_arrays(), simulate_to, seed=seed, notes=f"gait-tuner excite --robot {robot_name}")
        info["recording"] = str(simulate_to)
    if as_json:
        click.echo(json.dumps(info, allow_nan=False))
        return
    click.echo(f"{robot.name}: a {sweep.sweep_s:.0f} s sweep of {h.n} joints at {0.2:g}-{f_max:g} Hz, at most "
               f"{info['speed_share'] * 100:.0f} % of a servo's speed"
               + (f", then {info['steps_s']:.0f} s of steps up to {step_size:g} rad, one joint at a time" if steps else "")
               + f"; wrote {out}")
    if simulate_to is not None:
        click.echo(f"wrote {simulate_to} (the sweep on the simulated robot in its harness)")


@click.group()
def identify() -> None:
    """Fit the simulator to recordings of your robot: its servos (a sweep in a harness), then its
    ground (walks on the field). MuJoCo's system identification toolbox (mujoco[sysid])."""


@identify.command(name="servos")
@robot_option(default=None, help="The robot map YAML (or a built-in robot name).")
@RECORDING_OPTION
@TOPICS_OPTION
@click.option("--out", "out_dir", required=True, type=OutPath(file_okay=False), metavar="DIR",
              help="Where to write robot.yaml (your map with the servos identified), servos.yaml, fit.json "
                   "and report.txt.")
@click.option("--by", type=click.Choice(["groups", "joints"]), default="groups", show_default=True,
              help="Share the servo's numbers over hips, knees, ankles, arms and head, or fit each joint.")
@click.option("--noise", default=ENCODER_NOISE, show_default=True, type=Span(1e-6, 0.1),
              help="The encoders' noise [rad]: the residual's unit.")
@click.option("--fit", "fit_fields", default=None, metavar="FIELD,...",
              help="What to fit; the others keep the map's values. Default for a sweep: "
                   "kp,damping,armature,frictionloss,torque,back_emf,speed,backlash,latency; a dc-motor servo's "
                   "friction beyond Coulomb and viscous: add stribeck,stribeck_speed,load_motor (BAM's M5 terms; "
                   "slower). From walks: the legs' kp and the latency (what a walk can tell).")
@surface_option(default=None, help="For walking recordings: the ground they were walked on (rigid, carpet4, "
                                   "grass10, grass30, grass50 or a surface YAML).")
@click.option("--max-iters", default=40, show_default=True, type=click.IntRange(1, 500))
@click.option("--trace", is_flag=True, help="Print the optimiser's iterations on stderr.")
@JSON_OPTION
def identify_servos_cmd(robot_name: str | None, recordings: tuple[Path, ...], topics_file: Path | None,
                        out_dir: Path, by: str, noise: float, fit_fields: str | None, surface_name: str | None,
                        max_iters: int, trace: bool, as_json: bool) -> None:
    """Identify the robot's servos from recordings of its joints (commanded and measured angles). Best a
    sweep from `gait-tuner excite` on the robot hanging in a harness: per group or joint the gain,
    damping, armature, friction loss, torque and speed limits and backlash, and the latency. From
    walks (with --surface): what a walk can tell, the legs' gains and the latency."""
    import json

    from ..identify.field_recordings import RecordingError, read_field_recording
    from ..identify.report import fit_json, summary_lines, write_servo_fit
    from ..robots import load_robot
    from ..identify.harness import Harness
    from ..identify.servos import DEFAULT_FIT, JointLog, identify_servos
    if robot_name is None:
        raise UserError("identify servos: give --robot (your robot map)")
    robot = load_robot(robot_name)
    probe_folder(out_dir)                    # a folder it cannot write said before the fit, not after
    h = Harness(robot)
    read = []
    for path in recordings:
        try:
            rec = read_field_recording(path, topics=topics_file, robot_joints=robot.joint_map)
        except RecordingError as exc:
            raise UserError(str(exc)) from None
        read.append((path, rec, rec.not_hanging()))
    walks = [(p, why) for p, _, why in read if why is not None]
    if walks:
        if len(walks) < len(read):
            p, why = walks[0]
            raise UserError(f"identify servos: {p} is a walk ({why}) and the others are sweeps hanging in a harness: "
                            f"fit them apart (a walk tells the legs' gains and the latency, a sweep the rest)")
        if by != "groups" or noise != ENCODER_NOISE:
            raise UserError(f"identify servos {'--by joints' if by != 'groups' else f'--noise {noise:g}'}: a walk's fit "
                            f"is by leg group, in each sensor's own noise (docs/servos.md); leave it out for walks")
        _servos_from_walks(robot, [(p, rec) for p, rec, _ in read], surface_name, fit_fields, out_dir,
                           max_iters, trace, as_json, first=walks[0])
        return
    logs = []
    for path, rec, _ in read:
        try:
            t, targets, measured = rec.on_grid(h.control_period, h.joint_names)
        except RecordingError as exc:
            raise UserError(str(exc)) from None
        for gap in rec.gaps[:3]:
            click.echo(f"note: {path}: {gap}", err=True)
        logs.append(JointLog(str(path), h.control_period, tuple(h.joint_names), targets, measured,
                             valid=rec.grid_valid))
    fields = DEFAULT_FIT if fit_fields is None else tuple(f.strip() for f in fit_fields.split(",") if f.strip())
    bar, progress = running_total("identify servos", "rollouts")
    try:
        def budget(most: int) -> None:
            bar.total = most
            bar.set_postfix_str("at most; it stops sooner when the fit converges", refresh=False)
        fit = identify_servos(h, logs, by=by, noise=noise, max_iters=max_iters, progress=progress,
                              fit=fields, trace=sys.stderr if trace else None, budget=budget)
    finally:
        bar.close()
    lost = fit.unfollowed(noise)
    if not fit.converged or lost:
        j = lost[0] if lost else None
        why = (f"it does not follow {j} (residual RMS {fit.rms_before[j] * 1000:.2f} -> {fit.rms_after[j] * 1000:.2f} "
               f"mrad): a wrong sign or joint name in the recording, or contacts in it" if j else "not a number")
        raise UserError(f"identify servos: the fit did not converge: {why}; nothing written")
    laws = {ours: robot.servos[robot.joint_map[ours][0]] for ours in h.joint_names}
    written = write_servo_fit(fit, None if robot.map_path is None else Path(robot.map_path), out_dir, noise, laws)
    if as_json:
        click.echo(json.dumps({**fit_json(fit), "written": [str(p) for p in written]}, allow_nan=False))
        return
    for line in summary_lines(fit, noise):
        click.echo(line)
    for p in written:
        click.echo(f"wrote {p}")


def _servos_from_walks(robot, read, surface_name, fit_fields, out_dir, max_iters, trace, as_json, first) -> None:
    """``identify servos`` on walking recordings (``read``: (path, recording) pairs, read once): what
    a walk tells (tuner/identify/walk_servos.py)."""
    import json

    from ..identify.ground import walk_logs
    from ..identify.report import walk_fit_json, walk_fit_lines, write_walk_servo_fit
    from ..identify.walk_servos import NOT_FROM_A_WALK, WALK_FIELDS, identify_servos_from_walks
    from ..sim.surfaces import load_surface
    p, why = first
    if surface_name is None:
        raise UserError(f"identify servos: {p} is a walk ({why}): give --surface, the ground it was walked on "
                        f"(a walk tells the legs' gains and the latency; a sweep hanging in a harness, "
                        f"gait-tuner excite, tells the rest)")
    asked = [] if fit_fields is None else [f.strip() for f in fit_fields.split(",") if f.strip()]
    cannot = [f for f in asked if f not in WALK_FIELDS + ("latency",)]
    if cannot:
        raise UserError(f"identify servos --fit {','.join(cannot)}: a walk cannot tell {cannot[0]} (it tells the legs' "
                        f"kp and the latency; not {', '.join(NOT_FROM_A_WALK)}): fit it on a sweep hanging in a "
                        f"harness (gait-tuner excite)")
    surface = load_surface(surface_name)
    logs, notes = walk_logs(read, robot)
    for note in notes:
        click.echo(f"note: {note}", err=True)
    bar, progress = running_total("identify servos (walks)", "replays")
    try:
        fit = identify_servos_from_walks(robot, surface, logs, max_iters=max_iters, progress=progress,
                                         trace=sys.stderr if trace else None)
    finally:
        bar.close()
    if not fit.converged:
        raise UserError("identify servos: the walk fit did not converge (its replays match the recordings no better "
                        "than the map's servos); nothing written")
    written = write_walk_servo_fit(fit, robot, out_dir)
    if as_json:
        click.echo(json.dumps({**walk_fit_json(fit), "written": [str(x) for x in written]}, allow_nan=False))
        return
    for line in walk_fit_lines(fit, robot.sim.control_period):
        click.echo(line)
    for x in written:
        click.echo(f"wrote {x}")


@identify.command(name="ground")
@robot_option(default=None, help="The robot map YAML (its servos identified: identify servos' robot.yaml).")
@surface_option(default="grass30", help="The surface to start from: rigid, carpet4, grass10, grass30, grass50 "
                                        "or a surface YAML.")
@RECORDING_OPTION
@TOPICS_OPTION
@click.option("--out", "out_dir", required=True, type=OutPath(file_okay=False), metavar="DIR",
              help="Where to write surface.yaml (the ground identified), fit.json and report.txt.")
@click.option("--horizon", default=3.0, show_default=True, type=Span(0.5, 60.0),
              help="Seconds of each recording fitted (a replay is open loop: record several short walks).")
@click.option("--max-iters", default=25, show_default=True, type=click.IntRange(1, 500))
@click.option("--trace", is_flag=True, help="Print the optimiser's iterations on stderr.")
@JSON_OPTION
def identify_ground_cmd(robot_name: str | None, surface_name: str, recordings: tuple[Path, ...],
                        topics_file: Path | None, out_dir: Path, horizon: float, max_iters: int, trace: bool,
                        as_json: bool) -> None:
    """Identify the ground from recordings of the robot walking on it: the simulated walk replays
    each recording's joint targets on the surface, whose layer (stiffness, damping, friction, drag)
    is fitted until the replay's roll, pitch, gyro and encoders match the robot's."""
    import json

    from ..identify.report import ground_lines, write_ground_fit
    from ..robots import load_robot
    from ..identify.ground import identify_ground, read_walk_logs
    from ..sim.surfaces import load_surface
    if robot_name is None:
        raise UserError("identify ground: give --robot (your robot map, its servos identified)")
    robot = load_robot(robot_name)
    start = load_surface(surface_name)
    probe_folder(out_dir)                    # a folder it cannot write said before the fit, not after
    logs, notes = read_walk_logs(recordings, robot, topics_file)
    for note in notes:
        click.echo(f"note: {note}", err=True)
    bar, progress = running_total("identify ground", "replays")
    try:
        fit = identify_ground(robot, start, logs, max_iters=max_iters, progress=progress, horizon=horizon,
                              trace=sys.stderr if trace else None)
    finally:
        bar.close()
    if not fit.converged:
        raise UserError("identify ground: the fit did not converge (its replays match the recordings no better than "
                        f"{start.name} does); nothing written")
    written = write_ground_fit(fit, out_dir)
    if as_json:
        click.echo(json.dumps({"surface": str(written[0]), **fit.to_json()}, allow_nan=False))
        return
    for line in ground_lines(fit):
        click.echo(line)
    for p in written:
        click.echo(f"wrote {p}")

