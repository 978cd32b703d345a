"""The ``gait-tuner`` command line: one subcommand per verb.

Exit codes: 0 done; 1 internal error (a bug: please report it); 2 bad input
(a file, a name or a value; the one-line message says which).
"""

from __future__ import annotations

import dataclasses
import errno
import math
import os
import signal
import sys
from pathlib import Path

import click
import numpy as np

import gaits
from gaits import ParamError, UnreachableTargetError, families, family_class, list_baselines, load_baseline
from gaits.files import write_files_atomic, write_text_atomic

from .errors import EXIT_INTERNAL, EXIT_SYSTEM, EXIT_USAGE, UserError
from .params_io import resolve_drive, resolve_params
from .sim.randomisation import DEFAULT_PUSHES

__all__ = ["cli", "main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="gait-tuner")
def cli() -> None:
    """Tune the walking gaits of kid-size humanoid robots in simulation, per ground surface.

    Gait families: eros (quarter-circle trajectory, heel strike, landing
    deceleration), tlipfm (natural ZMP on the three-mass LIPM plus flywheel;
    lipm and dlipm as its comparisons), cosine (5-DoF cosine-law walking diagram).
    """


# --- options shared by several verbs, declared once --------------------------------------------

FAMILIES = families()        # the registered gait families (gaits/families.py)


class OutPath(click.Path):
    """A path the command writes (``--out``, ``--plot``): click's checks, and an empty one refused
    before any work (``Path('')`` would silently be the current folder)."""

    def __init__(self, **kwargs):
        super().__init__(path_type=Path, **kwargs)

    def convert(self, value, param, ctx):
        if isinstance(value, str) and not value.strip():
            self.fail("an empty path: name the file or folder to write", param, ctx)
        return super().convert(value, param, ctx)


class Span(click.FloatRange):
    """A number in a closed range: click's ``FloatRange``, and NaN refused (every comparison with NaN
    is false, so click lets it through: ``challenge push --step nan`` raised nothing and reported a
    0.05 m best distance)."""

    def convert(self, value, param, ctx):
        x = super().convert(value, param, ctx)
        if x != x:
            self.fail(f"{value!r} is not a number in the range {self.min:g}..{self.max:g}", param, ctx)
        return x


def robot_option(default: str | None = "kidsize", help: str = "Built-in robot name or a robot map YAML."):
    return click.option("--robot", "robot_name", default=default, show_default=default is not None,
                        metavar="NAME|PATH", help=help)


def surface_option(default: str = "grass50", help: str = "rigid, carpet4, grass10, grass30, grass50, or a surface YAML."):
    return click.option("--surface", "surface_name", default=default, show_default=True, metavar="NAME|PATH",
                        help=help)


def workers_option(help: str = "Processes on this machine; the results do not depend on it."):
    return click.option("--workers", default=2, show_default=True, type=click.IntRange(1, 64), help=help)


GAIT_OPTION = click.option("--gait", "family", type=click.Choice(FAMILIES),
                           help="Gait family (taken from the parameter file if omitted).")
PARAMS_OPTION = click.option("--params", "params_spec", metavar="PATH|NAME",
                             help="Parameter YAML file, shipped baseline or tuned set (`gait-tuner sets`). "
                                  "Default: the family's paper baseline.")
JSON_OPTION = click.option("--json", "as_json", is_flag=True, help="Print the result as strict JSON.")
RECORD_OPTION = click.option(
    "--record", "record_dir", type=OutPath(file_okay=False),
    help="Record every tick of every walk (what the controller was given and what it asked) into this folder, an "
         "MCAP file per walk (gaits/recording.py); `gait-tuner log info FILE` says what one holds.")
RUNS_OPTION = click.option("--runs", "runs_dir", default="runs", show_default=True,
                           type=OutPath(file_okay=False), help="Folder of the journal files.")
STABILISER_OPTION = click.option(
    "--stabiliser/--no-stabiliser", default=None,
    help="Use the parameter file's IMU stabiliser (default: as the file says) or switch it off.")
COMMANDS_OPTION = click.option(
    "--commands", "commands_file", type=click.Path(dir_okay=True, path_type=Path), metavar="STREAM.csv",
    help="Walk a command stream: CSV with the header t,vx,vy,wz (s, m/s, m/s, rad/s), each row holding "
         "until the next; the walk lasts until the last row plus --duration (default 2 s). A set without "
         "an engine walks it planned per step before the walk.")


CONTROLLER_OPTION = click.option(
    "--controller", "controller_file", type=click.Path(path_type=Path), metavar="CONTROLLER.yaml",
    help="Walk a controller of your own instead of a gait set: a YAML naming its class and parameters "
         "(tuner/controllers.py). Its code runs.")
COMMAND_OPTION = click.option(
    "--command", metavar="VX,VY,WZ",
    help="Walk this velocity (m/s forward, m/s left, rad/s counter-clockwise), ramped from rest "
         "and back (eros and tlipfm: any direction; cosine: forward and backward only). A command beyond the parameter set's step limits is an error "
         "naming the step and the limit.")


def _parse_command(text: str | None):
    if text is None:
        return None
    from gaits import parse_command
    return parse_command(text)


JOINT_NAMES_OPTION = click.option(
    "--joint-names", "joint_names", type=click.Choice(["robot", "ours"]), default="robot", show_default=True,
    help="Joint table columns in the robot's own MJCF joint names and signs (with held joints), "
         "or in gait-tuner's names and signs.")


FORMAT_OPTION = click.option(
    "--format", "table_format", type=click.Choice(["csv", "servo"]), default="csv", show_default=True,
    help="csv: angles [rad] with the references; servo: the robot map's servo IDs and position units "
         "(its servos: section) at the control rate, checked against each servo's speed and range "
         "(a target it cannot follow is an error unless --clip).")
CLIP_OPTION = click.option(
    "--clip", is_flag=True,
    help="Write the table the servos can play (moves limited to each servo's speed, targets clipped "
         "into the joint's range, as the simulated servo does) and say what changed; in the robot's "
         "own joint names.")


def joint_table_file(traj: "gaits.GaitTrajectory", robot, path: Path, joint_names: str, comment: str,
                     table_format: str = "csv", clip: bool = False) -> tuple[Path, str]:
    """(path, text) of the joint table of ``traj`` for ``robot`` as CSV, headed by a comment naming
    what it is for; ``table_format`` servo: in the map's servo units instead (``<name>.servo.csv``,
    checked). The caller writes it with the files it belongs with (``write_files_atomic``)."""
    from .robots.joint_table import robot_joint_table
    from .robots.servo_table import check_positions, check_table, servo_columns, to_units, too_fast
    if clip and joint_names != "robot":
        raise UserError("--clip writes the robot's own joints: leave out --joint-names ours")
    if table_format == "servo" and joint_names != "robot":
        raise UserError("--format servo writes the robot's own joints: leave out --joint-names ours")
    table = robot_joint_table(traj, robot)
    names = tuple(table.joint_names)
    speed = np.array([robot.servos[n].speed for n in names])
    if table_format == "csv":
        if clip:                             # the table the servos play, as the simulator's servo does
            lo, hi = robot.joint_ranges(names)
            q, notes = check_table(table.q_ref, table.t, names, speed, lo, hi, True)
            for line in notes:
                click.echo(f"note: {line}", err=True)
            table = dataclasses.replace(table, q_ref=q)
            comment += "; joint targets clipped to the servos' speed and range (the references are the plan's)" if notes else ""
        else:
            rate, over = too_fast(table.q_ref, table.t, speed)
        if not clip and over.any():          # said, as the simulator's servo limits it (never silently)
            j = int(np.argmax((rate / speed).max(axis=0)))
            click.echo(f"note: the table asks {names[j]} for up to {rate[:, j].max():.2f} rad/s where its servo "
                       f"gives {speed[j]:g} rad/s (the simulated servo moves at most that fast; {int(over.any(axis=1).sum())} "
                       f"row(s) ask more of some servo): --clip writes what the servos can play",
                       err=True)
        if joint_names == "robot":
            traj = table
        return path, traj.csv_text(comment=f"gait-tuner joint table for robot {robot.name} "
                                           f"({joint_names} joint names and signs; angles in rad); {comment}")
    units = servo_columns(robot.servo_units, names)
    lo, hi = robot.joint_ranges(names)
    q, notes = check_table(table.q_ref, table.t, names, speed, lo, hi, clip)
    for line in notes:
        click.echo(f"note: {line}", err=True)
    ticks = np.column_stack([to_units(q[:, j], u) for j, u in enumerate(units)])
    check_positions(ticks, table.t, names, units)
    dt = float(np.median(np.diff(table.t)))
    out = path.with_name(path.name.replace("joints.csv", "servo.csv")) if path.name.endswith("joints.csv") \
        else path.with_suffix(".servo.csv")
    rows = [f"# gait-tuner servo table for robot {robot.name}; {comment}; every {dt * 1000:g} ms "
            f"({1 / dt:g} Hz); positions in the servos' units (robot map servos:)" +
            ("; clipped to the servos' speed and range" if notes else ""),
            "# " + ", ".join(f"id{u.id} = {n} ({u.units_per_rad * 2 * np.pi:g} per turn, centre {u.centre:g}, "
                             f"direction {u.direction:+d}, offset {u.offset:g} rad)" for n, u in zip(names, units)),
            "t_s," + ",".join(f"id{u.id}" for u in units)]
    rows += [f"{t:.4f}," + ",".join(str(int(v)) for v in r) for t, r in zip(table.t, ticks)]
    return out, "\n".join(rows) + "\n"


@cli.command()
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
@click.option("--duration", type=float, help="With --commands: seconds walked after the stream's last row [s] (default 2).")
@JOINT_NAMES_OPTION
@FORMAT_OPTION
@CLIP_OPTION
@click.option("--no-plot", is_flag=True, help="Skip the PNG.")
def trajectory(family: str | None, params_spec: str | None, robot_name: str, out_dir: Path, dt: float,
               model: str | None, command: str | None, commands_file: Path | None, duration: float | None,
               joint_names: str, table_format: str, clip: bool, no_plot: bool) -> None:
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
    from .robots import load_robot

    drive = resolve_drive(params_spec, family, command=_parse_command(command), commands_file=commands_file,
                          tail=_tail(duration, commands_file))
    if model is not None:
        if not hasattr(drive.params, "model"):
            raise UserError(f"--model applies to the tlipfm family only (its CoM model), not {drive.family}")
        drive = drive.with_params(drive.params.replace(model=model))
    robot = load_robot(robot_name)
    traj = drive.table(robot, dt)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path, csv_text = joint_table_file(traj, robot, out_dir / "joints.csv", joint_names,
                                          f"gait {drive.describe()}", table_format, clip)
    yaml_path = out_dir / "params.yaml"
    write_files_atomic({csv_path: csv_text, yaml_path: gaits.gait_file_text(
        drive.params, resolve_params(params_spec, family).description, drive.stabiliser)})
    click.echo(f"{traj.family} for robot {robot.name}: {len(traj.t)} samples every {dt:g} s, "
               f"{traj.duration:.2f} s, walked {traj.p_world_com[-1, 0] - traj.p_world_com[0, 0]:+.3f} m")
    click.echo(f"wrote {csv_path}")
    click.echo(f"wrote {yaml_path}")
    if not no_plot:
        from .report.plots import plot_references
        png = plot_references(traj, out_dir / "references.png",
                              title=f"{traj.family} ({drive.source}), robot {robot.name}")
        click.echo(f"wrote {png}")


SAVE_SCENE_OPTION = click.option(
    "--save-scene", type=OutPath(dir_okay=False), metavar="SCENE.xml",
    help="Also write the assembled robot + surface model as one MJCF file (loads in any MuJoCo tool; "
         "the blade drag is applied by our loop, not in the file).")


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
    from .robots import load_robot
    from .search.study import MAX_DURATION_S
    from .sim.rollout import Simulator
    from .sim.surfaces import load_surface

    drive = resolve_drive(params_spec, family, stabiliser=stabiliser, command=_parse_command(command),
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
        from .report.video import save_scene as write_scene
        click.echo(f"wrote {write_scene(sim, save_scene)}", err=True)
    return drive, robot, sim, (None if commands_file is not None else duration)


def _envelope_note(drive, controller) -> None:
    """One note line when an engine's stream or command asks more than its envelope (the engine walks
    it clipped there, gaits/engine/), naming the direction, the asked and the largest speed."""
    engine = getattr(controller, "inner", controller)
    stream = drive.the_stream()
    if stream is None or not hasattr(engine, "envelope"):
        return
    e = engine.envelope()
    c = np.asarray(stream.commands, dtype=float)
    over = []
    for name, k, sign in (("forward", 0, 1), ("backward", 0, -1), ("left", 1, 1), ("right", 1, -1),
                          ("turn_left", 2, 1), ("turn_right", 2, -1)):
        asked = float(np.max(sign * c[:, k])) if len(c) else 0.0
        if asked > e[name] + 1e-9:
            unit = "rad/s" if k == 2 else "m/s"
            over.append(f"{name} {asked:g} {unit} (envelope {e[name]:.3g})")
    if over:
        click.echo(f"note: {drive.source}: the engine walks these commands clipped to its envelope: "
                   f"{', '.join(over)}", err=True)


def _walk(drive, robot, sim, duration: float | None, record_qpos: bool = False, record: Path | None = None):
    """The rollout of a drive on the simulator (the controller it names, for ``duration`` or its own
    length); with ``record`` (a folder) every tick the controller saw and asked is recorded there as
    an MCAP file (``gaits/recording.py``), whose path is said on stderr."""
    options = drive.run_options()
    if duration is not None:
        options["duration"] = duration
    from .sim.recorded import recording, recording_stem
    path = None if record is None else record / f"{recording_stem(drive)}--{sim.surface.name}.mcap"
    try:
        with recording(drive.controller(robot, sim.control_period), sim, drive, path, "walk") as controller:
            _envelope_note(drive, controller)
            table = getattr(getattr(controller, "inner", controller), "traj", None)    # planned in advance: checked
            if table is not None:
                problem = sim.range_error(table.q_ref, table.t)
                if problem is not None:   # said, not refused: the papers' own EROS tables ask the built-in robot so
                    click.echo(f"note: {drive.source}: {problem}", err=True)
            trace = sim.run(controller, record_qpos=record_qpos, **options)
    finally:
        if path is not None and path.exists():
            click.echo(f"recorded {path}", err=True)
    if drive.online and drive.command is not None:
        # a held command: its velocity is measured from 2 s after the first step to the stop
        start = float(getattr(drive.engine, "t_stand", 0.0) or 0.0) + 2.0
        trace.meta["steady"] = (start, float(drive.the_stream().t[-1]))
    return trace


def _walk_options(f):
    for opt in reversed([
        PARAMS_OPTION,
        GAIT_OPTION,
        robot_option(),
        surface_option(),
        click.option("--duration", type=float, help="Stop after this many seconds [s] (default: the whole gait; "
                                                     "with --commands: seconds after the stream's last row, default 2)."),
        COMMAND_OPTION,
        COMMANDS_OPTION,
        STABILISER_OPTION,
        CONTROLLER_OPTION,
    ]):
        f = opt(f)
    return f


class _LogLines:
    """tqdm's output for a log file: each refresh one plain line instead of carriage returns."""

    def write(self, text: str) -> None:
        line = text.replace("\r", "").rstrip()
        if line:
            sys.stderr.write(line + "\n")

    def flush(self) -> None:
        sys.stderr.flush()


def _bar_options() -> dict:
    """Progress bars live on a terminal, a line every 15 s in a log (never silent for minutes)."""
    if sys.stderr.isatty():
        return {"disable": False, "mininterval": 0.5}
    return {"disable": False, "mininterval": 15.0, "delay": 15.0, "file": _LogLines(), "ascii": True}


def _parse_size(size: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in size.lower().split("x"))
    except ValueError:
        raise UserError(f"--size {size!r}: expected WIDTHxHEIGHT in pixels, e.g. 640x480") from None
    return w, h


@cli.command()
@_walk_options
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

    from .report.video import VideoOptions, frame_ticks, render_trace

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
              **_bar_options()) as bar:
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


@cli.command()
@_walk_options
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
        from .report.live import KeyboardCommand, live_walk
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


@cli.command()
@_walk_options
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

    from .report.tables import format_metrics
    from .sim.metrics import DEFINITIONS, summarize, tracking

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
            click.echo("  commanded " + ", ".join(
                f"{k} {c:g} -> {g:.3f}" + (f" ({g / c:.0%})" if c else "")
                for k, c, g in zip(("vx", "vy", "wz"), (cmd.vx, cmd.vy, cmd.wz), got)))
        if followed is not None:
            click.echo("  tracking over " + f"{followed['steps']} steps: RMS error " + ", ".join(
                f"{k} {'-' if followed[key] is None else format(followed[key], '.3f')} {unit}"
                for k, key, unit in (("vx", "vx_rmse_mps", "m/s"), ("vy", "vy_rmse_mps", "m/s"),
                                     ("wz", "wz_rmse_radps", "rad/s"))))
    if plot_dir is not None:
        from .report.plots import plot_pitch, plot_zmp
        title = f"{drive.family} ({label}), robot {robot.name} on {surface.name}"
        p1 = plot_pitch({label: trace}, plot_dir / "pitch.png", title)
        p2 = plot_zmp(trace, plot_dir / "zmp.png", robot.foot_size, title)
        if not as_json:
            click.echo(f"wrote {p1}\nwrote {p2}")


@cli.command()
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

    from .report import experiments as ex
    from .robots import load_robot
    from .sim.surfaces import SURFACES, load_surface

    if paper != "eros" and (as_json or tuned_spec or pedestal_specs):
        raise UserError(f"{'--json' if as_json else '--tuned' if tuned_spec else '--pedestal'}: only the eros "
                        f"experiment takes it")
    tuned = None if tuned_spec is None else resolve_params(tuned_spec, "eros").params
    robot = load_robot(robot_name)
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
        with tqdm(total=n, desc="EROS matrix", unit="walk", **_bar_options()) as bar:
            matrices = ex.eros_matrices(robot_name, surfaces, lift_scale=lift_scale, double_support=ds,
                                        workers=workers, progress=bar.update, tuned=tuned)
        without, with_ = matrices[:2]
        tuned_cells = matrices[2] if tuned is not None else None
        distance = ex.distance_to_fall(robot, surfaces[1], long_steps, lift_scale, ds)
        if as_json:
            report = ex.eros_report(without, with_, distance, lift_scale, ds, tuned_cells)
            if tuned is not None:
                report["tuned"]["params"] = {k: getattr(tuned, k) for k in ex.TUNED_KNOBS}
                report["tuned"]["source"] = tuned_spec
            report["surfaces"] = {ex.PEDESTALS[p]: surfaces[p].name for p in sorted(surfaces)}
            click.echo(json.dumps({"robot": robot.name, **report}, allow_nan=False))
            return
        text = (f"robot {robot.name}; foot lift: the paper's Z x {lift_scale:g}; double support "
                f"{ds:.0%} of each step (ours{'; 0 = the literal cycle' if ds == 0 else ''})\n"
                + ex.format_eros(without, False) + "\n\n" + ex.format_eros(with_, True) + "\n\n")
        if tuned_cells is not None:
            knobs = ", ".join(f"{k} {getattr(tuned, k):.3g}" for k in ex.TUNED_KNOBS)
            text += ex.format_eros(tuned_cells, True, f"Table 8 cells, tuned knobs from {tuned_spec} "
                                                      f"({knobs})") + "\n\n"
        text += ex.format_distance(distance, surfaces[1].name)
    else:
        surface = load_surface(surface_name)
        text = f"robot {robot.name}\n" + ex.format_table3(ex.tlipfm_table3(robot, surface), surface.name)
    click.echo(text)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out_dir / "report.md", "```\n" + text + "\n```\n")
        click.echo(f"wrote {out_dir / 'report.md'}")


@cli.command()
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

    from .report import calibration as cal
    from .report import experiments as ex
    from .sim.surfaces import SURFACES

    n = len(cal.calibration_tasks(layer=layer))
    with tqdm(total=n, desc="calibration", unit="grid point", **_bar_options()) as bar:
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
        out_dir.mkdir(parents=True, exist_ok=True)
        made = f"gait-tuner calibrate --layer {layer} --lift-scale {lift_scale:g}{_commit_of(__file__)}"
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


def _storage_option(f):
    return click.option("--storage", metavar="URL",
                        help="sqlite:///FILE.db or postgresql://USER@HOST[:PORT]/DB (driver: pip install "
                             "'gait-tuner[postgres]'). Default: the journal file RUNS/<study>.journal, no server.")(f)


def _study_progress(spec, total: int):
    """A tqdm bar over the study's finished trials, and the callback that refreshes it."""
    from tqdm import tqdm

    from .search.trials import DONE_STATES, best_trial, trial_fell
    # a terminal gets a live bar; a log file (CI, nohup) a line every 15 s rather than every poll
    bar = tqdm(total=total, unit="trial", dynamic_ncols=True, **_bar_options())

    def progress(study) -> None:
        done = study.get_trials(deepcopy=False, states=DONE_STATES)
        bar.n = min(len(done), total)
        falls = sum(1 for t in done if trial_fell(t))
        try:
            best = f"{best_trial(study).values[0]:.2f}"
        except KeyError:
            best = "-"
        bar.set_postfix_str(f"best {best}, falls {falls}", refresh=False)
        bar.update(0)                                  # prints when mininterval has passed
    return bar, progress


def _run_and_report(spec, store, study_file: str, storage: str | None, total: int | None, workers: int,
                    seed: int, verb: str) -> None:
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    with _storage_errors(store):
        _run_study_and_report(spec, store, study_file, storage, total, workers, seed, verb)


def _storage_errors(store):
    """A database's full disk met in this process (opening, enqueueing, reaping) as one line."""
    import contextlib

    from .search.journal import StorageFull
    from .search.storage import storage_full

    @contextlib.contextmanager
    def guard():
        try:
            yield
        except (UserError, ParamError, KeyboardInterrupt, SystemExit):
            raise
        except Exception as exc:  # noqa: BLE001
            full = storage_full(exc)
            if full is None:
                raise
            raise StorageFull(f"disk full writing the study's storage {store.where} ({full}); free space "
                              f"and run the same command to resume") from None
    return guard()


def _run_study_and_report(spec, store, study_file: str, storage: str | None, total: int | None, workers: int,
                          seed: int, verb: str) -> None:
    from .search.trials import DONE_STATES, best_trial, trial_feasible, trial_fell
    from .search.workers import WorkersDying, prepare_study, run_workers
    study, budget, run = prepare_study(spec, store, total, seed)
    done = len(study.get_trials(deepcopy=False, states=DONE_STATES))
    click.echo(f"study {spec.name}: {spec.gait} on {spec.robot} / {', '.join(spec.surfaces)} "
               f"({spec.aggregate if len(spec.surfaces) > 1 else 'single surface'}), "
               f"budget {budget} trials ({done} finished), {workers} worker(s) here, storage {store.where}")
    if spec.controller is not None:
        click.echo(f"study {spec.name} runs the code of a controller of your own: {spec.controller.source}")
    if done >= budget:
        click.echo(f"study {spec.name} is finished: {done} of {budget} trials "
                   f"(raise the budget with `gait-tuner tune {study_file} --trials N`)")
    else:
        if workers > 1:
            click.echo("note: with several workers the trials' order, and so the best trial, depends on "
                       "timing; --workers 1 --seed S gives the same study every run")
        bar, progress = _study_progress(spec, budget)
        try:
            study = run_workers(spec, store, study, budget, workers, seed, progress, run=run)
        except KeyboardInterrupt:
            bar.close()
            click.echo(f"interrupted: finished trials are kept in {store.where}; "
                       f"run the same command to resume", err=True)
            raise SystemExit(130) from None
        except WorkersDying as exc:
            bar.close()
            click.echo(f"gait-tuner: error: {exc}", err=True)
            raise SystemExit(EXIT_INTERNAL) from None
        finally:
            bar.close()
    if verb == "worker":
        click.echo(f"study {spec.name}: budget reached")
        return
    try:
        t = best_trial(study)
    except KeyError:          # every trial was pruned (a randomised trial stopped at its falls) or failed
        states = [x.state.name.lower() for x in study.get_trials(deepcopy=False)]
        counts = ", ".join(f"{states.count(k)} {k}" for k in dict.fromkeys(states))
        click.echo(f"no trial of study {spec.name} completed yet ({counts}): no best trial to export; give it "
                   f"more trials (resume with the same command and --trials N), or a wider space")
        return
    n_fell = sum(1 for x in study.get_trials(deepcopy=False, states=DONE_STATES) if trial_fell(x))
    n_infeasible = sum(1 for x in study.get_trials(deepcopy=False, states=DONE_STATES) if not trial_feasible(x))
    click.echo(spec.scenario_room.describe_best(spec.settings, t, fell=trial_fell(t), falls=n_fell,
                                                infeasible=n_infeasible))
    if not trial_feasible(t):
        click.echo(f"no feasible trial of study {spec.name} yet: nothing worth exporting; give it more trials "
                   f"(resume with the same command and --trials N), or a wider space (`export --trial N` "
                   f"writes one anyway)")
        return
    click.echo(f"export it with: gait-tuner export {study_file}"
               + (f" --storage {storage}" if storage else "") + (" --pareto-pick knee" if len(spec.objectives) > 1 else ""))


@cli.command()
@click.argument("study_file", metavar="STUDY.yaml")
@click.option("--trials", type=click.IntRange(1, 100_000), help="The study's budget: total finished trials "
              "it should hold, shared by every worker (default: the stored budget, else the file's). "
              "Re-running resumes: finished trials are kept.")
@workers_option("Processes running trials of this study on this machine.")
@_storage_option
@click.option("--seed", type=click.IntRange(0, 2 ** 31 - 1), help="Sampler seed (default: the file's sampler_seed).")
@RUNS_OPTION
def tune(study_file: str, trials: int | None, workers: int, storage: str | None, seed: int | None,
         runs_dir: Path) -> None:
    """Run (or resume) a tuning study: Optuna search seeded by CasADi, against MuJoCo walks.

    The progress bar shows finished trials of the budget, the best score so far
    (torso pitch RMS [deg] of a gait that did not fall), falls so far and the
    time left. Ctrl-C stops cleanly: finished trials stay in the storage. A trial
    whose worker was killed is retried with the same parameters (up to 3 times).
    """
    from .search.storage import StudyStore
    from .search.study import load_study

    spec = load_study(study_file)
    store = StudyStore.open(spec.name, storage, runs_dir)
    _run_and_report(spec, store, study_file, storage, trials,
                    workers, spec.sampler_seed if seed is None else seed, "tune")


@cli.command()
@click.argument("study_file", metavar="STUDY.yaml")
@_storage_option
@workers_option("Processes running trials on this machine.")
@click.option("--seed", type=click.IntRange(0, 2 ** 31 - 1), help="Sampler seed of this machine's processes (default: the file's "
              "sampler_seed plus a number drawn from the host name, so machines sample differently).")
@RUNS_OPTION
def worker(study_file: str, storage: str | None, workers: int, seed: int | None, runs_dir: Path) -> None:
    """Join a study from this machine and run its trials until the study's budget is reached.

    Every machine needs the same STUDY.yaml (and robot file) and the same --storage URL,
    usually PostgreSQL. The budget is the study's (set by `tune --trials`, else the file's
    trials), shared by all workers and `tune` processes: together they run it exactly once.
    The CasADi seed and baselines are enqueued once, by whoever starts first.
    """
    import zlib

    from .search.storage import StudyStore
    from .search.study import load_study

    spec = load_study(study_file)
    store = StudyStore.open(spec.name, storage, runs_dir)
    if seed is None:
        import socket
        seed = spec.sampler_seed + zlib.crc32(f"{socket.gethostname()}-{os.getpid()}".encode()) % 100_000
    _run_and_report(spec, store, study_file, storage, None, workers, seed, "worker")


def _commit_of(path: str) -> str:
    from .report.provenance import commit_of
    return commit_of(path)


def _tuned_study(study_file: str, storage: str | None, runs_dir: Path):
    """(spec, optuna study) of a study that has been tuned; a one-line error if it has not."""
    from .search.workers import load_tuned_study
    from .search.study import load_study

    spec = load_study(study_file)
    return spec, load_tuned_study(spec, storage, runs_dir)


@cli.command()
@click.argument("study_file", metavar="STUDY")
@_storage_option
@RUNS_OPTION
@click.option("--pareto", is_flag=True, help="Only Optuna's best trials (the Pareto front of feasible "
              "trials for two objectives, the best feasible one for one).")
@click.option("--sort", "sort_key", type=click.Choice(["number", "score", "speed"]), default="score",
              show_default=True, help="Order of the rows (score best first: ascending for a minimised study, "
                                      "descending for a maximised one; speed descending).")
@click.option("--limit", type=click.IntRange(1, 100_000), default=20, show_default=True)
@JSON_OPTION
def trials(study_file: str, storage: str | None, runs_dir: Path, pareto: bool, sort_key: str, limit: int,
           as_json: bool) -> None:
    """List a study's trials: state, objectives, feasibility, survival, searched parameters.

    score: the pitch score [deg] minimised (see tuner/search/objective.py; a speed study's speed score
    and a challenge study's push distance [m] maximised); speed [m/s] when the study has it; feasible: stayed up (robust: survival >= the study's minimum) and walked at
    least half its plan; survival: robust studies' share of randomised walks that stayed up.
    """
    import json

    from optuna.trial import TrialState

    from .search.trials import trial_feasible, trial_result

    spec, study = _tuned_study(study_file, storage, runs_dir)
    rows_src = study.best_trials if pareto else study.get_trials(deepcopy=False)
    rows = []
    for t in rows_src:
        res = trial_result(t)
        values = list(t.values) if t.values is not None else []
        rows.append({"number": t.number, "state": t.state.name.lower(),
                     "score": values[0] if values else None,
                     "speed": values[1] if len(values) > 1 else None,
                     "feasible": trial_feasible(t), "survival": res.get("survival"),
                     "start": t.user_attrs.get("start"),
                     "params": {r.name: t.params.get(r.label, t.params.get(r.name)) for r in spec.space}})
    maximised = spec.directions[0] == "maximize"
    keys = {"number": lambda r: r["number"],
            "score": lambda r: (r["score"] is None, (-r["score"] if maximised else r["score"])
                                if r["score"] is not None else 0.0),
            "speed": lambda r: (r["speed"] is None, -(r["speed"] or 0.0))}
    rows.sort(key=keys[sort_key])
    shown = rows[:limit]
    if as_json:
        click.echo(json.dumps({"study": spec.name, "trials": len(study.trials), "shown": shown,
                               "pareto": pareto}, indent=2, allow_nan=False))
        return
    done = sum(1 for t in study.trials if t.state in (TrialState.COMPLETE, TrialState.PRUNED))
    click.echo(f"study {spec.name}: {len(study.trials)} trials ({done} finished), showing {len(shown)}"
               + (" of Optuna's best" if pareto else f" by {sort_key}"))
    names = [r.name for r in spec.space]
    head = f"{'#':>5s} {'state':9s} {'score':>8s} " + (f"{'speed':>7s} " if len(spec.objectives) > 1 else "") \
        + f"{'feasible':8s} {'surv.':>5s}  " + " ".join(f"{n:>{max(len(n), 9)}s}" for n in names)
    click.echo(head)
    for r in shown:
        cells = [f"{r['number']:5d}", f"{r['state']:9s}",
                 f"{r['score']:8.3f}" if r["score"] is not None else f"{'-':>8s}"]
        if len(spec.objectives) > 1:
            cells.append(f"{r['speed']:7.4f}" if r["speed"] is not None else f"{'-':>7s}")
        cells.append(f"{'yes' if r['feasible'] else 'no':8s}")
        cells.append(f"{r['survival']:5.0%}" if r["survival"] is not None else f"{'-':>5s}")
        params = " ".join(f"{r['params'][n]:>{max(len(n), 9)}.4g}" if r["params"][n] is not None
                          else f"{'-':>{max(len(n), 9)}s}" for n in names)
        click.echo(" ".join(cells) + "  " + params)


@cli.command()
@click.argument("study_file", metavar="STUDY")
@_storage_option
@RUNS_OPTION
@click.option("--trial", "number", type=int, help="Export this trial instead of the best one.")
@click.option("--pareto-pick", type=click.Choice(["pitch", "speed", "knee"]),
              help="Two-objective studies: the Pareto point with the lowest pitch, the highest speed, or "
                   "the knee (nearest the best of both, each scaled over the front).")
@click.option("--out", type=OutPath(dir_okay=False),
              help="Parameter file to write (default: RUNS/<study>/best.yaml); the joint table goes "
                   "beside it (<out>.joints.csv).")
@COMMAND_OPTION
@COMMANDS_OPTION
@click.option("--duration", type=float, help="With --commands: seconds walked after the stream's last row [s] (default 2).")
@JOINT_NAMES_OPTION
@FORMAT_OPTION
@CLIP_OPTION
def export(study_file: str, storage: str | None, runs_dir: Path, number: int | None, pareto_pick: str | None,
           out: Path | None, command: str | None, commands_file: Path | None, duration: float | None,
           joint_names: str, table_format: str, clip: bool) -> None:
    """Write a study's best (or a chosen) trial as a parameter YAML plus its joint table.

    STUDY is the study file (or shipped study name). The YAML is accepted as it
    is by `simulate` and `trajectory`.
    """
    from .search.trials import best_trial, pareto_pick as pick, trial_engine, trial_fell, trial_params, trial_stabiliser

    if number is not None and pareto_pick is not None:
        raise UserError("give --trial or --pareto-pick, not both")
    if clip and joint_names != "robot":
        raise UserError("--clip writes the robot's own joints: leave out --joint-names ours")
    spec, study = _tuned_study(study_file, storage, runs_dir)
    if out is None:
        out = runs_dir / spec.name / "best.yaml"
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        t = pick(study, pareto_pick) if pareto_pick else best_trial(study, number)
        if spec.controller is not None:
            return _export_controller(spec, t, out)
        params = trial_params(spec.gait, t)
    except KeyError as exc:
        raise UserError(str(exc.args[0])) from None
    held = (t.user_attrs.get("speed") or {}).get("by_direction")
    desc = (f"study {spec.name} trial {t.number}{_commit_of(spec.source)}: score {t.values[0]:.6g}"
            + ("" if not trial_fell(t) or held else " (fell)")
            + ("" if not held else "; highest stairs held: "
               + ", ".join(f"{d} {v:.3g} {'rad/s' if d.startswith('turn') else 'm/s'}" for d, v in held.items()))
            + f"; surfaces {', '.join(spec.surfaces)}; robot {spec.robot}")
    from .robots import load_robot
    robot = load_robot(spec.robot)
    from .streams import load_stream
    cmd = _parse_command(command)
    if cmd is not None and commands_file is not None:
        raise UserError("give --command or --commands, not both")
    stream = None if commands_file is None else load_stream(commands_file, _tail(duration, commands_file))
    engine = trial_engine(t)
    drive = gaits.Drive(params, trial_stabiliser(t), cmd, stream, source=f"study {spec.name} trial {t.number}",
                        engine=engine)
    what = f"set {out.stem} ({drive.describe()}); surfaces {', '.join(spec.surfaces)}"
    if engine is not None and table_format == "servo":
        # what the engine sends: its targets as it walks the command in the simulator, on the study's
        # first surface (on the robot it re-plans from what it senses there: the same engine, other targets)
        traj = _engine_targets(drive, robot, spec.surfaces[0])
        what += f"; the engine's own targets walking it on {spec.surfaces[0]} in the simulator"
    else:
        traj = gaits.Drive(params, trial_stabiliser(t), cmd, stream).table(robot, robot.sim.control_period)
        if engine is not None:
            what += "; the engine's gait planned per step (--format servo: the engine's own targets)"
    table, table_text = joint_table_file(traj, robot, out.with_suffix(".joints.csv"), joint_names, what,
                                         table_format, clip)
    # the set and its table as one: after a kill at any moment both are new or both old
    write_files_atomic({table: table_text, out: gaits.gait_file_text(params, desc, trial_stabiliser(t), engine)})
    click.echo(f"trial {t.number} (score {t.values[0]:.4f}) -> {out} and {table}")


def _engine_targets(drive, robot, surface_name: str) -> "gaits.GaitTrajectory":
    """The targets an engine set sends walking its command (or a stop: standing) in the simulator,
    as a joint table (the robot's unmapped joints at zero: held), with the walk's references."""
    from .sim.rollout import Simulator
    from .sim.surfaces import load_surface
    if drive.command is None and drive.stream is None:
        drive = dataclasses.replace(drive, command=gaits.WalkCommand(0.0, 0.0, 0.0))
    sim = Simulator(robot, load_surface(surface_name))
    trace = _walk(drive, robot, sim, None)
    if trace.fell:
        click.echo(f"note: the engine's walk fell ({trace.reason}): the table ends there", err=True)
    q = np.zeros((len(trace.t), len(gaits.JOINT_NAMES)))
    for j, name in enumerate(sim.joint_names):
        q[:, gaits.JOINT_NAMES.index(name)] = trace.q_ref[:, j]
    return gaits.GaitTrajectory("engine", trace.t - trace.t[0], q, trace.p_torso, trace.p_com,
                                np.asarray(trace.zmp_ref)[:, :2], trace.p_sole_l, trace.p_sole_r,
                                np.asarray(trace.support, dtype=int), meta={"engine": True})


def _export_controller(spec, t, out: Path) -> None:
    """A controller study's trial as a controller file (its class, the tuned values, the ranges)."""
    from .controllers import save_controller
    from .search.trials import trial_fell
    values = (t.user_attrs.get("params") or {}).get("controller")
    if values is None:
        raise UserError(f"trial {t.number} recorded no controller parameters")
    user = spec.controller.with_params(values)
    desc = (f"study {spec.name} trial {t.number}{_commit_of(spec.source)}: score {t.values[0]:.6g}"
            + (" (fell)" if trial_fell(t) else "") + f"; surfaces {', '.join(spec.surfaces)}; robot {spec.robot}")
    save_controller(out, user, desc)
    click.echo(f"trial {t.number} (score {t.values[0]:.4f}) -> {out} (a controller file: "
               f"gait-tuner simulate --controller {out})")


@cli.command()
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

    from .report.compare import n_rows, run_compare

    names = [s for s in surface_names.split(",") if s]
    if not names:
        raise UserError("--surfaces: give at least one surface name or file")
    if study_file is not None:
        _tuned_study(study_file, None, runs_dir)     # a study with no runs: one line, before any walk
    for spec in params_specs:
        resolve_params(spec, None)
    from .sim.surfaces import load_surface
    for name in names:
        load_surface(name)
    if robot_name is None:
        if study_file is not None:
            from .search.study import load_study
            robot_name = load_study(study_file).robot
        else:
            robot_name = "kidsize"
    with tqdm(total=n_rows(list(params_specs), names, baselines), desc="compare", unit="set x surface",
              **_bar_options()) as bar:
        text = run_compare(list(params_specs), robot_name, names, baselines, study_file, runs_dir, out_dir,
                           workers=workers, progress=bar.update, random_rollouts=random_rollouts)
    click.echo(text)
    if video:
        from .report.compare import render_sets
        with tqdm(total=n_rows(list(params_specs), names, baselines), desc="videos", unit="video",
                  **_bar_options()) as bar:
            paths = render_sets(list(params_specs), robot_name, names, baselines, out_dir, progress=bar.update)
        click.echo(f"wrote {len(paths)} videos in {out_dir / 'videos'}")


@cli.command()
@click.option("--params", "params_spec", metavar="PATH|NAME",
              help="Parameter YAML file or shipped set (`gait-tuner sets`); or --controller.")
@robot_option()
@surface_option()
@click.option("--rollouts", default=100, show_default=True, type=click.IntRange(1, 100_000),
              help="Randomised rollouts without pushes.")
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
@click.option("--duration", type=float, help="With --commands: seconds walked after the stream's last row [s] (default 2).")
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

    from .sim.randomisation import randomisation_from_mapping
    from .sim.robustness import evaluate
    from .yaml_input import read_yaml_file

    if params_spec is None and controller_file is None:
        raise UserError("give --params (a gait set) or --controller (your own)")
    drive = resolve_drive(params_spec, None, stabiliser=stabiliser, command=_parse_command(command),
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
    from .robots import load_robot
    if not drive.online:
        drive.table(load_robot(robot_name), 0.01)      # a command the set cannot walk: one line, before any work
    else:                                              # an engine clips a command to its envelope: said
        _envelope_note(drive, drive.controller(load_robot(robot_name), 0.01))
    total = rollouts + len(sizes) * push_rollouts
    with tqdm(total=total, desc="robustness", unit="rollout", **_bar_options()) as bar:
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
        from .report.plots import plot_robustness
        path = plot_robustness(report, plot_dir)
        if not as_json:
            click.echo(f"wrote {path}")


@cli.group()
def challenge() -> None:
    """RoboCup Humanoid League technical challenges, simulated."""


@challenge.command(name="push")
@click.option("--params", "params_spec", metavar="PATH|NAME",
              help="Parameter YAML file or shipped set (`gait-tuner sets`); or --controller.")
@CONTROLLER_OPTION
@robot_option()
@surface_option("carpet4")
@click.option("--rules", type=click.Choice(["2025", "2019"]), default="2025", show_default=True,
              help="2025: the rules since 2025-02-13 (a 3, 5 or 10 kg bottle; pushes from the front, from behind, "
                   "from either; partial success at two; M). 2019: the old KidSize trial (a 1 kg bottle, three "
                   "random directions, sqrt(H) / (m H_com)), for comparison.")
@click.option("--bottle", type=click.Choice(["3", "5", "10"]), default="3", show_default=True,
              help="The bottle's mass [kg] (2025 rules).")
@click.option("--third", type=click.Choice(["both", "front", "back"]), default="both", show_default=True,
              help="2025 rules: where the third push comes from; both: each D tried with either, the worse counts.")
@click.option("--rope", default=1.5, show_default=True, type=Span(1.0, 2.0),
              help="Rope length L [m] to the bottle's centre of mass: 1.5-2 m by the 2025 rules, 1-2 m by 2019's.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1),
              help="Seed of the pushes: their directions (2019), their timing and a few degrees of direction (2025).")
@click.option("--step", default=0.05, show_default=True, type=Span(0.01, 0.5),
              help="How much D [m] grows from trial to trial.")
@click.option("--by-direction", is_flag=True,
              help="Not the rules' trial: single pushes per direction (--directions), each at 3.0 and 3.1 s, "
                   "D raised from 0.4 m by --step (0.1 with this flag unless given) until one fails: which "
                   "direction binds the rules' random three.")
@click.option("--directions", default="0,45,90,135,180,225,270,315", show_default=True, metavar="DEG,DEG,...",
              help="With --by-direction: the bottle's direction of travel against the robot's heading [deg] "
                   "(0 the way it faces, 90 to its left).")
@STABILISER_OPTION
@JSON_OPTION
@RECORD_OPTION
def challenge_push(params_spec: str | None, controller_file: Path | None, robot_name: str, surface_name: str,
                   rules: str, bottle: str, third: str, rope: float, seed: int, step: float, by_direction: bool,
                   directions: str, stabiliser: bool | None, as_json: bool, record_dir: Path | None) -> None:
    """The push-recovery challenge: a bottle on a rope released from a growing distance D.

    The robot walks in place. By the 2025 rules (the default): a 3, 5 or 10 kg bottle meets the
    robot at its CoM height; a trial is a push from the front, one from behind and one from either
    (--third); a push is absorbed when the robot is still up, stepping, at the next one; fully
    successful at three, partially at two; D (at most 0.75 L) grows by --step while a trial is at
    least partially successful; the largest D of each, the bottle's momentum at impact and M =
    sqrt(H) / h_c * m_B / m_R * h_i / h_c are reported. --rules 2019: a 1 kg bottle, three random
    directions, the rank sqrt(H) / (m_robot H_com). tuner/sim/challenge.py says what is ours.
    """

    from .robots import load_robot
    from .sim.challenge import challenge as run_challenge
    from .sim.rollout import Simulator
    from .sim.surfaces import load_surface

    if params_spec is None and controller_file is None:
        raise UserError("give --params (a gait set) or --controller (your own)")
    if not by_direction and click.get_current_context().get_parameter_source("directions").name != "DEFAULT":
        raise UserError("--directions is for --by-direction (the rules' trial draws its directions from --seed)")
    ctx = click.get_current_context()
    if rules == "2019":
        given = [o for o in ("bottle", "third") if ctx.get_parameter_source(o).name != "DEFAULT"]
        if given:
            raise UserError(f"--{given[0]} is for the 2025 rules (the 2019 trial has a 1 kg bottle and three random "
                            f"directions)")
    elif rope < 1.5:
        raise UserError(f"--rope {rope:g}: the 2025 rules' rope is 1.5 to 2 m (1 to 2 m with --rules 2019)")
    if rules == "2025" and by_direction:
        raise UserError("--by-direction is an analysis of the 2019 trial's random directions: add --rules 2019")
    drive = resolve_drive(params_spec, None, stabiliser=stabiliser, controller=controller_file)
    from .sim.scene import BOTTLE_2019, BOTTLES
    sim = Simulator(load_robot(robot_name), load_surface(surface_name), pendulum=rope,
                    bottle=BOTTLE_2019 if rules == "2019" else BOTTLES[int(bottle)])

    def shown(trial: dict) -> None:
        if not as_json:
            J = [p["measured_Ns"] for p in trial["pushes"]]
            click.echo(f"  D {trial['distance_m']:.2f} m: {'fully successful' if trial['success'] else trial['reason']}"
                       f" (pushes {', '.join('-' if j is None else f'{j:.2f}' for j in J)} N s measured)")
    if by_direction:
        if record_dir is not None:
            raise UserError("--record is for the rules' trial (each trial's walk one file), not --by-direction")
        _challenge_by_direction(sim, drive, directions, step, as_json)
        return
    if rules == "2025":
        _challenge_2025(sim, drive, seed, step, third, as_json, record_dir)
        return
    if not as_json:
        click.echo(f"push-recovery challenge: {drive.describe()} on {sim.robot.name} / {sim.surface.name}, rope {rope:g} m")
    report = run_challenge(sim, drive, seed=seed, step=step, progress=shown, record=record_dir)
    if _challenge_said(sim, drive, report, record_dir, as_json):
        return
    if report["best_distance_m"] is None:
        click.echo("no trial fully successful (not even the first)")
    else:
        click.echo(f"best D {report['best_distance_m']:.2f} m: H {report['drop_m'] * 1000:.0f} mm, momentum "
                   f"{report['momentum_Ns']:.2f} N s at impact, rank {report['rank']:.3f} "
                   f"(robot {report['robot_mass_kg']:.2f} kg, CoM {report['com_height_m']:.3f} m)")


@challenge.command(name="bound")
@robot_option()
@surface_option("carpet4")
@click.option("--bottle", type=click.Choice(["3", "5", "10"]), default="3", show_default=True,
              help="The bottle's mass [kg] (2025 rules).")
@click.option("--rope", default=1.5, show_default=True, type=Span(1.5, 2.0), help="Rope length L [m].")
@click.option("--steps", default=3, show_default=True, type=click.IntRange(1, 4),
              help="Steps the model may take to absorb a push.")
@JSON_OPTION
def challenge_bound(robot_name: str, surface_name: str, bottle: str, rope: float, steps: int, as_json: bool) -> None:
    """The physical bound for this robot: the largest push from behind and from the front that any
    step sequence within its limits absorbs, and the largest sustained forward speed.

    A trajectory optimisation (CasADi) of the linear inverted pendulum that knows the push in
    advance: step places and timings free, the ZMP anywhere on the sole (and within the ankle's
    torque), steps within the reach, each swing no shorter than the hip and knee servos' torque and
    speed allow. An upper bound within what it models; what it leaves out is said
    (tuner/search/bound.py)."""
    import json

    from .robots import load_robot
    from .search.bound import robot_bound
    from .sim.surfaces import load_surface
    out = robot_bound(load_robot(robot_name), load_surface(surface_name), float(bottle), rope, steps)
    if as_json:
        click.echo(json.dumps(out, indent=2, allow_nan=False))
        return
    m, m_b = out["model"], out["bottle_kg"]
    click.echo(f"bound for {out['robot']} on {out['surface']} (an upper bound of the LIPM within the servos' limits, "
               f"{steps} step(s) at most; {m['mass_kg']:.2f} kg, z_c {m['z_c_m']:.3f} m, ZMP {m['zmp_back_m'] * 1000:.0f} mm "
               f"back / {m['zmp_front_m'] * 1000:.0f} mm ahead, reach {m['reach_m'] * 1000:.0f} mm, lift "
               f"{m['lift_m'] * 1000:.0f} mm)")
    click.echo(f"  from the surface: {out['surface_terms']}")
    for side, label in (("from_behind", "from behind"), ("from_the_front", "from the front")):
        r = out[side]
        where = (f"D {r['distance_m']:.2f} m" + ("" if r["within_rules"] else f" (beyond the rules' 0.75 L = "
                                                                               f"{0.75 * rope:.2f} m)")
                 if r["distance_m"] is not None else "no release reaches it")
        click.echo(f"  a push {label}: Delta v {r['delta_v_mps']:.2f} m/s, a {m_b:g} kg bottle's "
                   f"{r['momentum_Ns']:.2f} N s, {where}" + (f", M {r['M']:.3f}" if r["M"] is not None else "")
                   + "; steps " + ", ".join(f"{p['step_m'] * 1000:.0f} mm in {p['swing_s']:.3f} s"
                                               for p in r["plan"]))
    sp = out["speed"]
    click.echo(f"  forward speed: {sp['speed_mps']:.2f} m/s (steps of {sp['step_m'] * 1000:.0f} mm every "
               f"{sp['period_s']:.3f} s), Froude number {sp['froude']:.2f}")
    click.echo("  left out (so an upper bound only within it): " + "; ".join(out["leaves_out"]))


def _challenge_said(sim, drive, report: dict, record_dir: Path | None, as_json: bool) -> bool:
    """Say where a challenge's trials were recorded; with ``as_json`` print the report (True: done)."""
    import json
    if record_dir is not None:
        click.echo(f"recorded {len(report['trials'])} trial(s) into {record_dir}", err=True)
    if as_json:
        click.echo(json.dumps({"robot": sim.robot.name, "surface": sim.surface.name, "params": drive.source,
                               "drive": drive.describe(), **report}, indent=2, allow_nan=False))
    return as_json


def _challenge_2025(sim, drive, seed: int, step: float, third: str, as_json: bool, record_dir: Path | None) -> None:
    """``challenge push`` by the 2025 rules (``challenge.challenge_2025``)."""
    import math

    from .sim.challenge import challenge_2025

    def shown(trial: dict) -> None:
        if as_json:
            return
        # a push from the front: the bottle moving backward against the heading (cos < 0)
        cells = ", ".join(f"{'front' if math.cos(math.radians(p['direction_deg'])) < 0 else 'back'} "
                          f"{'-' if p['measured_Ns'] is None else format(p['measured_Ns'], '.2f')} N s "
                          f"{'absorbed' if p['absorbed'] else 'not absorbed'}" for p in trial["pushes"])
        verdict = "fully successful" if trial["success"] else "partially successful" if trial["partial"] else \
            f"failed ({trial['reason']})"
        click.echo(f"  D {trial['distance_m']:.2f} m, third from the {trial['third']}: {verdict} ({cells})")
    if not as_json:
        click.echo(f"push-recovery challenge (2025 rules): {drive.describe()} on {sim.robot.name} / {sim.surface.name}, "
                   f"{sim.bottle.mass:g} kg bottle, rope {sim.rope:g} m, D up to {0.75 * sim.rope:.3g} m")
    report = challenge_2025(sim, drive, seed=seed, step=step, third=third, progress=shown, record=record_dir)
    if _challenge_said(sim, drive, report, record_dir, as_json):
        return
    for kind in ("full", "partial"):
        f = report[kind]
        if f["distance_m"] is None:
            click.echo(f"{'fully' if kind == 'full' else 'partially'} successful: no D (not even the first)")
        else:
            click.echo(f"{'fully' if kind == 'full' else 'partially'} successful up to D {f['distance_m']:.2f} m: H "
                       f"{f['drop_m'] * 1000:.0f} mm, {f['momentum_Ns']:.2f} N s at impact, M {f['M']:.3f}")
    click.echo(f"  (M = sqrt(H) / h_c * m_B / m_R * h_i / h_c: h_c = h_i = {report['com_height_m']:.3f} m, m_B "
               f"{report['bottle_kg']:g} kg, m_R {report['robot_mass_kg']:.2f} kg)")


def _challenge_by_direction(sim, drive, directions: str, step: float, as_json: bool) -> None:
    """``challenge push --by-direction``: single pushes per direction (``challenge.push_by_direction``)."""
    import json

    from .sim.challenge import push_by_direction

    try:
        dirs = tuple(float(v) for v in directions.split(",") if v.strip())
    except ValueError:
        raise UserError(f"--directions {directions!r}: expected comma-separated angles in degrees, e.g. 90,270") from None
    if not dirs or not all(-360.0 <= d <= 360.0 for d in dirs):
        raise UserError(f"--directions {directions!r}: give one or more angles in [-360, 360] deg")
    seen: dict[float, float] = {}
    for d in dirs:
        key = round(d % 360.0, 9) % 360.0
        if key in seen:
            same = seen[key]
            raise UserError(f"--directions {directions!r}: {d:g} deg is the direction of {same:g} deg, given "
                            "already (each direction is walked once)")
        seen[key] = d
    step = step if click.get_current_context().get_parameter_source("step").name != "DEFAULT" else 0.1

    def shown(row: dict) -> None:
        if not as_json:
            f = row["first_failure"]
            best = "none" if row["best_distance_m"] is None else \
                f"{row['best_distance_m']:.2f} m ({row['momentum_Ns']:.2f} N s)"
            click.echo(f"  {row['direction_deg']:5.0f} deg: best D {best}" +
                       (f"; fails at {f['distance_m']:.2f} m pushed at {f['push_s']:.1f} s: {f['reason']}" if f else ""))
    if not as_json:
        click.echo(f"single pushes by direction (not the rules' trial): {drive.describe()} on {sim.robot.name} / "
                   f"{sim.surface.name}, rope {sim.rope:g} m")
    rows = push_by_direction(sim, drive, directions=dirs, step=step, progress=shown)
    if as_json:
        click.echo(json.dumps({"robot": sim.robot.name, "surface": sim.surface.name, "params": drive.source,
                               "drive": drive.describe(), "rope_m": sim.rope, "by_direction": rows},
                              indent=2, allow_nan=False))
        return
    worst = min(rows, key=lambda r: r["best_distance_m"] or 0.0)
    click.echo(f"worst direction {worst['direction_deg']:.0f} deg: best D "
               + ("none" if worst["best_distance_m"] is None else f"{worst['best_distance_m']:.2f} m"))


@cli.group()
def robot() -> None:
    """Check a robot before you tune for it (the built-in `kidsize` or your robot map YAML)."""


def _robot_file_of(robot, spec: str):
    """The robot side's robot file (gaits.robot_file.RobotFile) of a loaded robot."""
    from gaits.robot_file import JointSpec, RobotFile
    model = robot.model()
    names = [theirs for theirs, _ in robot.joint_map.values()]
    lo, hi = robot.joint_ranges(names)
    joints = {}
    for (ours, (theirs, sign)), low, high in zip(robot.joint_map.items(), lo, hi):
        servo = robot.servos.get(theirs)
        joints[ours] = JointSpec(theirs, int(sign), float(low) if np.isfinite(low) else -np.pi,
                                 float(high) if np.isfinite(high) else np.pi,
                                 float(servo.speed) if servo else 6.5, float(servo.torque) if servo else 6.0,
                                 robot.servo_units.get(theirs))
    held = {j: float(v) for j, v in robot.pose.items() if j not in names}
    return RobotFile(robot.name, robot.leg, tuple(float(v) for v in robot.foot_size), joints,
                     robot.sim.control_period, float(np.sum(model.body_mass)), held,
                     bool(getattr(robot, "foot_sensors", True)))


@robot.command(name="export")
@click.argument("robot_spec", metavar="MAP|NAME")
@click.option("--out", "out", required=True, type=OutPath(dir_okay=False),
              help="The robot file to write (YAML, read by gaits.robot_file on the robot).")
def robot_export(robot_spec: str, out: Path) -> None:
    """Write the one robot file the robot side needs: leg geometry, soles, mass, joint order and
    signs, ranges, servo limits, and each joint's servo id, units, direction and offset (the map's
    servos: section), so the loop on the robot loads no robot model and copies no number by hand."""
    from gaits.robot_file import save_robot_file
    from .report.provenance import commit_of
    from .robots import load_robot
    robot = load_robot(robot_spec)
    rf = _robot_file_of(robot, robot_spec)
    joints, held = rf.joints, rf.held
    source = robot.map_path or robot_spec
    save_robot_file(out, rf, f"gait-tuner robot file of {robot.name} (from {source}{commit_of(__file__)}); "
                             f"read by gaits.robot_file.load_robot_file on the robot")
    with_servo = sum(j.servo is not None for j in joints.values())
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

    from .robots import load_robot
    from .report.robot_check import format_report, robot_report

    report = robot_report(load_robot(robot_spec), stand=not no_stand, duration=duration)
    click.echo(json.dumps(report, indent=2, allow_nan=False) if as_json else format_report(report))


@cli.command(name="studies")
def studies_cmd() -> None:
    """List the shipped studies."""
    from .search.study import list_studies, load_study
    for path in list_studies():
        spec = load_study(str(path))
        click.echo(f"{path.stem:26s} {spec.gait:7s} {','.join(spec.surfaces):32s} {spec.trials:4d} trials  "
                   f"{spec.description[:60]}")


@cli.command()
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

    from .sim.surfaces import SURFACES, load_surface
    chosen = [load_surface(n) for n in surface_names] or list(SURFACES.values())
    if not run_tests:
        if as_json:
            click.echo(json.dumps({s.name: s.to_mapping() for s in chosen}, indent=2, allow_nan=False))
            return
        for s in chosen:
            click.echo(f"{s.name:8s} layer {s.layer_height * 1000:4.0f} mm  drag {s.drag:5.1f} N s/m  "
                       f"friction {s.friction:.2f}  {s.description}")
        if any(s.drag_gated for s in chosen):
            from .sim import native_step
            native_step.install()
            click.echo(f"\ngrass drag gate on this machine: {native_step.status()}")
        return
    from .report.surface_tests import surface_tests
    from .report.tables import format_surface_tests
    report = surface_tests(chosen)
    click.echo(json.dumps(report, indent=2, allow_nan=False) if as_json else format_surface_tests(report))


@cli.command()
def baselines() -> None:
    """List the papers' shipped parameter sets (`gait-tuner sets` lists the tuned ones too)."""
    for name in list_baselines():
        gf = load_baseline(name)
        click.echo(f"{name:22s} {gf.family:7s} {gf.description[:90]}")


@cli.command()
@JSON_OPTION
def sets(as_json: bool) -> None:
    """List every shipped parameter set: the papers' baselines and the tuned results, with where
    each comes from (a study, trial and commit for a tuned one) and how it walks."""
    import json

    from .params_io import RESULTS_DIR, list_results
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


@cli.command()
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
def init(robot_name: str, surface_name: str, purpose: str, top_speed: float, out_dir: Path | None) -> None:
    """Make a walk for a robot: a starting set whose gait model has the robot's own masses, CoM
    height, stance and a step its knees' servos can carry, and the study that tunes it on the
    surface (tune it with `gait-tuner tune`, then `export`). Says where each number came from."""
    import yaml

    from .robots import BUILTIN_ROBOTS, load_robot
    from .search.initial import initial_walk
    from .sim.surfaces import load_surface
    robot = load_robot(robot_name)
    surface = load_surface(surface_name)
    ref = robot_name if robot_name in BUILTIN_ROBOTS else str(Path(robot_name).resolve())
    name = f"{robot.name}-{surface.name}-{purpose}"
    out_dir = out_dir or Path("runs") / "init" / name
    iw = initial_walk(robot, ref, surface, purpose, name=name, start_file=f"{name}-start.yaml", top_speed=top_speed)
    desc = (f"gait-tuner init for {robot.name} on {surface.name} ({purpose}): "
            + "; ".join(f"{k} {getattr(iw.params, k):g} from {why}" for k, why in iw.sources.items()))
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
    if iw.servo and robot.map_path:
        # the weight-sized gains go into a copy of the team's map beside the study, which walks it
        from .robots.robot_map import map_with_servo
        robot_file = out_dir / f"{name}-robot.yaml"
        files[robot_file] = (f"# {Path(robot.map_path).name} with the legs' servo gains sized to the robot's weight by "
                             f"gait-tuner init\n# ({iw.servo_source})\n"
                             + yaml.safe_dump(map_with_servo(Path(robot.map_path), out_dir, {"legs": iw.servo}),
                                              sort_keys=False))
        iw.study["robot"] = robot_file.name
    files[study] = ("# written by gait-tuner init; edit the space and the budget as you like\n"
                    + yaml.safe_dump(iw.study, sort_keys=False))
    write_files_atomic(files)
    click.echo(f"{robot.name} on {surface.name}, for {purpose}:")
    for k, why in iw.sources.items():
        click.echo(f"  {k:11s} {getattr(iw.params, k):8.4g}  from {why}")
    click.echo(f"  {'t1, t2':11s} {iw.params.t1:.3g}, {iw.params.t2:.3g}  TKU-X's shares of the step")
    for share, rung in iw.ladder:
        click.echo(f"  {'also tried':11s} {rung.period:8.4g}  the period whose swing asks the knee {share:.0%} of its speed")
    if iw.servo:
        key, value = next(iter(iw.servo.items()))
        click.echo(f"  {'legs ' + key:11s} {value:8.4g}  {iw.servo_source}")
    else:
        click.echo(f"  {'servo gains':11s} {'':8s}  {iw.servo_source}")
    click.echo("".join(f"wrote {p}\n" for p in files) + f"tune it: gait-tuner tune {study} --workers 2")


@cli.group()
def log() -> None:
    """Recordings of what a robot (or the simulator) did: MCAP files in the RoboCup HumanoidDataset
    layout (gaits/recording.py)."""


@log.command(name="info")
@click.argument("recording", type=click.Path(dir_okay=False, path_type=Path))
@JSON_OPTION
def log_info(recording: Path, as_json: bool) -> None:
    """Say what RECORDING holds: its robot, task and controller, its duration, and per channel the
    messages, the rate and the gaps (intervals over three times the median) or times that go back."""
    import json

    from gaits.files import MAX_BYTES, read_bytes_checked
    from gaits.recording import read_recording, recording_info
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


def _robot_map_path(robot_name: str) -> Path | None:
    """The robot map file behind ``--robot`` (None for a built-in robot)."""
    from .robots import BUILTIN_ROBOTS
    return None if robot_name in BUILTIN_ROBOTS else Path(robot_name)


@cli.command()
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

    from .robots import load_robot
    from .sim.harness import Harness, excitation, record_sweep, step_train
    robot = load_robot(robot_name)
    h = Harness(robot)
    try:
        t, targets = excitation(h, duration=duration, f1=f_max, amplitude=amplitude, seed=seed)
        sweep_s = float(t[-1])
        if steps:
            targets = np.vstack([targets, step_train(h, targets[-1], amplitude=step_size, seed=seed)])
            t = np.arange(len(targets)) * h.control_period
    except ValueError as exc:
        raise UserError(f"excite: {exc}") from None
    header = "t," + ",".join(f"target.{j}" for j in h.joint_names)
    rows = "\n".join(",".join([f"{t[k]:.4f}"] + [f"{v:.6f}" for v in targets[k]]) for k in range(len(t)))
    write_text_atomic(out, header + "\n" + rows + "\n")
    s = h.servo_arrays()
    lo, hi = h.range_ours()
    n_sweep = int(round(sweep_s / h.control_period)) + 1        # the sweep's rows (the steps jump, by design)
    speed = np.abs(np.diff(targets[:n_sweep], axis=0)).max(axis=0) / h.control_period
    info = {"robot": robot.name, "sweep": str(out), "seconds": float(t[-1]), "joints": list(h.joint_names),
            "amplitude_rad": dict(zip(h.joint_names, np.round((targets.max(0) - targets.min(0)) / 2, 4).tolist())),
            "speed_share": float(np.max(speed / h.nominal_speed())),
            "sweep_s": sweep_s, "steps_s": float(t[-1]) - sweep_s}
    if simulate_to is not None:
        record_sweep(h, targets, s, simulate_to, seed=seed, notes=f"gait-tuner excite --robot {robot_name}")
        info["recording"] = str(simulate_to)
    if as_json:
        click.echo(json.dumps(info, allow_nan=False))
        return
    click.echo(f"{robot.name}: a {sweep_s:.0f} s sweep of {h.n} joints at {0.2:g}-{f_max:g} Hz, at most "
               f"{info['speed_share'] * 100:.0f} % of a servo's speed"
               + (f", then {info['steps_s']:.0f} s of steps up to {step_size:g} rad, one joint at a time" if steps else "")
               + f"; wrote {out}")
    if simulate_to is not None:
        click.echo(f"wrote {simulate_to} (the sweep on the simulated robot in its harness)")


@cli.group()
def identify() -> None:
    """Fit the simulator to recordings of your robot: its servos (a sweep in a harness), then its
    ground (walks on the field). MuJoCo's system identification toolbox (mujoco[sysid])."""


RECORDING_OPTION = click.option("--recording", "recordings", multiple=True, required=True,
                                type=click.Path(path_type=Path), metavar="FILE",
                                help="A recording: gait-tuner's .mcap, a ROS 2 bag (folder, .mcap or .db3) "
                                     "or a .csv (tuner/recordings.py); repeat for several.")
TOPICS_OPTION = click.option("--topics", "topics_file", type=click.Path(dir_okay=False, path_type=Path),
                             help="A ROS 2 bag's topics and joint names (YAML; tuner/recordings.py).")


def _running_total(desc: str, unit: str):
    """A progress bar of a count that a callback reports as a running total (on a terminal only)."""
    from tqdm import tqdm
    bar = tqdm(desc=desc, unit=f" {unit}", disable=None, leave=False)
    seen = [0]

    def progress(n: int) -> None:
        bar.update(n - seen[0])
        seen[0] = n
    return bar, progress


@identify.command(name="servos")
@robot_option(default=None, help="The robot map YAML (or a built-in robot name).")
@RECORDING_OPTION
@TOPICS_OPTION
@click.option("--out", "out_dir", required=True, type=OutPath(file_okay=False), metavar="DIR",
              help="Where to write robot.yaml (your map with the servos identified), servos.yaml, fit.json "
                   "and report.txt.")
@click.option("--by", type=click.Choice(["groups", "joints"]), default="groups", show_default=True,
              help="Share the servo's numbers over hips, knees, ankles, arms and head, or fit each joint.")
@click.option("--noise", default=0.001, show_default=True, type=Span(1e-6, 0.1),
              help="The encoders' noise [rad]: the residual's unit.")
@click.option("--fit", "fit_fields", default="kp,damping,armature,frictionloss,torque,back_emf,speed,backlash,latency",
              show_default=True, metavar="FIELD,...", help="What to fit; the others keep the map's values.")
@click.option("--max-iters", default=40, show_default=True, type=click.IntRange(1, 500))
@click.option("--trace", is_flag=True, help="Print the optimiser's iterations on stderr.")
@JSON_OPTION
def identify_servos_cmd(robot_name: str | None, recordings: tuple[Path, ...], topics_file: Path | None,
                        out_dir: Path, by: str, noise: float, fit_fields: str, max_iters: int, trace: bool,
                        as_json: bool) -> None:
    """Identify the robot's servos from recordings of its joints (commanded and measured angles; best a
    sweep from `gait-tuner excite` on the robot hanging in a harness): per group or joint the gain,
    damping, armature, friction loss, torque and speed limits and backlash, and the latency."""
    import json

    from .recordings import RecordingError, read_field_recording
    from .report.identification import fit_json, summary_lines, write_servo_fit
    from .robots import load_robot
    from .sim.harness import Harness
    from .sim.identify import JointLog, identify_servos
    if robot_name is None:
        raise UserError("identify servos: give --robot (your robot map)")
    robot = load_robot(robot_name)
    h = Harness(robot)
    logs = []
    for path in recordings:
        try:
            rec = read_field_recording(path, topics=topics_file, robot_joints=robot.joint_map)
            t, targets, measured = rec.on_grid(h.control_period, h.joint_names)
        except RecordingError as exc:
            raise UserError(str(exc)) from None
        walking = rec.not_hanging()
        if walking is not None:
            raise UserError(f"identify servos: {path} is not of the robot hanging in a harness ({walking}): the fit's "
                            f"model holds the torso and lets no foot touch, which a walk's contacts break; record a "
                            f"sweep hanging (gait-tuner excite), and fit the ground from walks (identify ground)")
        for gap in rec.gaps[:3]:
            click.echo(f"note: {path}: {gap}", err=True)
        logs.append(JointLog(str(path), h.control_period, tuple(h.joint_names), targets, measured))
    bar, progress = _running_total("identify servos", "rollouts")
    try:
        fit = identify_servos(h, logs, by=by, noise=noise, max_iters=max_iters, progress=progress,
                              fit=tuple(f.strip() for f in fit_fields.split(",") if f.strip()),
                              trace=sys.stderr if trace else None)
    finally:
        bar.close()
    lost = fit.unfollowed(noise)
    if not fit.converged or lost:
        j = lost[0] if lost else None
        why = (f"it does not follow {j} (residual RMS {fit.rms_before[j] * 1000:.2f} -> {fit.rms_after[j] * 1000:.2f} "
               f"mrad): a wrong sign or joint name in the recording, or contacts in it" if j else "not a number")
        raise UserError(f"identify servos: the fit did not converge: {why}; nothing written")
    laws = {ours: robot.servos[robot.joint_map[ours][0]] for ours in h.joint_names}
    written = write_servo_fit(fit, _robot_map_path(robot_name), out_dir, noise, laws)
    if as_json:
        click.echo(json.dumps({**fit_json(fit), "written": [str(p) for p in written]}, allow_nan=False))
        return
    for line in summary_lines(fit, noise):
        click.echo(line)
    for p in written:
        click.echo(f"wrote {p}")


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

    from .recordings import RecordingError, read_field_recording
    from .report.identification import ground_lines, write_ground_fit
    from .robots import load_robot
    from .sim.identify_ground import identify_ground, walk_log
    from .sim.surfaces import load_surface
    if robot_name is None:
        raise UserError("identify ground: give --robot (your robot map, its servos identified)")
    robot = load_robot(robot_name)
    start = load_surface(surface_name)
    dt = robot.sim.control_period
    logs = []
    for path in recordings:
        try:
            rec = read_field_recording(path, topics=topics_file, robot_joints=robot.joint_map)
            joints = [j for j in rec.joints if j in robot.joint_map]
            grid = rec.on_grid(dt, joints)
            imu = rec.imu_on_grid(grid[0], rec.grid_start)
        except RecordingError as exc:
            raise UserError(str(exc)) from None
        for gap in rec.gaps[:3]:
            click.echo(f"note: {path}: {gap}", err=True)
        logs.append(walk_log(str(path), dt, grid, imu["rpy"], imu["gyro"], imu["accel"], joints))
    bar, progress = _running_total("identify ground", "replays")
    try:
        fit = identify_ground(robot, start, logs, max_iters=max_iters, progress=progress, horizon=horizon,
                              trace=sys.stderr if trace else None)
    finally:
        bar.close()
    worse = [k for k in fit.rms_after if not np.isfinite(fit.rms_after[k])]
    if worse or sum(fit.rms_after.values()) > sum(fit.rms_before.values()) * 1.0001:
        raise UserError("identify ground: the fit did not converge (its replays match the recordings no better than "
                        f"{start.name} does); nothing written")
    written = write_ground_fit(fit, out_dir)
    if as_json:
        click.echo(json.dumps({"surface": str(written[0]), "values": fit.values,
                               "intervals": {k: (v if np.isfinite(v) else None) for k, v in fit.intervals.items()},
                               "identifiable": fit.identifiable, "rms_before": fit.rms_before,
                               "rms_after": fit.rms_after, "replays": fit.rollouts}, allow_nan=False))
        return
    for line in ground_lines(fit):
        click.echo(line)
    for p in written:
        click.echo(f"wrote {p}")


@cli.command()
@click.argument("params_spec", metavar="SET")
@robot_option(default=None, help="The identified robot map (identify servos' robot.yaml).")
@click.option("--surface", "surface_name", required=True, metavar="SURFACE.yaml",
              help="The identified ground (identify ground's surface.yaml).")
@click.option("--default-robot", "default_robot", metavar="NAME|PATH",
              help="The robot as the tool knew it before (default: the same map).")
@click.option("--default-surface", "default_surface", metavar="NAME|PATH",
              help="The surface as the tool knew it before (default: the one the identification started "
                   "from, when its name says it: grass30-identified -> grass30).")
@click.option("--walks", default=20, show_default=True, type=click.IntRange(1, 10_000),
              help="Randomised match walks per world.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1))
@workers_option()
@JSON_OPTION
def transfer(params_spec: str, robot_name: str | None, surface_name: str, default_robot: str | None,
             default_surface: str | None, walks: int, seed: int, workers: int, as_json: bool) -> None:
    """The gap before the match: SET's randomised match walks (commands every 1-3 s, the default
    randomisation, tuner/sim/scenario.py) in the identified world beside the default one: survival,
    torso pitch and tracking, so a team sees what its field will do to its walk before it tunes."""
    import json

    from tqdm import tqdm

    from .report.transfer import transfer_lines, world_summary
    from .robots import BUILTIN_ROBOTS, load_robot
    from .sim.robustness import scenario_walks
    from .sim.scenario import MatchDistribution
    from .sim.surfaces import SURFACES, load_surface
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
    drive = resolve_drive(params_spec, None)
    worlds = {"default": (default_robot, default_surface), "identified": (robot_name, surface_name)}
    out = {}
    with tqdm(total=2 * walks, desc="transfer", unit="walk", **_bar_options()) as bar:
        for key, (robot, surface) in worlds.items():
            rows = scenario_walks(robot, surface, drive, MatchDistribution(), walks=walks, seed=seed,
                                  workers=workers, progress=bar.update)
            out[key] = (f"{load_robot(robot).name} on {load_surface(surface).name}", world_summary(rows))
    if as_json:
        click.echo(json.dumps({k: {"world": w, **s} for k, (w, s) in out.items()}, allow_nan=False))
        return
    for line in transfer_lines(drive.source or params_spec, out):
        click.echo(line)


@cli.command()
@click.argument("walk_specs", metavar="WALK...", nargs=-1, required=True)
@robot_option()
@click.option("--surfaces", "surface_names", default="rigid,grass30", show_default=True,
              help="Comma-separated surfaces (names or files).")
@click.option("--speeds", default="0.2,0.1,0.1,0.5", show_default=True, metavar="FWD,BACK,SIDE,TURN",
              help="The command asked in each direction [m/s, m/s, m/s, rad/s]; 0 leaves a direction out.")
@click.option("--walks", default=20, show_default=True, type=click.IntRange(0, 10_000),
              help="Randomised match walks per walk and surface (0: none).")
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

    from .report.tables import json_finite
    from .report.versus import DIRECTIONS, versus_cell, versus_markdown, versus_plots
    from .robots import load_robot
    from .sim.surfaces import load_surface
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
    robot = load_robot(robot_name)
    for n in names:
        load_surface(n)
    drives = [(Path(spec).stem if spec.endswith((".yaml", ".yml")) else spec, resolve_drive(spec, None))
              for spec in walk_specs]
    labels = [label for label, _ in drives]
    if len(set(labels)) != len(labels):
        raise UserError(f"versus: two walks share the name {next(x for x in labels if labels.count(x) > 1)!r}: "
                        f"rename one file")
    out_dir.mkdir(parents=True, exist_ok=True)
    per_cell = len(speed_of) + walks + (1 if challenge else 0)
    cells = []
    with tqdm(total=len(drives) * len(names) * per_cell, desc="versus", unit="walk", **_bar_options()) as bar:
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


@cli.group()
def bus() -> None:
    """A simulated Dynamixel bus: the robot-side code (gait-tuner-loop) drives the simulated robot
    through real Protocol 2.0 packets on a pseudo-terminal (tuner/sim/bus.py)."""


@bus.command(name="serve")
@robot_option(help="Built-in robot name or a robot map YAML (with a servos: section).")
@surface_option()
@click.option("--link", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also make this path a link to the bus's pseudo-terminal (a fixed name for the client).")
@click.option("--baud", default="1000000", show_default=True,
              type=click.Choice(["57600", "115200", "1000000", "2000000", "3000000", "4000000"]))
@click.option("--duration", default=600.0, show_default=True, type=Span(0.1, 86400.0),
              help="Longest walk [s] of simulated time.")
@click.option("--idle", default=5.0, show_default=True, type=Span(0.5, 600.0),
              help="End once the client has been silent this long [s].")
@click.option("--hang", is_flag=True, help="The robot hangs in a harness (for a sweep: gait-tuner-loop --sweep).")
@click.option("--randomisation", "randomisation_spec", metavar="YAML|default|none", default="none", show_default=True,
              help="Perturb the simulated robot and field as `robustness` does (default: its defaults; a YAML "
                   "overrides fields): walk I of --seed S is robustness's rollout I of the same seed.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1),
              help="With --randomisation: the evaluation seed.")
@click.option("--walk", "walk_index", default=0, show_default=True, type=click.IntRange(0, 999_999),
              help="With --randomisation: which of the seed's walks (robustness's rollout number).")
def bus_serve(robot_name: str, surface_name: str, link: Path | None, baud: str, duration: float, idle: float,
              hang: bool, randomisation_spec: str, seed: int, walk_index: int) -> None:
    """Serve ROBOT's servos and IMU on a pseudo-terminal, answered by MuJoCo in lockstep (a tick of
    physics per sync write of goal positions). Prints the bus's path, then what the walk did.
    With --hang the robot hangs in a harness (its torso held, feet off the ground): play a sweep
    on it (gait-tuner-loop --sweep) and record what identify servos fits."""
    from .robots import load_robot
    from .sim.bus import serve
    from .sim.rollout import Simulator
    from .sim.surfaces import load_surface
    robot = load_robot(robot_name)
    rf = _robot_file_of(robot, robot_name)
    missing = [o for o, j in rf.joints.items() if j.servo is None]
    if missing:
        raise UserError(f"{robot_name}: no servo id for {', '.join(missing)}: give the map a servos: section")
    if hang:
        from .sim.harness import Harness, HangingSim
        sim = HangingSim(Harness(robot))
    else:
        sim = Simulator(robot, load_surface(surface_name))
    perturb = None
    if randomisation_spec != "none":
        if hang:
            raise UserError("--randomisation is for a walk on the ground, not --hang")
        from .sim.randomisation import EVALUATE, draw, randomisation_from_mapping
        from .yaml_input import read_yaml_file
        doc = None if randomisation_spec == "default" else read_yaml_file(Path(randomisation_spec), "randomisation")
        perturb = draw(randomisation_from_mapping(doc, randomisation_spec), (seed, walk_index), *sim.n_random(),
                       namespace=EVALUATE)

    def ready(path: str) -> None:
        click.echo(f"bus of {robot.name} on {sim.surface.name} at {path} ({baud} baud, "
                   f"{len(rf.joints)} servos, IMU id 200)", err=False)
        sys.stdout.flush()
    out = serve(sim, rf, baudrate=int(baud), link=None if link is None else str(link), idle=idle, duration=duration,
                ready=ready, perturb=perturb)
    click.echo(f"served {out['ticks']} ticks ({out['ticks'] * sim.control_period:.2f} s); ended: {out['ended']}"
               + (f"; the walk: {out['outcome']}" if out["outcome"] else "")
               + (f"; {out['ignored']} packet(s) not answered" if out["ignored"] else "")
               + (f"; randomised: seed {seed}, walk {walk_index}" if perturb is not None else ""))
    if out["ticks"]:
        click.echo(f"on the wire: {out['bytes_per_tick']:.0f} bytes a tick, {out['wire_ms_per_tick']:.2f} ms at {baud} "
                   f"baud (a real bus adds this, and each servo's return delay, to every tick's latency)")


@cli.command(name="params")
@click.argument("family", type=click.Choice(FAMILIES))
def params_cmd(family: str) -> None:
    """Print a family's parameters (name, default, unit, allowed range, paper symbol) and the walk
    commands it takes."""
    for row in family_class(family).field_table():
        paper = row["paper"] or ""
        click.echo(f"{row['name']:22s} {str(row['default']):>12.12s}  {row['range']:28s} "
                   f"{paper:8s} {row['doc']}")
    click.echo(f"walk command (--command): {gaits.family(family).commands_text}")
    click.echo("online (an engine: section): " + ("the walk engine, footsteps and CoM re-planned each step from "
               "the measured state (gaits/engine/)" if gaits.family(family).engine == "feedback" else
               "the family's table re-planned at each step start for the current command, no state feedback "
               "(gaits/online_table.py)"))


_SYSTEM_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG}
#: a path that cannot name a file (inside a file, too long, a folder, a link loop): a bad --out or file name
_PATH_ERRNOS = {errno.ENOTDIR, errno.ENAMETOOLONG, errno.EISDIR, errno.ELOOP}


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turn bad input into one line on stderr and exit code 2."""
    import tuner
    if signal.getsignal(signal.SIGINT) is tuner._interrupted_while_loading:
        signal.signal(signal.SIGINT, signal.default_int_handler)     # loaded: Ctrl-C is ours to handle
    try:
        cli.main(args=argv, prog_name="gait-tuner", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.Abort:
        click.echo("gait-tuner: interrupted", err=True)
        return 130
    except click.ClickException as exc:
        # one line, as for every other bad input (click's own output is a usage block)
        ctx = getattr(exc, "ctx", None)
        hint = f" (see `{ctx.command_path} --help`)" if ctx is not None else ""
        msg = " ".join(exc.format_message().split())
        click.echo(f"gait-tuner: error: {msg}{hint}", err=True)
        return EXIT_USAGE
    except (UserError, ParamError, UnreachableTargetError) as exc:
        click.echo(f"gait-tuner: error: {exc}", err=True)
        return EXIT_SYSTEM if type(exc).__name__ == "StorageFull" else EXIT_USAGE
    except OSError as exc:
        if exc.errno in _PATH_ERRNOS:       # a path the user gave that cannot be a file: their mistake
            where = f"{exc.filename}: " if exc.filename else ""
            why = {errno.ENOTDIR: "a part of the path is a file, not a folder",
                   errno.ENAMETOOLONG: "a name in the path is longer than the file system allows",
                   errno.EISDIR: "it is a folder, not a file", errno.ELOOP: "too many symbolic links"}[exc.errno]
            click.echo(f"gait-tuner: error: {where}{why}", err=True)
            return EXIT_USAGE
        if exc.errno not in _SYSTEM_ERRNOS:
            raise_internal = exc
        else:
            where = f"{exc.filename}: " if exc.filename else ""
            click.echo(f"gait-tuner: error: {where}{exc.strerror or exc} (a file being written there was "
                       f"left as it was)", err=True)
            return EXIT_SYSTEM
        click.echo(f"gait-tuner: internal error: {raise_internal.__class__.__name__}: {raise_internal} "
                   f"(please report it)", err=True)
        return EXIT_INTERNAL
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
