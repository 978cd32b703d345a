"""The ``gait-tuner`` command line's root: the verbs, each loaded only when it runs, and ``main``.

Each verb (or group of verbs) lives in a module of this package: it parses, calls one function of a
wing, prints. The root names them (:data:`VERBS`: module, command, one-line help), so that
``gait-tuner --help`` and a refusal of an unknown verb load no simulator, optimiser or gait; a
verb's module is imported when it is asked for (``tests/test_cli_face.py`` checks the one-line helps
against the commands' own).

Exit codes: 0 done; 1 internal error (a bug: please report it); 2 bad input (a file, a name or a
value; the one-line message says which); 3 the system refused (a full disk, a read-only folder).
"""

from __future__ import annotations

import errno
import importlib
import signal
import sys

import click

from ..errors import EXIT_INTERNAL, EXIT_SYSTEM, EXIT_USAGE, UserError

__all__ = ["cli", "main", "run", "VERBS"]

#: verb -> (module of this package, its click command, its one-line help as ``--help`` lists it)
VERBS: dict[str, tuple[str, str, str]] = {
    "baselines": ("robot", "baselines", "List the papers' shipped parameter sets (`gait-tuner sets` lists the tuned ones too)."),
    "bus": ("robot", "bus", "A simulated Dynamixel bus: the robot-side code (gait-tuner-loop) drives the simulated robot "
                            "through real Protocol 2.0 packets on a pseudo-terminal (tuner/sim/bus.py)."),
    "calibrate": ("papers", "calibrate", "Re-derive the pedestals' ground numbers from the EROS Tables 7-8 (slow: tens of "
                                         "minutes)."),
    "challenge": ("challenge", "challenge", "RoboCup Humanoid League technical challenges, simulated."),
    "compare": ("evaluate", "compare", "Compare parameter sets side by side: stability matrix, stability %, pitch, ZMP "
                                       "error, speed."),
    "excite": ("identify", "excite", "Write the joint sweep to play on the robot hanging in a harness (feet off the "
                                     "ground), the recording to identify its servos from: a chirp per joint within its "
                                     "range, at most 60 % of its servo's speed and, played on the simulated harness, 80 % "
                                     "of its torque."),
    "experiment": ("papers", "experiment", "Run a paper's experiment in simulation and print it beside the paper's "
                                           "numbers."),
    "export": ("study", "export", "Write a study's best (or a chosen) trial as a parameter YAML plus its joint table."),
    "identify": ("identify", "identify", "Fit the simulator to recordings of your robot: its servos (a sweep in a "
                                         "harness), then its ground (walks on the field)."),
    "init": ("robot", "init", "Make a walk for a robot: a starting set whose gait model has the robot's own masses, CoM "
                              "height, stance and a step its knees' servos can carry, and the study that tunes it on the "
                              "surface (tune it with `gait-tuner tune`, then `export`)."),
    "log": ("identify", "log", "Recordings of what a robot (or the simulator) did: MCAP files in the RoboCup "
                               "HumanoidDataset layout (gaits/robot/recorder.py)."),
    "params": ("walks", "params_cmd", "Print a family's parameters (name, default, unit, allowed range, paper symbol) and "
                                      "the walk commands it takes."),
    "render": ("walks", "render", "Film a walk: an MP4 from MuJoCo's offscreen renderer, headless."),
    "robot": ("robot", "robot", "Check a robot before you tune for it (the built-in `kidsize` or your robot map YAML)."),
    "robustness": ("evaluate", "robustness", "Does a gait survive what differs between our model and your robot and "
                                             "field?"),
    "sets": ("robot", "sets", "List every shipped parameter set: the papers' baselines and the tuned results, with where "
                              "each comes from (a study, trial and commit for a tuned one) and how it walks."),
    "simulate": ("walks", "simulate", "Walk a gait on a robot and a surface in MuJoCo and print its metrics."),
    "studies": ("robot", "studies_cmd", "List the shipped studies."),
    "surfaces": ("robot", "surfaces", "List the built-in surfaces and their contact parameters (--test: the turf test "
                                      "methods on them)."),
    "train": ("train", "train", "Train a set's residual (a linear correction on the walk engine's leg targets) in "
                                "the simulator's closed loop: random search over randomised match walks or push "
                                "trials, the set written after every iteration."),
    "trajectory": ("walks", "trajectory", "Generate a gait's joint table q_ref(t) and its Cartesian references for a "
                                          "robot."),
    "transfer": ("evaluate", "transfer", "The gap before the match: SET's randomised match walks (commands every 1-3 s, "
                                         "the default randomisation, tuner/sim/match_walks.py) in the identified world "
                                         "beside the default one: survival, torso pitch and tracking, so a team sees what "
                                         "its field will do to its walk before it tunes."),
    "trials": ("study", "trials", "List a study's trials: state, objectives, feasibility, survival, searched "
                                  "parameters."),
    "tune": ("study", "tune", "Run (or resume) a tuning study: Optuna search seeded by CasADi, against MuJoCo walks."),
    "versus": ("evaluate", "versus", "Walks side by side on one robot: sets, controllers, policies, placo."),
    "view": ("walks", "view", "Watch a walk in MuJoCo's interactive viewer (needs a display)."),
    "worker": ("study", "worker", "Join a study from this machine and run its trials until the study's budget is "
                                  "reached."),
}


class LazyGroup(click.Group):
    """A click group whose verbs are imported when asked for; ``--help`` lists them from
    :data:`VERBS` without importing any."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(VERBS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in VERBS:
            return None
        module, attr, _ = VERBS[name]
        return getattr(importlib.import_module(f".{module}", __package__), attr)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        width = formatter.width - 6 - max(len(n) for n in VERBS)
        rows = [(n, _short(VERBS[n][2], width)) for n in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


def _short(text: str, width: int) -> str:
    """A verb's one-line help in ``width`` characters: whole words, "..." where it is cut (click's own
    helper for this is deprecated in click 8.2 and goes in 9)."""
    text = " ".join(text.split())
    if len(text) <= width:
        return text
    cut = text[:max(width - 3, 1)]
    return (cut.rsplit(" ", 1)[0] if " " in cut else cut).rstrip(" ,;:") + "..."


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="gait-tuner")
def cli() -> None:
    """Tune the walking gaits of kid-size humanoid robots in simulation, per ground surface.

    Gait families: eros (quarter-circle trajectory, heel strike, landing
    deceleration), tlipfm (natural ZMP on the three-mass LIPM plus flywheel;
    lipm and dlipm as its comparisons), cosine (5-DoF cosine-law walking diagram).
    """


_SYSTEM_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG}


def _bad_input(exc: BaseException) -> bool:
    """A user's mistake that a lower layer raised: ours, or the gait files' (``gaits`` is loaded by
    then if it raised one)."""
    if isinstance(exc, UserError):
        return True
    gaits = sys.modules.get("gaits")
    return gaits is not None and isinstance(exc, (gaits.ParamError, gaits.UnreachableTargetError))


_interrupts = [0]          # Ctrl-Cs taken by this process's handler


def _on_ctrl_c(signum: int, frame: object) -> None:
    """Python's own Ctrl-C, counted: a verb's module and its libraries now load when it runs, and a
    Ctrl-C in the middle of a compiled library's import surfaces as an ImportError; counted, it is
    still an interrupt (one line, 130), not an internal error."""
    _interrupts[0] += 1
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turn bad input into one line on stderr and exit code 2."""
    import tuner
    if signal.getsignal(signal.SIGINT) in (tuner._interrupted_while_loading, signal.default_int_handler):
        signal.signal(signal.SIGINT, _on_ctrl_c)     # loaded: Ctrl-C is ours to handle
    seen = _interrupts[0]
    try:
        cli.main(args=argv, prog_name="gait-tuner", standalone_mode=False)
    except (click.Abort, KeyboardInterrupt):
        click.echo("gait-tuner: interrupted", err=True)
        return 130
    except Exception as exc:  # noqa: BLE001 - sorted below
        if _interrupts[0] > seen:                       # whatever a Ctrl-C broke on its way out
            click.echo("gait-tuner: interrupted", err=True)
            return 130
        return _said(exc)
    return 0


def _said(exc: Exception) -> int:
    """One line on stderr for what ended a verb, and its exit code."""
    try:
        raise exc
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.ClickException as exc:
        # one line, as for every other bad input (click's own output is a usage block)
        ctx = getattr(exc, "ctx", None)
        hint = f" (see `{ctx.command_path} --help`)" if ctx is not None else ""
        msg = " ".join(exc.format_message().split())
        click.echo(f"gait-tuner: error: {msg}{hint}", err=True)
        return EXIT_USAGE
    except OSError as exc:
        # a path that cannot name a file (inside a file, too long, a folder, a link loop): a bad --out
        # or file name, the user's mistake (gaits.files says each in words; imported here, not before
        # a verb needs it)
        from gaits.files import PATH_PROBLEMS, FolderRefused
        if exc.errno in PATH_PROBLEMS or isinstance(exc, FolderRefused):
            where = f"{exc.filename}: " if exc.filename else ""
            why = exc.strerror if isinstance(exc, FolderRefused) else PATH_PROBLEMS[exc.errno]
            click.echo(f"gait-tuner: error: {where}{why}", err=True)
            return EXIT_USAGE
        if exc.errno in _SYSTEM_ERRNOS:
            where = f"{exc.filename}: " if exc.filename else ""
            click.echo(f"gait-tuner: error: {where}{exc.strerror or exc} (a file being written there was "
                       f"left as it was)", err=True)
            return EXIT_SYSTEM
        click.echo(f"gait-tuner: internal error: {exc.__class__.__name__}: {exc} (please report it)", err=True)
        return EXIT_INTERNAL
    except Exception as exc:  # noqa: BLE001 - last resort: one line, not a traceback
        if _bad_input(exc):
            click.echo(f"gait-tuner: error: {exc}", err=True)
            return EXIT_SYSTEM if type(exc).__name__ == "StorageFull" else EXIT_USAGE
        click.echo(f"gait-tuner: internal error: {exc.__class__.__name__}: {exc} "
                   f"(please report it)", err=True)
        return EXIT_INTERNAL


def run() -> None:
    """Console-script entry: exit with :func:`main`'s code."""
    sys.exit(main())
