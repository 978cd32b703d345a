"""gait-tuner's running half: robots, surfaces, simulation, metrics, the CasADi seed and the search.

``gaits`` holds the pure math; everything that steps physics or optimises lives here.
"""

from __future__ import annotations

import os as _os
import sys as _sys

# MuJoCo picks its OpenGL backend when it is first imported. With no display (a server, CI),
# default to EGL (headless; Mesa's software renderer where there is no GPU) so `render` works;
# with a display the default (GLFW) serves both `render` and the interactive `view`.
if ("MUJOCO_GL" not in _os.environ and _sys.platform.startswith("linux")
        and not _os.environ.get("DISPLAY") and not _os.environ.get("WAYLAND_DISPLAY")):
    _os.environ["MUJOCO_GL"] = "egl"


def _interrupted_while_loading(signum: int, frame: object) -> None:
    """Ctrl-C before the command line is ready (its libraries load for a second or two, longer on
    a loaded machine): one line and 130, as any interrupt of `gait-tuner`. A signal handler, not an
    ``except KeyboardInterrupt`` here: the interrupt may land in any module the command line
    imports (ours, click's, the standard library's). Nothing is open yet, so nothing to tidy.
    :func:`tuner.cli.main` gives Ctrl-C back to Python's handler once it runs."""
    _sys.stderr.write("gait-tuner: interrupted\n")
    _sys.stderr.flush()
    _os._exit(130)


if _os.path.basename(_sys.argv[0] if _sys.argv else "") == "gait-tuner":
    import signal as _signal
    import threading as _threading
    if (_threading.current_thread() is _threading.main_thread()
            and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler):
        _signal.signal(_signal.SIGINT, _interrupted_while_loading)

from .errors import UserError
from .sim.metrics import DEFINITIONS, Metrics, summarize
from .params_io import resolve_params
from .sim.randomisation import Randomisation
from .robots import RobotModel, RobotSpec, load_robot
from .servos import ServoLaw
from .sim.rollout import FallCriteria, Simulator, Trace
from .sim.surfaces import SURFACES, Surface, load_surface

__all__ = [
    "DEFINITIONS",
    "FallCriteria",
    "Metrics",
    "Randomisation",
    "RobotModel",
    "RobotSpec",
    "SURFACES",
    "ServoLaw",
    "Simulator",
    "Surface",
    "Trace",
    "UserError",
    "load_robot",
    "load_surface",
    "resolve_params",
    "summarize",
]
