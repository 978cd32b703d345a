"""A walk asked for on the command line: the joint table (trajectory), the walk simulated (simulate), filmed (render), watched (view), and a family's parameters (params)."""

from __future__ import annotations

import os
from pathlib import Path

import click

import gaits
from gaits import family_class
from gaits.files import write_files_atomic, make_folder

from ..errors import UserError
from ..robots.joint_table import joint_table_file
from ..params_io import resolve_drive, resolve_params
from .options import OutPath, FamilyChoice, robot_option, GAIT_OPTION, PARAMS_OPTION, JSON_OPTION, RECORD_OPTION, COMMANDS_OPTION, TAIL_OPTION, COMMAND_OPTION, parse_command, JOINT_NAMES_OPTION, FORMAT_OPTION, CLIP_OPTION, SAVE_SCENE_OPTION, walk_options, bar_options


@click.command()
@GAIT_OPTION
@PARAMS_OPTION
@robot_option(help="Built-in robot name or a robot map YAML: its legs set the IK.")
@click.option("--out", "out_dir", required=True, type=OutPath(file_okay=False),
              help="Directory for joints.csv, references.png and params.yaml.")
@click.option("--dt", default=0.01, show_default=True, type=float,
              help="Control period of the joint table [s].")
@click.option("--model", type=click.Choice(["lipm", "dlipm", "tlipfm"]),
              help="tlipfm only: override the parameter file's CoM model.")
@COMMAND_OPTION
@COMMANDS_OPTION
@TAIL_OPTION
@JOINT_NAMES_OPTION
@FORMAT_OPTION
@CLIP_OPTION
@click.option("--no-plot", is_flag=True, help="Skip the PNG.")
@JSON_OPTION
def trajectory(family: str | None, params_spec: str | None, robot_name: str, out_dir: Path, dt: float,
               model: str | None, command: str | None, commands_file: Path | None, duration: float | None,
               joint_names: str, table_format: str, clip: bool, no_plot: bool, as_json: bool) -> None:
    """Generate a gait's joint table q_ref(t) and its Cartesian references for a robot.

    Writes OUT/joints.csv (a comment line naming the robot, then time, the joint targets
    [rad], CoM, ZMP reference, pelvis and feet [m], support phase), OUT/params.yaml (the
    exact parameters used) and OUT/references.png. A table is open loop: a stabiliser in the
    parameter file is kept in params.yaml but cannot be in the table.
    """
    if not str(out_dir).strip() or str(out_dir) == ".":
        raise UserError("--out: give a folder for the joint table, e.g. --out runs/tk")
    if clip and joint_names != "robot":
        raise UserError("--clip writes the robot's own joints: leave out --joint-names ours")
    from ..robots import load_robot

    drive = resolve_drive(params_spec, family, command=parse_command(command), commands_file=commands_file,
                          tail=_tail(duration, commands_file))
    if model is not None:
        if not hasattr(drive.params, "model"):
            raise UserError(f"--model applies to the tlipfm family only (its CoM model), not {drive.family}")
        drive = drive.with_params(drive.params.replace(model=model))
    robot = load_robot(robot_name)
    traj = drive.table(robot, dt)
    make_folder(out_dir)
    csv_path, csv_text, notes = joint_table_file(traj, robot, out_dir / "joints.csv", joint_names,
                                                 f"gait {drive.describe()}", table_format, clip)
    for line in notes:
        click.echo(f"note: {line}", err=True)
    yaml_path = out_dir / "params.yaml"
    write_files_atomic({csv_path: csv_text, yaml_path: gaits.gait_file_text(
        drive.params, resolve_params(params_spec, family).description, drive.stabiliser)})
    walked = float(traj.p_world_com[-1, 0] - traj.p_world_com[0, 0])
    wrote = [str(csv_path), str(yaml_path)]
    if not no_plot:
        from ..report.plots import plot_references
        wrote.append(str(plot_references(traj, out_dir / "references.png",
                                         title=f"{traj.family} ({drive.source}), robot {robot.name}")))
    if as_json:
        import json
        click.echo(json.dumps({"family": traj.family, "robot": robot.name, "samples": len(traj.t), "dt_s": dt,
                               "duration_s": float(traj.duration), "walked_x_m": walked, "wrote": wrote},
                              indent=2, allow_nan=False))
        return
    click.echo(f"{traj.family} for robot {robot.name}: {len(traj.t)} samples every {dt:g} s, "
               f"{traj.duration:.2f} s, walked {walked:+.3f} m")
    click.echo("".join(f"wrote {p}\n" for p in wrote), nl=False)


def _tail(duration: float | None, commands_file) -> float | None:
    """--duration of a command-stream walk: the seconds after its last row."""
    if commands_file is None or duration is None:
        return None
    if not 0 <= duration <= 600:            # NaN fails this too
        raise UserError(f"--duration must be in [0, 600] s after a command stream's last row, got {duration:g} s")
    return duration


def _skipped_rows_note(drive) -> None:
    """One note line when a table walks a stream some of whose rows no step starts in (never walked)."""
    skipped = drive.stream_rows_not_walked()
    if skipped:
        rows = ", ".join(f"{drive.stream.t[i]:g} s" for i in skipped[:5]) + (", ..." if len(skipped) > 5 else "")
        click.echo(f"note: {len(skipped)} row(s) of the stream last less than a step of this set and are not "
                   f"walked (a table plans one command per step, from the row at its start): the rows at {rows}",
                   err=True)


def _walk_setup(robot_name: str, surface_name: str, family: str | None, params_spec: str | None,
                duration: float | None, command: str | None, commands_file: Path | None, stabiliser: bool | None,
                save_scene: Path | None = None, controller_file: Path | None = None):
    """(drive, robot, simulator, duration of the rollout or None) of a walk asked for on the command
    line; with ``save_scene`` the assembled model is written there too (reported on stderr)."""
    from ..robots import load_robot
    from ..search.study import MAX_DURATION_S
    from ..sim.rollout import Simulator
    from ..sim.surfaces import load_surface

    drive = resolve_drive(params_spec, family, stabiliser=stabiliser, command=parse_command(command),
                          commands_file=commands_file, tail=_tail(duration, commands_file),
                          controller=controller_file)
    robot = load_robot(robot_name)
    surface = load_surface(surface_name)
    if commands_file is None and duration is not None and not 0 < duration <= MAX_DURATION_S:  # NaN fails too
        raise UserError(f"--duration must be in (0, {MAX_DURATION_S:g}] s, got {duration:g} s")
    sim = Simulator(robot, surface)
    _skipped_rows_note(drive)
    if drive.engine is not None and drive.command is None and drive.stream is None:
        click.echo(f"note: {drive.source or drive.family} walks online (its engine: section) and was given no "
                   f"--command or --commands: it " + ("steps in place" if drive.engine.idle == "step" else
                                                     "stands where it started") +
                   ", and the walk's figures are of that", err=True)
    if save_scene is not None:
        from ..report.video import save_scene as write_scene
        click.echo(f"wrote {write_scene(sim, save_scene)}", err=True)
    return drive, robot, sim, (None if commands_file is not None else duration)


def _walk(drive, robot, sim, duration: float | None, record_qpos: bool = False, record: Path | None = None):
    """The walk (``tuner/sim/walk.py``) with its notes said on stderr."""
    from ..sim.walk import walk
    return walk(drive, robot, sim, duration, record_qpos=record_qpos, record=record,
                note=lambda line: click.echo(line, err=True))


def _parse_size(size: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in size.lower().split("x"))
    except ValueError:
        raise UserError(f"--size {size!r}: expected WIDTHxHEIGHT in pixels, e.g. 640x480") from None
    return w, h


@click.command()
@walk_options
@click.option("--out", required=True, type=OutPath(dir_okay=False), metavar="WALK.mp4",
              help="The video file to write (H.264 MP4).")
@click.option("--size", default="640x480", show_default=True, help="Frame size WIDTHxHEIGHT [px], multiples of 16.")
@click.option("--fps", default=30, show_default=True, type=int, help="Frames per second.")
@click.option("--no-overlay", is_flag=True, help="No text over the frames.")
@SAVE_SCENE_OPTION
def render(robot_name: str, surface_name: str, family: str | None, params_spec: str | None,
           duration: float | None, command: str | None, commands_file: Path | None, stabiliser: bool | None,
           controller_file: Path | None, out: Path, size: str, fps: int, no_overlay: bool,
           save_scene: Path | None) -> None:
    """Film a walk: an MP4 from MuJoCo's offscreen renderer, headless.

    The camera tracks the torso; grass is drawn as a translucent slab as tall as its blades;
    the overlay shows time, forward speed, torso pitch and the moment of a fall. Needs no
    display (EGL); see tuner/report/video.py for the packages.
    """
    from tqdm import tqdm

    from ..report.video import VideoOptions, frame_ticks, render_trace

    if out.suffix.lower() != ".mp4":
        raise UserError(f"--out {out}: the video is H.264 MP4; name it *.mp4")
    w, h = _parse_size(size)
    options = VideoOptions(width=w, height=h, fps=fps, overlay=not no_overlay)
    drive, robot, sim, duration = _walk_setup(robot_name, surface_name, family, params_spec, duration, command,
                                              commands_file, stabiliser, save_scene, controller_file)
    trace = _walk(drive, robot, sim, duration, record_qpos=True)
    title = (f"{drive.source} | {robot.name} | {sim.surface.name}" + (f" | command {command}" if command else "")
             + (f" | {commands_file.name}" if commands_file else "") + (" | stabiliser" if drive.closed_loop else ""))
    n = len(frame_ticks(len(trace.t), sim.control_period, fps))
    with tqdm(total=n + int(round(options.hold_end * fps)), unit="frame", desc="render",
              **bar_options()) as bar:
        info = render_trace(sim, trace, out, options, title=title, progress=bar.update)
    click.echo(f"wrote {info['path']}: {info['frames']} frames, {info['width']}x{info['height']}, "
               f"{info['fps']} fps ({info['seconds']:.1f} s); {drive.describe()}; the walk: {trace.reason}"
               + (f" at {trace.t_fall:.2f} s" if trace.fell and trace.t_fall is not None else ""))


def _open_display() -> None:
    """A one-line error when no window can be opened (MuJoCo's viewer would end the process from C)."""
    import warnings

    import glfw
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok = glfw.init()
    if not ok:
        shown = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        raise UserError(f"view: cannot open a window on display {shown!r}; "
                        f"use `gait-tuner render ... --out walk.mp4` instead")


@click.command()
@walk_options
@SAVE_SCENE_OPTION
def view(robot_name: str, surface_name: str, family: str | None, params_spec: str | None,
         duration: float | None, command: str | None, commands_file: Path | None, stabiliser: bool | None,
         controller_file: Path | None, save_scene: Path | None) -> None:
    """Watch a walk in MuJoCo's interactive viewer (needs a display).

    A set that walks online (the walk engine, --controller) without --command/--commands runs
    live physics: the keyboard steers it (arrows, Z/X, space) and the mouse pushes it (see
    tuner/report/live.py). Otherwise the walk is simulated first (as `simulate` does), then
    replayed in real time until the window is closed. Without a display: use `render` for a
    video, or --save-scene and open the scene in any MuJoCo tool.
    """
    import os
    import time

    import mujoco

    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise UserError("view needs a display (no DISPLAY or WAYLAND_DISPLAY here); "
                        "use `gait-tuner render ... --out walk.mp4`, or --save-scene with `view`'s options")
    drive, robot, sim, duration = _walk_setup(robot_name, surface_name, family, params_spec, duration, command,
                                              commands_file, stabiliser, save_scene, controller_file)
    if drive.online and command is None and commands_file is None:
        from ..report.live import KeyboardCommand, live_walk
        _open_display()
        import mujoco.viewer
        keyboard = KeyboardCommand()
        click.echo(f"{drive.describe()}: live physics; arrows steer (forward/back, turning), Z/X sideways, "
                   f"space stops; double-click a body and Ctrl + right-drag to push it; close the window to end")
        with mujoco.viewer.launch_passive(sim.model, sim.data, key_callback=keyboard.key) as viewer:
            trace = live_walk(sim, drive.controller(robot, sim.control_period), viewer, keyboard,
                              limit_s=duration or 3600.0)
        click.echo(f"the walk: {trace.reason} after {trace.t[-1]:.1f} s")
        return
    trace = _walk(drive, robot, sim, duration, record_qpos=True)
    click.echo(f"{drive.describe()}; the walk: {trace.reason}; replaying {trace.t[-1]:.1f} s (close the window to stop)")
    _open_display()
    import mujoco.viewer
    d = mujoco.MjData(sim.model)
    with mujoco.viewer.launch_passive(sim.model, d) as viewer:
        while viewer.is_running():
            for k in range(len(trace.t)):
                if not viewer.is_running():
                    break
                d.qpos[:] = trace.qpos[k]
                mujoco.mj_forward(sim.model, d)
                viewer.sync()
                time.sleep(sim.control_period)


@click.command()
@walk_options
@JSON_OPTION
@click.option("--plot", "plot_dir", type=OutPath(file_okay=False),
              help="Write pitch.png and zmp.png into this directory.")
@SAVE_SCENE_OPTION
@RECORD_OPTION
def simulate(robot_name: str, surface_name: str, family: str | None, params_spec: str | None,
             duration: float | None, command: str | None, commands_file: Path | None, stabiliser: bool | None,
             controller_file: Path | None, as_json: bool, plot_dir: Path | None, save_scene: Path | None,
             record_dir: Path | None) -> None:
    """Walk a gait on a robot and a surface in MuJoCo and print its metrics.

    A parameter file's IMU stabiliser is used unless --no-stabiliser says otherwise. With
    --command the gait walks that velocity, ramped from rest and back (gaits.CommandRamp: 4
    steps up, 12 held, 4 down), and vx_mps, vy_mps, wz_radps are measured over the held steps
    after two of them. With --commands it walks a command stream and reports how well it
    tracked it (RMS velocity errors per step, from each segment's second step on).
    """
    import json

    from ..report.tables import format_metrics
    from ..sim.metrics import DEFINITIONS, summarize, tracking

    drive, robot, sim, duration = _walk_setup(robot_name, surface_name, family, params_spec, duration, command,
                                              commands_file, stabiliser, save_scene, controller_file)
    surface = sim.surface
    trace = _walk(drive, robot, sim, duration, record=record_dir)
    metrics = summarize(trace)
    label = drive.source
    commanded = None if drive.command is None else {"vx_mps": drive.command.vx, "vy_mps": drive.command.vy,
                                                    "wz_radps": drive.command.wz}
    followed = None
    if drive.stream is not None:
        followed = tracking(trace, drive.stream, trace.meta.get("step_starts"))
    if as_json:
        out = metrics.to_dict()
        if followed is not None:
            out["tracking"] = followed
        click.echo(json.dumps({"robot": robot.name, "surface": surface.name, "gait": drive.family,
                               "params": label, "drive": drive.describe(), "stabiliser": drive.closed_loop,
                               "command": commanded,
                               "commands": None if commands_file is None else str(commands_file),
                               "metrics": out, "definitions": DEFINITIONS}, indent=2, allow_nan=False))
    else:
        click.echo(f"{drive.describe()} on {robot.name} / {surface.name}: {metrics.reason}")
        click.echo(format_metrics(metrics, DEFINITIONS))
        if drive.command is not None:
            cmd = drive.command
            got = [metrics.vx_mps, metrics.vy_mps, metrics.wz_radps]
            if metrics.velocity_note:
                click.echo(f"  commanded vx {cmd.vx:g}, vy {cmd.vy:g}, wz {cmd.wz:g}: not measured ({metrics.velocity_note})")
            else:
                click.echo("  commanded " + ", ".join(
                    f"{k} {c:g} -> {g:.3f}" + (f" ({g / c:.0%})" if c else "")
                    for k, c, g in zip(("vx", "vy", "wz"), (cmd.vx, cmd.vy, cmd.wz), got)))
        if followed is not None:
            click.echo("  tracking over " + f"{followed['steps']} steps: RMS error " + ", ".join(
                f"{k} {'-' if followed[key] is None else format(followed[key], '.3f')} {unit}"
                for k, key, unit in (("vx", "vx_rmse_mps", "m/s"), ("vy", "vy_rmse_mps", "m/s"),
                                     ("wz", "wz_rmse_radps", "rad/s"))))
    if plot_dir is not None:
        from ..report.plots import plot_pitch, plot_zmp
        title = f"{drive.family} ({label}), robot {robot.name} on {surface.name}"
        p1 = plot_pitch({label: trace}, plot_dir / "pitch.png", title)
        p2 = plot_zmp(trace, plot_dir / "zmp.png", robot.foot_size, title)
        if not as_json:
            click.echo(f"wrote {p1}\nwrote {p2}")


@click.command(name="params")
@click.argument("family", type=FamilyChoice())
@JSON_OPTION
def params_cmd(family: str, as_json: bool) -> None:
    """Print a family's parameters (name, default, unit, allowed range, paper symbol) and the walk
    commands it takes."""
    table = family_class(family).field_table()
    online = ("the walk engine, footsteps and CoM re-planned each step from the measured state (gaits/engine/)"
              if gaits.family(family).engine == "feedback" else
              "the family's table re-planned at each step start for the current command, no state feedback "
              "(gaits/online_table.py)")
    if as_json:
        import json
        click.echo(json.dumps({"family": family, "params": table, "commands": gaits.family(family).commands_text,
                               "online": online}, indent=2, allow_nan=False))
        return
    for row in table:
        paper = row["paper"] or ""
        click.echo(f"{row['name']:22s} {str(row['default']):>12.12s}  {row['range']:28s} "
                   f"{paper:8s} {row['doc']}")
    click.echo(f"walk command (--command): {gaits.family(family).commands_text}")
    click.echo("online (an engine: section): " + online)

