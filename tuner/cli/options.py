"""What several verbs share, declared once: the options, their types, and the progress printers.

Nothing here imports a simulator or a gait at import time (``gait-tuner --help`` loads none):
the gait families a ``--gait`` takes are read from ``gaits`` when the option is first used.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click


__all__ = ["OutPath", "TAIL_OPTION", "Span", "FamilyChoice", "robot_option", "surface_option", "workers_option", "GAIT_OPTION",
           "PARAMS_OPTION", "JSON_OPTION", "RECORD_OPTION", "RUNS_OPTION", "STABILISER_OPTION", "COMMANDS_OPTION",
           "CONTROLLER_OPTION", "COMMAND_OPTION", "parse_command", "JOINT_NAMES_OPTION", "FORMAT_OPTION", "CLIP_OPTION",
           "SAVE_SCENE_OPTION", "walk_options", "bar_options", "storage_option", "RECORDING_OPTION", "TOPICS_OPTION",
           "running_total"]


class FamilyChoice(click.Choice):
    """click's ``Choice`` over the registered gait families (``gaits/families.py``), read when the
    option is first used rather than when the command line loads."""

    def __init__(self) -> None:
        super().__init__(())

    @property
    def choices(self):
        from gaits import families
        return tuple(families())

    @choices.setter
    def choices(self, value) -> None:       # click's __init__ sets it; the families are the registry's
        pass


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


GAIT_OPTION = click.option("--gait", "family", type=FamilyChoice(),
                           help="Gait family (taken from the parameter file if omitted).")


PARAMS_OPTION = click.option("--params", "params_spec", metavar="PATH|NAME",
                             help="Parameter YAML file, shipped baseline or tuned set (`gait-tuner sets`). "
                                  "Default: the family's paper baseline.")


JSON_OPTION = click.option("--json", "as_json", is_flag=True, help="Print the result as strict JSON.")


RECORD_OPTION = click.option(
    "--record", "record_dir", type=OutPath(file_okay=False),
    help="Record every tick of every walk (what the controller was given and what it asked) into this folder, an "
         "MCAP file per walk (gaits/robot/recorder.py); `gait-tuner log info FILE` says what one holds.")


RUNS_OPTION = click.option("--runs", "runs_dir", default=None, type=OutPath(file_okay=False),
                           help="Folder of the journal files [default: the study file's runs: (init writes one "
                                "beside its study), else ./runs].")


STABILISER_OPTION = click.option(
    "--stabiliser/--no-stabiliser", default=None,
    help="Use the parameter file's IMU stabiliser (default: as the file says) or switch it off.")


COMMANDS_OPTION = click.option(
    "--commands", "commands_file", type=click.Path(dir_okay=True, path_type=Path), metavar="STREAM.csv",
    help="Walk a command stream: CSV with the header t,vx,vy,wz (s, m/s, m/s, rad/s), each row holding "
         "until the next; the walk lasts until the last row plus --duration (default 2 s). A set without "
         "an engine walks it planned per step before the walk.")
#: With --commands: how long the walk goes on after the stream's last row (every verb that walks one)
TAIL_OPTION = click.option("--duration", type=float,
                           help="With --commands: seconds walked after the stream's last row [s] (default 2).")


CONTROLLER_OPTION = click.option(
    "--controller", "controller_file", type=click.Path(path_type=Path), metavar="CONTROLLER.yaml",
    help="Walk a controller of your own instead of a gait set: a YAML naming its class and parameters "
         "(tuner/controllers.py). Its code runs.")


COMMAND_OPTION = click.option(
    "--command", metavar="VX,VY,WZ",
    help="Walk this velocity (m/s forward, m/s left, rad/s counter-clockwise), ramped from rest "
         "and back (eros and tlipfm: any direction; cosine: forward and backward only). A command beyond the parameter set's step limits is an error "
         "naming the step and the limit.")


def parse_command(text: str | None):
    if text is None:
        return None
    from gaits import parse_command as parse
    return parse(text)


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


SAVE_SCENE_OPTION = click.option(
    "--save-scene", type=OutPath(dir_okay=False), metavar="SCENE.xml",
    help="Also write the assembled robot + surface model as one MJCF file (loads in any MuJoCo tool; "
         "the blade drag is applied by our loop, not in the file).")


def walk_options(f):
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


def bar_options() -> dict:
    """Progress bars live on a terminal, a line every 15 s in a log (never silent for minutes)."""
    if sys.stderr.isatty():
        return {"disable": False, "mininterval": 0.5}
    return {"disable": False, "mininterval": 15.0, "delay": 15.0, "file": _LogLines(), "ascii": True}


def storage_option(f):
    return click.option("--storage", metavar="URL",
                        help="sqlite:///FILE.db or postgresql://USER@HOST[:PORT]/DB (driver: pip install "
                             "'gait-tuner[postgres]'). Default: the journal file RUNS/<study>.journal, no server.")(f)


RECORDING_OPTION = click.option("--recording", "recordings", multiple=True, required=True,
                                type=click.Path(path_type=Path), metavar="FILE",
                                help="A recording: gait-tuner's .mcap, a ROS 2 bag (folder, .mcap or .db3) "
                                     "or a .csv (tuner/identify/field_recordings.py); repeat for several.")


TOPICS_OPTION = click.option("--topics", "topics_file", type=click.Path(dir_okay=False, path_type=Path),
                             help="A ROS 2 bag's topics and joint names (YAML; tuner/identify/field_recordings.py).")


def running_total(desc: str, unit: str):
    """A progress bar of a count that a callback reports as a running total: on a terminal, and a
    line every 15 s in a log (never silent for minutes). ``bar.total`` may be set later (an upper
    bound: the bar then says how long at most)."""
    from tqdm import tqdm
    bar = tqdm(desc=desc, unit=f" {unit}", leave=False, **bar_options())
    seen = [0]

    def progress(n: int) -> None:
        bar.update(n - seen[0])
        seen[0] = n
    return bar, progress

