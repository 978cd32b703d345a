"""Walking live in MuJoCo's viewer: the physics runs as you watch, the keyboard steers the walk,
the mouse pushes the robot (MuJoCo's own perturbation: double-click a body, then Ctrl + right drag).

For a set that walks online (the walk engine, a controller of your own). Keys (GLFW codes):
up / down arrow: forward speed +- 0.05 m/s; left / right arrow: turning +- 0.2 rad/s;
Z / X: sideways +- 0.03 m/s; space: stop (zero command). The command is clipped to the engine's
envelope by the engine itself.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["KeyboardCommand", "live_walk", "KEYS"]

#: GLFW key code -> (axis, change)
KEYS = {265: (0, 0.05), 264: (0, -0.05), 263: (2, 0.2), 262: (2, -0.2), 90: (1, 0.03), 88: (1, -0.03)}
SPACE = 32


class KeyboardCommand:
    """The walk command steered from the keyboard; the loop reads it every tick (``at``)."""

    def __init__(self) -> None:
        self.command = np.zeros(3)

    def key(self, keycode: int) -> None:
        if keycode == SPACE:
            self.command = np.zeros(3)
        elif keycode in KEYS:
            axis, change = KEYS[keycode]
            self.command[axis] = round(self.command[axis] + change, 6)

    def at(self, t: float) -> np.ndarray:
        return self.command


def live_walk(sim, controller, viewer, keyboard: KeyboardCommand, *, realtime: bool = True,
              limit_s: float = 3600.0, clock=time.perf_counter, sleep=time.sleep):
    """Walk ``controller`` on ``sim`` while ``viewer`` (MuJoCo's passive viewer, or any object with
    ``is_running()`` and ``sync()``) shows it, paced to real time; ends when the window closes,
    the robot falls, or after ``limit_s``. Returns the trace."""
    start = clock()
    dt = sim.control_period

    def tick(k: int, data) -> bool:
        if not viewer.is_running():
            return False
        viewer.sync()
        if realtime:
            ahead = (k + 1) * dt - (clock() - start)
            if ahead > 0:
                sleep(ahead)
        return True
    return sim.run(controller, commands=keyboard, duration=limit_s, on_tick=tick)
