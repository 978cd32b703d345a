"""Seeing the walk: a video of a rollout, and the assembled scene as an MJCF file.

The video replays a rollout's recorded qpos (``Simulator.rollout(record_qpos=True)``) through
MuJoCo's offscreen renderer: the physics ran once, in the simulator; here only kinematics
(``mj_forward``) and drawing happen. A camera tracks the torso from the front-left; the grass
layer is drawn as a translucent slab as tall as its blades (``sim/scene.py``), so the
depth the feet sink to is visible. Each frame carries a text overlay: time, forward speed
(torso, over the last 0.5 s), torso pitch, and after a fall a red "FELL at t" banner held
for a second.

Headless backend: EGL (``MUJOCO_GL=egl``, set by ``tuner/__init__.py`` when there is no
display), which on a machine without a GPU is Mesa's llvmpipe software renderer (the
``libegl1`` / ``libgl1-mesa-dri`` packages of the distribution). The encoder is the ffmpeg
binary that the ``imageio-ffmpeg`` wheel ships (H.264, yuv420p: plays everywhere).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from gaits.files import write_text_atomic, make_folder

from ..errors import UserError
from ..sim.rollout import Simulator, Trace

__all__ = ["VideoOptions", "frame_ticks", "render_trace", "save_scene", "video_info"]


@dataclass(frozen=True)
class VideoOptions:
    """How a walk is filmed (pixels, frames per second, camera in degrees and metres)."""

    width: int = 640            # [px] a multiple of 16 (H.264 macro blocks)
    height: int = 480           # [px] a multiple of 16
    fps: int = 30               # [1/s]
    distance: float = 1.1       # [m] camera to torso
    azimuth: float = 135.0      # [deg] 90 looks along -y (from the robot's left), 180 from the front
    elevation: float = -15.0    # [deg]
    hold_end: float = 1.0       # [s] the last frame held (the fall moment stays visible)
    overlay: bool = True

    def __post_init__(self) -> None:
        for name, lo, hi in (("width", 64, 3840), ("height", 64, 2160)):
            v = getattr(self, name)
            if not lo <= v <= hi or v % 16:
                raise UserError(f"--size: {name} = {v} px: expected a multiple of 16 in [{lo}, {hi}]")
        if not 1 <= self.fps <= 120:
            raise UserError(f"--fps {self.fps}: expected 1..120 frames per second")


@functools.lru_cache(maxsize=4)
def _font(size: int):
    from PIL import ImageFont
    try:
        return ImageFont.load_default(size=size)
    except TypeError:                                   # Pillow < 10.1: fixed-size bitmap font
        return ImageFont.load_default()


def _overlay(frame: np.ndarray, lines: list[tuple[str, tuple[int, int, int]]]) -> np.ndarray:
    from PIL import Image, ImageDraw
    img = Image.fromarray(frame)
    draw = ImageDraw.Draw(img)
    font = _font(max(12, frame.shape[0] // 28))
    y = 6
    for text, colour in lines:
        box = draw.textbbox((8, y), text, font=font)
        draw.rectangle((box[0] - 4, box[1] - 2, box[2] + 4, box[3] + 2), fill=(0, 0, 0))
        draw.text((8, y), text, fill=colour, font=font)
        y = box[3] + 6
    return np.asarray(img)


def frame_ticks(n_ticks: int, dt: float, fps: int) -> list[int]:
    """The control tick shown in each frame, so the video plays in real time."""
    n_frames = int(math.floor((n_ticks - 1) * dt * fps + 1e-9)) + 1
    return [min(n_ticks - 1, int(round(i / (fps * dt)))) for i in range(n_frames)]


def render_trace(sim: Simulator, trace: Trace, out: Path, options: VideoOptions = VideoOptions(),
                 title: str = "", progress=None) -> dict:
    """Write ``trace`` (recorded with ``record_qpos=True``) as an MP4; returns frames, size, fps."""
    import imageio_ffmpeg

    if trace.qpos is None:
        raise ValueError("the trace has no qpos: roll out with record_qpos=True")
    out = Path(out)
    make_folder(out.parent)
    m = sim.model
    d = mujoco.MjData(m)
    try:
        renderer = mujoco.Renderer(m, options.height, options.width)
    except Exception as exc:  # noqa: BLE001 - no OpenGL at all: say which backend failed
        import os
        raise UserError(f"cannot open an OpenGL context for rendering (MUJOCO_GL="
                        f"{os.environ.get('MUJOCO_GL', 'default')}): {str(exc).splitlines()[0]}; "
                        f"headless machines need EGL (Mesa: libegl1 libgl1-mesa-dri)") from None
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    cam.trackbodyid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, sim.robot.torso)
    cam.distance, cam.azimuth, cam.elevation = options.distance, options.azimuth, options.elevation
    dt = sim.control_period
    ticks = frame_ticks(len(trace.t), dt, options.fps)
    hold = int(round(options.hold_end * options.fps))
    window = max(1, int(round(0.5 / dt)))
    writer = imageio_ffmpeg.write_frames(str(out), (options.width, options.height), fps=options.fps,
                                         codec="libx264", pix_fmt_out="yuv420p", quality=7,
                                         macro_block_size=16, ffmpeg_log_level="error")
    writer.send(None)
    n = 0
    frame = None
    try:
        for k in ticks + [ticks[-1]] * hold:
            if frame is None or n < len(ticks):
                d.qpos[:] = trace.qpos[k]
                mujoco.mj_forward(m, d)
                renderer.update_scene(d, camera=cam)
                frame = renderer.render()
                if options.overlay:
                    k0 = max(0, k - window)
                    speed = (trace.p_torso[k, 0] - trace.p_torso[k0, 0]) / max((k - k0) * dt, dt)
                    lines = [(title, (255, 255, 255))] if title else []
                    lines.append((f"t {trace.t[k]:5.2f} s   speed {speed:+.2f} m/s   "
                                  f"pitch {math.degrees(trace.pitch[k]):+5.1f} deg", (255, 255, 255)))
                    if trace.fell and trace.t_fall is not None and trace.t[k] >= trace.t_fall - dt / 2:
                        lines.append((f"FELL at {trace.t_fall:.2f} s", (255, 70, 70)))
                    elif n >= len(ticks) - 1:
                        lines.append((f"{trace.reason}", (120, 255, 120)))
                    frame = _overlay(frame, lines)
            writer.send(np.ascontiguousarray(frame))
            n += 1
            if progress is not None:
                progress(1)
    finally:
        writer.close()
        renderer.close()
    return {"frames": n, "width": options.width, "height": options.height, "fps": options.fps,
            "seconds": n / options.fps, "path": str(out)}


def video_info(path: Path) -> dict:
    """Frames and size of a video, read back with ffmpeg (for tests and the CLI's report)."""
    import imageio_ffmpeg
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    n = sum(1 for _ in gen)
    return {"frames": n, "width": meta["size"][0], "height": meta["size"][1], "fps": meta["fps"]}


def save_scene(sim: Simulator, out: Path) -> Path:
    """The assembled robot + surface model as one MJCF file, for any MuJoCo tool.

    It holds what the simulator compiles: the robot, our servos, touch sensors, the surface's
    soil and layer. The blade drag is not in it: the simulator applies it each tick (see
    ``sim/rollout.py``), so on grass a plain MuJoCo loop walks with less drag than we do.
    """
    out = Path(out)
    write_text_atomic(out, sim.spec.to_xml())
    return out
