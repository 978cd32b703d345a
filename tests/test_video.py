"""Seeing the walk: `render` writes a real video (read back: frames and size), `--save-scene` writes
a model that any MuJoCo loop walks exactly as our simulator did, `view` without a display is one
line."""


import mujoco
import numpy as np
import pytest

import gaits
from tuner.report.video import frame_ticks, video_info
from tuner.robots import load_robot
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES
from conftest import run_cli


def test_frame_ticks_play_in_real_time():
    ticks = frame_ticks(101, 0.01, 30)          # 1 s of 10 ms ticks at 30 fps
    assert len(ticks) == 31 and ticks[0] == 0 and ticks[-1] == 100
    assert ticks[15] == 50                       # frame 15 is t = 0.5 s
    assert frame_ticks(1, 0.01, 30) == [0]


def test_render_writes_the_expected_video(gait_tuner_cmd, run_env, tmp_path):
    out = tmp_path / "walk.mp4"
    r = run_cli(gait_tuner_cmd, ["render", "--params", "tkux-table2", "--surface", "grass50",
                                         "--duration", "1.5", "--size", "320x240", "--fps", "20",
                                         "--out", str(out)], run_env)
    assert r.returncode == 0, r.stderr
    info = video_info(out)
    # 1.5 s at 20 fps: 31 frames of the walk, then the last one held for 1 s (20 frames)
    assert (info["frames"], info["width"], info["height"]) == (31 + 20, 320, 240)
    assert "51 frames, 320x240, 20 fps" in r.stdout


@pytest.mark.slow   # the MP4 writer is tested by render's test above; this films two whole walks at 640x480
def test_compare_video_films_every_set_on_every_surface(gait_tuner_cmd, run_env, tmp_path):
    r = run_cli(gait_tuner_cmd, ["compare", "tkux-table2", "--no-baselines", "--surfaces", "rigid,carpet4",
                                         "--random-rollouts", "0", "--workers", "1", "--video",
                                         "--out", str(tmp_path)], run_env)
    assert r.returncode == 0, r.stderr
    videos = sorted((tmp_path / "videos").glob("*.mp4"))
    assert [v.name for v in videos] == ["tkux-table2--carpet4.mp4", "tkux-table2--rigid.mp4"]
    for v in videos:
        info = video_info(v)
        assert info["frames"] > 30 and (info["width"], info["height"]) == (640, 480)
    assert "wrote 2 videos" in r.stdout


@pytest.mark.parametrize("args, words", [
    (["--size", "300x240"], "multiple of 16"),
    (["--size", "big"], "WIDTHxHEIGHT"),
    (["--fps", "0"], "fps"),
])
def test_render_bad_options_are_one_line(gait_tuner_cmd, run_env, tmp_path, args, words):
    r = run_cli(gait_tuner_cmd, ["render", "--params", "tkux-table2", "--out", str(tmp_path / "w.mp4")]
                       + args, run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and words in r.stderr


def test_view_without_a_display_is_one_line(gait_tuner_cmd, run_env):
    env = {k: v for k, v in run_env.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    r = run_cli(gait_tuner_cmd, ["view", "--params", "tkux-table2"], env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "display" in r.stderr


@pytest.mark.parametrize("surface", ["rigid", "carpet4"])
def test_saved_scene_walks_as_the_simulator(gait_tuner_cmd, run_env, tmp_path, surface):
    scene = tmp_path / "scene.xml"
    r = run_cli(gait_tuner_cmd, ["simulate", "--params", "tkux-table2", "--surface", surface,
                                 "--duration", "2", "--save-scene", str(scene)], run_env)
    assert r.returncode == 0, r.stderr
    robot = load_robot("kidsize")
    sim = Simulator(robot, SURFACES[surface])
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, sim.control_period)
    trace = sim.rollout(traj, duration=2.0, record_qpos=True)
    # a plain MuJoCo loop on the saved file, fed the commands the servos received
    m = mujoco.MjModel.from_xml_path(str(scene))
    assert (m.nq, m.nu, m.opt.timestep) == (sim.model.nq, sim.model.nu, sim.model.opt.timestep)
    d = mujoco.MjData(m)
    d.qpos[:] = trace.qpos[0]
    d.ctrl[:] = sim.data.ctrl                          # held joints' targets (arms, head)
    mujoco.mj_forward(m, d)
    servo = trace.q_sent * sim._sign + sim._offset      # back to the robot's signs
    for k in range(1, len(trace.t)):
        d.ctrl[:sim._n_servo] = servo[k]
        mujoco.mj_step(m, d, nstep=sim.nstep)
    assert np.max(np.abs(d.qpos - trace.qpos[-1])) < 1e-6
