"""Simulated walks recorded as a robot's are (``--record DIR`` of simulate, robustness, challenge).

One adapter between the simulator's runs and ``gaits/robot/recorder.py``: the controller a run drives is
wrapped so that every tick it was given and every target it returned are written to an MCAP file
in the HumanoidDataset layout (what the controller saw, not the simulator's ground truth), with the
metadata naming the robot, the surface, the controller and its parameters, and the run (task,
randomisation seed, push). A run that stops (a fall, an error, Ctrl-C) keeps what it recorded:
the file is closed whatever ends the walk.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

__all__ = ["recording", "recording_stem"]


def recording_stem(drive: Any) -> str:
    """A file-name stem for a drive's recordings: its set's or controller's name, safe characters only."""
    name = Path(getattr(drive, "source", None) or getattr(drive, "family", None) or "walk").stem
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


@contextmanager
def recording(controller: Any, sim: Any, drive: Any, path: Path | None, task: str,
              notes: str = "") -> Iterator[Any]:
    """``controller`` recorded into ``path`` for the block (``path`` None: the controller as it is)."""
    if path is None:
        yield controller
        return
    from gaits.robot.recorder import Recorder, RecordingController, RecordingMeta
    params = getattr(drive, "params", None)
    # the measured joints are the simulator's servo joints (a robot without arms measures fewer than 20);
    # the targets, what the controller asks: our 20 roles and the robot's extra joints
    meta = RecordingMeta(robot=sim.robot.name, task=task, simulated=True, joints=list(sim.joint_names),
                         target_joints=list(sim.target_names),
                         controller=drive.describe(),
                         parameters={} if params is None else params.to_mapping(), surface=sim.surface.name,
                         notes=notes)
    recorder = Recorder(path, meta)
    try:
        yield RecordingController(controller, recorder)
    except BaseException:
        recorder.close(whole=False)       # an older recording of the name stays; the partial one beside it
        raise
    recorder.close()
