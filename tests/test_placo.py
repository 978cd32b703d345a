"""placo's walk as a controller (tuner/placo_walk.py, the placo extra): its file checked in one
line; the frames placo needs added to a URDF that lacks them; where placo is installed, a walk on
a URDF robot through the adapter (slow)."""

from __future__ import annotations

import json

import pytest
import yaml

import third_party_robot as T
from tuner.controllers import load_controller
from tuner.errors import UserError
from tuner.placo_walk import PLACO_DEFAULTS, _with_frames

from conftest import run_cli


def test_a_placo_file_is_read_and_checked(tmp_path):
    path = tmp_path / "placo.yaml"
    path.write_text(yaml.safe_dump({"placo": {"walk_com_height": 0.25, "feet_spacing": 0.1},
                                    "ranges": {"walk_com_height": {"low": 0.2, "high": 0.3}}}))
    user = load_controller(path)
    assert user.params == {**PLACO_DEFAULTS, "walk_com_height": 0.25, "feet_spacing": 0.1}
    assert user.ranges == {"walk_com_height": (0.2, 0.3)}
    assert user.limits.tick == 30.0                 # placo reads the URDF when built: seconds, not 1 s
    for doc, needle in (({"placo": {"walk_height": 0.2}}, "placo: unknown parameter 'walk_height'"),
                        ({"placo": {"walk_com_height": -1}}, "placo.walk_com_height = -1: expected a finite number"),
                        ({"placo": {"replan_period": 0}}, "placo.replan_period = 0: expected a positive number"),
                        ({"placo": {}, "ranges": {"feet_spacing": {"low": 0.2, "high": 0.3}}},
                         "params.feet_spacing = 0.122 lies outside its range"),
                        ({"placo": {}, "extra": 1}, "unknown key 'extra' in a placo file")):
        path.write_text(yaml.safe_dump(doc))
        with pytest.raises(UserError, match=needle):
            load_controller(path)


def test_the_frames_placo_needs_are_added_where_a_urdf_has_none(tmp_path):
    from tuner.robots import load_robot
    (tmp_path / "robot.urdf").write_text(T.urdf(T.mjcf()))
    (tmp_path / "map.yaml").write_text(T.map_yaml(mjcf_name="robot.urdf").replace("mjcf:", "urdf:"))
    robot = load_robot(str(tmp_path / "map.yaml"))
    text = _with_frames((tmp_path / "robot.urdf").read_text(), robot)
    for name, parent in (("trunk", robot.torso), ("left_foot", robot.feet[0]), ("right_foot", robot.feet[1])):
        assert f'<link name="{name}"/>' in text and f'<parent link="{parent}"/>' in text
    assert _with_frames(text, robot) == text            # present: left as they are
    import xml.etree.ElementTree as ET
    ET.fromstring(text)                                  # still a well-formed URDF


def test_a_team_urdf_s_packages_and_turned_feet_are_given_to_placo_as_they_are(tmp_path):
    """placo reads the URDF itself: its package:// meshes become the folders our loader found (a
    team's file failed in placo: 'Mesh package://... could not be found'), and the sole frames
    it needs take the soles' own axes where a foot body is turned (Wolfgang-OP's by 90 deg)."""
    import numpy as np
    import xml.etree.ElementTree as ET
    from types import SimpleNamespace
    from tuner.placo_walk import _rpy
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])     # a foot body turned 90 deg about z
    tilt = np.array([[np.cos(0.26), 0.0, np.sin(0.26)], [0.0, 1.0, 0.0], [-np.sin(0.26), 0.0, np.cos(0.26)]])
    robot = SimpleNamespace(torso="torso", feet=("l_foot", "r_foot"), soles=((0.0, 0.0, -0.03), (0.01, 0.0, -0.03)),
                            sole_axes=(R, R @ tilt), package_dirs={"team_description": "/opt/team/desc"})
    text = ('<robot name="t"><link name="torso"><visual><geometry><mesh filename="package://team_description/'
            'meshes/a.stl"/></geometry></visual></link><link name="l_foot"/><link name="r_foot"/></robot>')
    out = _with_frames(text, robot)
    assert 'filename="/opt/team/desc/meshes/a.stl"' in out and "package://" not in out
    joints = {j.find("child").get("link"): j.find("origin") for j in ET.fromstring(out).iter("joint")}
    for side, name in ((0, "left_foot"), (1, "right_foot")):
        r, p, y = (float(v) for v in joints[name].get("rpy").split())
        Rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
        Ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
        Rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
        np.testing.assert_allclose(Rz @ Ry @ Rx, robot.sole_axes[side].T, atol=1e-10)    # 12 digits written
    assert _rpy(np.eye(3)) == (0.0, 0.0, 0.0)


@pytest.mark.slow
def test_placo_walks_a_urdf_robot_through_the_adapter(tmp_path, gait_tuner_cmd, run_env):
    pytest.importorskip("placo", reason="placo's walk needs the placo extra (pip install 'gait-tuner[placo]')")
    (tmp_path / "robot.urdf").write_text(T.urdf(T.mjcf(kp=60.0)))
    (tmp_path / "map.yaml").write_text(T.map_yaml(mjcf_name="robot.urdf").replace("mjcf:", "urdf:")
                                       + "servo:\n  legs: {kp: 60}\n")
    (tmp_path / "placo.yaml").write_text(yaml.safe_dump({"placo": {"walk_com_height": 0.2, "feet_spacing": 0.09,
                                                                   "walk_foot_height": 0.03,
                                                                   "walk_max_dx_forward": 0.05,
                                                                   "walk_trunk_pitch": 0.05}}))
    r = run_cli(gait_tuner_cmd, ['simulate', '--robot', str(tmp_path / 'map.yaml'), '--controller',
                                 str(tmp_path / 'placo.yaml'), '--surface', 'rigid', '--command', '0.1,0,0',
                                 '--duration', '8', '--json'], run_env, timeout=600)
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)["metrics"]
    # untuned for this robot it shuffles (0.05 m in 8 s, measured): it stands and steps through the adapter
    assert m["outcome"] == "completed" and m["distance_m"] > 0.02, m
