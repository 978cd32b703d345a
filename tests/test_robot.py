"""Built-in robot numbers, and bringing your own MJCF with a joint map."""


import numpy as np
import pytest

import gaits
from gaits import JOINT_NAMES
from tuner.errors import UserError
from tuner.sim.metrics import summarize
from tuner.robots import RobotSpec, kidsize_xml, load_robot
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES

from conftest import run_cli


def test_builtin_robot_matches_its_sources():
    spec = RobotSpec()
    assert spec.total_mass == pytest.approx(4.95)     # TKU-X Table 1
    assert spec.height == pytest.approx(0.52)         # EROS
    robot = load_robot("kidsize")
    assert len(robot.joint_map) == 20                 # EROS Table 1
    sim = Simulator(robot, SURFACES["rigid"])
    assert sum(sim.model.body_mass) == pytest.approx(4.95)
    assert sim.model.nu == 20
    assert np.all(sim.model.actuator_forcerange[:, 1] <= 6.0)


def byo_files(tmp_path, joint_map_text=None, flip_knee=True):
    """The built-in robot saved as a user MJCF with other joint names (and a flipped knee)."""
    xml = kidsize_xml()
    for name in JOINT_NAMES:
        xml = xml.replace(f'joint name="{name}"', f'joint name="J_{name}"')
    if flip_knee:
        xml = xml.replace('joint name="J_l_knee" axis="0 1 0" range="0 2.6"',
                          'joint name="J_l_knee" axis="0 -1 0" range="-2.6 0"')
    xml = xml.replace("<worldbody>", '<worldbody>\n    <geom name="floor" type="plane" size="1 1 0.1"/>')
    (tmp_path / "robot.xml").write_text(xml)
    if joint_map_text is None:
        joint_map_text = "\n".join(f"  {n}: J_{n}" for n in JOINT_NAMES)
    (tmp_path / "map.yaml").write_text(
        f"mjcf: robot.xml\ntorso: torso\nfeet: {{left: l_foot, right: r_foot}}\njoints:\n{joint_map_text}\n")
    return tmp_path / "map.yaml"


def test_bring_your_own_robot_walks_like_the_builtin(tmp_path):
    robot = load_robot(str(byo_files(tmp_path)))
    builtin = load_robot("kidsize")
    assert robot.joint_map["l_knee"] == ("J_l_knee", -1)     # sign found from the axis
    assert robot.joint_map["r_knee"] == ("J_r_knee", 1)
    for f in ("hip_offset_y", "hip_offset_z", "thigh", "shank", "ankle_height", "com_above_pelvis"):
        assert getattr(robot.leg, f) == pytest.approx(getattr(builtin.leg, f), abs=1e-9)
    assert robot.foot_size == pytest.approx(builtin.foot_size)
    out = []
    for r in (robot, builtin):
        sim = Simulator(r, SURFACES["rigid"])
        traj = gaits.generate(gaits.load_baseline("tkux-table2").params, builtin.leg, sim.control_period)
        out.append(summarize(sim.rollout(traj, duration=4.0)))
    assert out[0].pitch_rms_deg == pytest.approx(out[1].pitch_rms_deg, abs=1e-6)
    assert out[0].distance_m == pytest.approx(out[1].distance_m, abs=1e-6)


@pytest.mark.parametrize("edit,match", [
    (lambda m: m.replace("  l_knee: J_l_knee\n", ""), "leg joints missing from the map: l_knee"),
    (lambda m: m.replace("l_knee: J_l_knee", "l_knee: J_l_kne"), "joints.l_knee: 'J_l_kne' is not a joint"),
    (lambda m: m.replace("l_knee: J_l_knee", "l_knee: TMP").replace("l_hip_roll: J_l_hip_roll", "l_hip_roll: J_l_knee")
     .replace("l_knee: TMP", "l_knee: J_l_hip_roll"),
     r"joints.l_hip_roll and joints.l_hip_pitch look swapped"),
    (lambda m: m.replace("l_knee: J_l_knee", "l_knee: {name: J_l_knee, sign: 1}"),
     "joints.l_knee.sign = 1 contradicts the axis of 'J_l_knee'"),
    (lambda m: m.replace("r_knee: J_r_knee", "r_knee: J_l_knee"), "mapped twice: J_l_knee"),
    (lambda m: m + "  l_toe: J_l_knee\n", "unknown joint 'l_toe'"),
])
def test_bad_maps_name_the_problem(tmp_path, edit, match):
    base = "\n".join(f"  {n}: J_{n}" for n in JOINT_NAMES) + "\n"
    path = byo_files(tmp_path, edit(base).rstrip("\n"))
    with pytest.raises(UserError, match=match):
        load_robot(str(path))


def test_bad_map_files(tmp_path):
    path = byo_files(tmp_path)
    text = path.read_text()
    path.write_text(text.replace("torso: torso", "torso: pelvis"))
    with pytest.raises(UserError, match="torso body 'pelvis' not in robot.xml"):
        load_robot(str(path))
    path.write_text(text.replace("mjcf: robot.xml", "mjcf: nothing.xml"))
    with pytest.raises(UserError, match="mjcf: .*nothing.xml: no such MJCF file"):
        load_robot(str(path))
    path.write_text(text + "wheels: 4\n")
    with pytest.raises(UserError, match="unknown key 'wheels'"):
        load_robot(str(path))
    with pytest.raises(UserError, match="not a built-in robot"):
        load_robot(str(tmp_path / "missing.yaml"))


def test_cli_bad_robot_map_exits_2(gait_tuner_cmd, run_env, tmp_path):
    base = "\n".join(f"  {n}: J_{n}" for n in JOINT_NAMES if n != "r_ankle_roll")
    path = byo_files(tmp_path, base)
    r = run_cli(gait_tuner_cmd, ['simulate', '--robot', str(path), '--gait', 'tlipfm'], run_env, timeout=120)
    assert r.returncode == 2
    assert "leg joints missing from the map: r_ankle_roll" in r.stderr
    assert r.stderr.strip().count("\n") == 0
