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

from .errors import UserError  # noqa: F401 - the package's face: tuner.UserError

#: the public names and where they live: imported when first asked for (PEP 562), so that
#: ``import tuner`` (every verb's first step, ``gait-tuner --help`` included) loads no simulator
_PUBLIC = {"DEFINITIONS": "sim.metrics", "Metrics": "sim.metrics", "summarize": "sim.metrics",
           "resolve_params": "params_io", "Randomisation": "sim.randomisation", "RobotModel": "robots",
           "RobotSpec": "robots", "load_robot": "robots", "ServoLaw": "servos", "FallCriteria": "sim.rollout",
           "Simulator": "sim.rollout", "Trace": "sim.rollout", "SURFACES": "sim.surfaces", "Surface": "sim.surfaces",
           "load_surface": "sim.surfaces"}

__all__ = sorted(["UserError", *_PUBLIC])


def __getattr__(name: str):
    if name in _PUBLIC:
        import importlib
        value = getattr(importlib.import_module(f".{_PUBLIC[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'tuner' has no attribute {name!r}")
