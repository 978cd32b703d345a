"""The loop a team runs on its robot, as a script: ``python examples/robot_loop.py GAIT.yaml --dry-run``.

The loop itself is ``gaits/robot/loop.py`` (the robot-side package, ``robot/pyproject.toml``, installs it
as the command ``gait-tuner-loop``); this file runs it from a checkout."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gaits.robot.loop import main  # noqa: E402

if __name__ == "__main__":
    main()
