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

try:
    from .errors import UserError
    from .sim.metrics import DEFINITIONS, Metrics, summarize
    from .params_io import resolve_params
    from .sim.randomisation import Randomisation
    from .robots import RobotModel, RobotSpec, ServoSpec, load_robot
    from .sim.rollout import FallCriteria, Simulator, Trace
    from .sim.surfaces import SURFACES, Surface, load_surface
except KeyboardInterrupt:
    # Ctrl-C while the command line's libraries load (a second or two): one line and 130, as any
    # interrupt of `gait-tuner`; imported as a library, the interrupt goes on as it came
    if _os.path.basename(_sys.argv[0] if _sys.argv else "") != "gait-tuner":
        raise
    _sys.stderr.write("gait-tuner: interrupted\n")
    raise SystemExit(130) from None

__all__ = [
    "DEFINITIONS",
    "FallCriteria",
    "Metrics",
    "Randomisation",
    "RobotModel",
    "RobotSpec",
    "SURFACES",
    "ServoSpec",
    "Simulator",
    "Surface",
    "Trace",
    "UserError",
    "load_robot",
    "load_surface",
    "resolve_params",
    "summarize",
]
