"""Bring your own robot: third-party-style MJCFs load unedited, are checked, and walk as the file says."""

import json
import math

import mujoco
import numpy as np
import pytest

import gaits
import third_party_robot as T
from tuner.errors import UserError
from tuner.sim.metrics import summarize
from tuner.robots import load_robot
from tuner.servos import preset
from tuner.sim.scene import PREFIX
from tuner.robots.mjcf_geometry import axis_line_distance
from tuner.report.robot_check import robot_report
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES
from conftest import run_cli


def test_axis_line_distance_hand_checked():
    # x axis through (0, 0, 0) and y axis through (5, 0, 3): closest points (5, 0, 0) and (5, 0, 3)
    d, mid = axis_line_distance([0, 0, 0], [1, 0, 0], [5, 7, 3], [0, 1, 0])
    assert d == pytest.approx(3.0)
    assert mid == pytest.approx([5, 0, 1.5])
    # parallel lines 4 apart
    d, _ = axis_line_distance([0, 0, 0], [0, 1, 0], [1, 9, 0], [0, -2, 0])
    assert d == pytest.approx(1.0)
    # the anchors of intersecting lines can lie anywhere on them: 30.7 mm apart, lines meet
    d, mid = axis_line_distance([-0.024, 0.035, -0.0285], [-1, 0, 0], [0.0001, 0.054, -0.0285], [0, 1, 0])
    assert d == pytest.approx(0.0, abs=1e-12)
    assert mid == pytest.approx([0.0001, 0.035, -0.0285])


@pytest.fixture(scope="module", params=["two_box", "capsule", "cleats"])
def robot(request, tmp_path_factory):
    path = T.write(tmp_path_factory.mktemp(request.param), T.mjcf(feet=request.param))
    return request.param, load_robot(str(path))


def test_geometry_derived_from_axis_lines_and_all_foot_geoms(robot):
    feet, r = robot
    L = r.leg
    assert L.hip_offset_y == pytest.approx(0.035, abs=1e-9)
    assert L.hip_offset_z == pytest.approx(0.0285, abs=1e-9)
    assert L.thigh == pytest.approx(0.11015, abs=1e-9)
    assert L.shank == pytest.approx(0.110, abs=1e-9)
    if feet == "two_box":       # two boxes: x -39.5..87.5 mm, y -26.5..51.5 mm (left), bottom 30.5 mm below the ankle
        assert r.foot_size == pytest.approx((0.127, 0.078), abs=1e-9)
        assert L.ankle_height == pytest.approx(0.0305, abs=1e-9)
        assert L.sole_outward == pytest.approx(0.0125, abs=1e-9)
        assert len(r.sole_hulls[0]) == 8
        assert L.sole_forward == pytest.approx(-0.0001, abs=1e-9)
    elif feet == "cleats":  # spheres on four welded bodies at x -30..80 mm, y -20..40 mm, in a turned foot frame
        assert r.foot_size == pytest.approx((0.110, 0.060), abs=1e-6)
        assert L.ankle_height == pytest.approx(0.0305, abs=1e-9)
        assert L.sole_outward == pytest.approx(0.010, abs=1e-6)
        assert r.soles[0] == pytest.approx((0.025, -0.0305, -0.010), abs=1e-9)   # the foot frame's y is up
        assert len(r.touch_bodies(0)) == 4
    else:   # two capsules (r 10 mm) along x -35..80 mm at y 38 and -16 mm: they touch along their bottom lines
        assert r.foot_size == pytest.approx((0.115, 0.054), abs=1e-6)
        assert L.ankle_height == pytest.approx(0.0325, abs=1e-9)
        assert L.sole_outward == pytest.approx(0.011, abs=1e-6)
        assert L.sole_forward == pytest.approx(0.0225 - 0.0241, abs=1e-6)
    # mirrored right leg: signs found from the axes
    assert r.joint_map["l_hip_pitch"] == ("HipPitch_L", 1) and r.joint_map["r_hip_pitch"] == ("HipPitch_R", -1)
    assert r.joint_map["l_ankle_pitch"][1] == -1 and r.joint_map["r_ankle_pitch"][1] == 1
    assert r.joint_map["l_hip_yaw"][1] == -1 and r.joint_map["l_hip_roll"][1] == -1


def test_com_offset_matches_an_independent_computation(robot):
    _, r = robot
    m = mujoco.MjModel.from_xml_path(r.mjcf_path)
    d = mujoco.MjData(m)
    from tuner.robots.mjcf_geometry import crouch_angles
    for name, value in crouch_angles(r.leg, r.joint_map).items():
        d.qpos[m.jnt_qposadr[m.joint(name).id]] = value
    mujoco.mj_forward(m, d)
    com = np.sum(d.xipos[1:] * m.body_mass[1:, None], axis=0) / m.body_mass[1:].sum()
    torso = m.body("body_link").id
    assert r.leg.com_forward == pytest.approx(com[0] - d.xpos[torso, 0], abs=1e-9)
    assert r.leg.com_forward < -0.004           # the torso's CoM sits behind the hips


def test_servos_from_the_file_and_held_pose_from_its_keyframe(robot):
    _, r = robot
    knee = r.servo_of("l_knee")
    assert (knee.kp, knee.torque, knee.armature, knee.damping) == pytest.approx((21.1, 5.0, 0.045, 1.084))
    assert knee.speed == pytest.approx(6.5)                   # no speed in a file: the MX-64 preset's
    assert r.pose["ShoRoll_L"] == pytest.approx(1.25) and r.pose["ShoRoll_R"] == pytest.approx(-1.25)
    assert "actuators" in r.sources["servos.legs"] and "preset MX-64" in r.sources["servos.legs"]


def test_what_we_add_is_namespaced_and_free_of_the_files_defaults(robot):
    _, r = robot
    sim = Simulator(r, SURFACES["grass50"])
    m = sim.model
    ours = [a for a in range(m.nu) if m.actuator(a).name.startswith(PREFIX)]
    assert len(ours) == m.nu                                     # the file's actuators are replaced
    for a in ours:
        name = m.actuator(a).name
        if "/drag/" in name:                                     # not the file's ctrlrange -3.14..3.14
            assert list(m.actuator_ctrlrange[a]) == [0.0, 1.0]
            assert not m.actuator_forcelimited[a]                # the file's forcerange would cap the drag
        else:
            assert not m.actuator_ctrllimited[a]
    assert m.geom("gt/soil").margin == 0.0                       # the file's <geom margin> does not leak
    assert m.geom("gt/layer").margin == pytest.approx(SURFACES["grass50"].layer_height)
    assert m.site("imu").id != m.site("gt/imu").id               # the file's own imu site stays its own
    assert m.nkey == 1 and m.key_ctrl.shape == (1, m.nu)         # keyframe ctrl rebuilt for our servos


def test_legs_only_map_holds_the_other_joints(tmp_path):
    path = T.write(tmp_path, yaml_text=T.map_yaml(T.joint_map(legs_only=True)))
    r = load_robot(str(path))
    assert len(r.held_joints) == 8
    for surface in ("rigid", "carpet4"):                        # the 20-value keyframe used to crash these
        sim = Simulator(r, SURFACES[surface])
        trace = sim.rollout(gaits.generate(gaits.load_baseline("tkux-table2").params, r.leg, sim.control_period),
                            duration=3.0)
        assert not trace.fell
        q = sim.data.qpos[sim.model.jnt_qposadr[sim.model.joint("ShoRoll_L").id]]
        assert q == pytest.approx(1.25, abs=0.05)               # held, not swinging


@pytest.mark.parametrize("surface", ["rigid", "grass50"])
def test_tlipfm_baseline_walks_on_the_third_party_robot(robot, surface):
    _, r = robot
    sim = Simulator(r, SURFACES[surface])
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, r.leg, sim.control_period)
    trace = sim.rollout(traj)
    assert not trace.fell, trace.reason
    # the CoM starts over the feet: the gait planned the CoM, not the torso origin
    feet_x = (trace.p_sole_l[0, 0] + trace.p_sole_r[0, 0]) / 2
    assert abs(trace.p_com[0, 0] - feet_x) < 0.002
    assert summarize(trace).distance_m > 0.0


def test_robot_check_stand_test_sees_the_whole_weight(robot):
    feet, r = robot
    rep = robot_report(r)
    json.dumps(rep, allow_nan=False)
    assert rep["stand"]["stays_up"]
    assert rep["stand"]["sensed_weight_fraction"] == pytest.approx(1.0, abs=0.02)
    assert rep["mass_kg"] == pytest.approx(3.158 + (0.04 if feet == "cleats" else 0.0), abs=0.01)
    assert rep["servos"]["legs"]["kp"] == pytest.approx(21.1)


def test_map_servo_overrides_and_presets(tmp_path):
    path = T.write(tmp_path, yaml_text=T.map_yaml(extra="servo:\n  legs: {speed: 5.0}\n  arms: MX-106\n"
                                                        "sim: {control_period: 0.02, max_tilt_deg: 40}\n"))
    r = load_robot(str(path))
    assert r.servo_of("l_knee").kp == pytest.approx(21.1) and r.servo_of("l_knee").speed == 5.0
    assert r.servo_of("l_elbow") == preset("MX-106")            # a preset is the law its name gives, as it is
    assert r.servo_of("l_elbow").torque == pytest.approx(10.67, abs=0.01)
    sim = Simulator(r, SURFACES["rigid"])
    assert sim.control_period == 0.02 and sim.nstep == 10
    assert sim.fall.max_tilt == pytest.approx(math.radians(40))


def _run(cmd, args, env, cwd=None):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env, cwd=cwd)


def _swap_lr(jmap, kinds):
    out = dict(jmap)
    for k in kinds:
        out[f"l_{k}"], out[f"r_{k}"] = jmap[f"r_{k}"], jmap[f"l_{k}"]
    return out


BAD_MAPS = [
    ("left/right joints", lambda: T.map_yaml(_swap_lr(T.joint_map(), T.LEG)),
     "joints.l_hip_yaw: 'HipYaw_R' is on the right leg (the chain to 'foot_r'): left and right swapped?"),
    ("left/right knees only", lambda: T.map_yaml(_swap_lr(T.joint_map(), ["knee"])),
     "joints.l_knee: 'Knee_R' is on the right leg"),
    ("feet swapped", lambda: T.map_yaml(feet=("foot_r", "foot_l")),
     "feet.left: body 'foot_r' lies at y = -"),
    ("knee and hip pitch", lambda: T.map_yaml({**T.joint_map(), "l_knee": "HipPitch_L", "l_hip_pitch": "Knee_L"}),
     "joints.l_hip_pitch and joints.l_knee look swapped"),
    ("negative kp", lambda: T.map_yaml(extra="servo:\n  legs: {kp: -3}\n"),
     "servo.legs.kp = -3 N m/rad is out of range (0, 1000] N m/rad"),
    ("nan torque", lambda: T.map_yaml(extra="servo:\n  legs: {torque: .nan}\n"),
     "servo.legs.torque = nan N m is out of range (0, 200] N m"),
    ("string speed", lambda: T.map_yaml(extra="servo:\n  arms: {speed: fast}\n"),
     "servo.arms.speed = 'fast': expected a number"),
    ("unknown servo field", lambda: T.map_yaml(extra="servo:\n  legs: {gain: 3}\n"),
     "servo.legs: unknown field 'gain' (allowed for the pd law: preset, law, kp, kv, torque, speed, armature, damping, "
     "frictionloss, backlash, latency)"),
    ("unknown preset", lambda: T.map_yaml(extra="servo:\n  legs: MX-9000\n"),
     "servo.legs.preset = 'MX-9000': unknown (did you mean 'MX-106'?) (allowed: MX-64, MX-106, XL-320, XL-330, STS3215, "
     "MX-28, XM430-W350, XH540-W270, XM540-W270, MX-28-pd, MX-64-pd, MX-106-pd, XM430-W350-pd)"),
    ("unknown servo group", lambda: T.map_yaml(extra="servo:\n  wheels: MX-64\n"),
     "servo: unknown group 'wheels' (allowed: legs, arms, head, other, hips, knees, ankles, or one of the map's joints by our name)"),
    ("unknown leg field", lambda: T.map_yaml(extra="leg:\n  thigh_length: 0.1\n"),
     "leg: unknown field 'thigh_length' (allowed: hip_offset_y, hip_offset_z, thigh, shank"),
    ("pose out of range", lambda: T.map_yaml(extra="pose:\n  Elbow_L: 4.0\n"),
     "pose.Elbow_L = 4.0 rad is out of the joint's range [-2.5, 2.5] rad"),
    ("pose of a leg joint", lambda: T.map_yaml(extra="pose:\n  Knee_L: 0.3\n"),
     "pose: 'Knee_L' is not a non-leg hinge joint"),
    ("bad sim field", lambda: T.map_yaml(extra="sim:\n  timestep: 0.003\n"),
     "sim.control_period = 0.01 s must be a whole multiple of sim.timestep = 0.003 s"),
    ("sign contradicts", lambda: T.map_yaml({**T.joint_map(), "r_knee": {"name": "Knee_R", "sign": 1}}),
     "joints.r_knee.sign = 1 contradicts the axis of 'Knee_R'"),
]


@pytest.mark.parametrize("case,make,message", BAD_MAPS, ids=[c[0] for c in BAD_MAPS])
def test_wrong_maps_are_one_line_exit_2(gait_tuner_cmd, run_env, tmp_path, case, make, message):
    text = make()
    if "{'name'" in text:
        text = text.replace("{'name': 'Knee_R', 'sign': 1}", "{name: Knee_R, sign: 1}")
    path = T.write(tmp_path, yaml_text=text)
    r = _run(gait_tuner_cmd, ["robot", "check", str(path), "--no-stand"], run_env)
    assert r.returncode == 2, r.stdout + r.stderr
    assert r.stderr.count("\n") == 1, r.stderr
    assert message in r.stderr


def test_robot_check_cli_reports_what_it_derived(gait_tuner_cmd, run_env, tmp_path):
    path = T.write(tmp_path)
    r = _run(gait_tuner_cmd, ["robot", "check", str(path)], run_env)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "hip offset y 35.0 mm, hip below torso origin 28.5 mm, thigh 110.2 mm, shank 110.0 mm" in out
    assert "127 x 78 mm" in out and "hull of 2 collision geom(s)" in out
    assert "kp 21.1 N m/rad" in out and "the file's actuators on 12 joint(s)" in out
    assert "ShoRoll_L +1.250" in out and "keyframe 'stand'" in out
    assert "stand test (rigid floor, 2.0 s, walking crouch): stays up" in out
    r = _run(gait_tuner_cmd, ["robot", "check", str(path), "--json", "--no-stand"], run_env)
    doc = json.loads(r.stdout)
    assert doc["leg_mm"]["thigh"] == pytest.approx(110.15) and "stand" not in doc


def test_study_robot_resolves_against_the_study_file_and_fails_early(gait_tuner_cmd, run_env, tmp_path):
    T.write(tmp_path / "team", subdir="model")            # team/map.yaml -> team/model/robot.xml
    study = tmp_path / "team" / "study.yaml"
    study.write_text("gait: tlipfm\nrobot: map.yaml\nsurfaces: [rigid]\ntrials: 2\nduration: 2.0\n"
                     "base: tkux-table2\nspace:\n  t1: {low: 0.12, high: 0.18}\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    r = _run(gait_tuner_cmd, ["tune", str(study), "--runs", str(tmp_path / "runs")], run_env, cwd=elsewhere)
    assert r.returncode == 0, r.stderr
    r = _run(gait_tuner_cmd, ["export", str(study), "--runs", str(tmp_path / "runs"),
                              "--out", str(tmp_path / "best.yaml")], run_env, cwd=elsewhere)
    assert r.returncode == 0, r.stderr
    table = (tmp_path / "best.joints.csv").read_text().splitlines()
    assert table[0].startswith("# gait-tuner joint table for robot map (robot joint names and signs")
    assert "study study trial" in table[0]
    assert "HipPitch_L[rad]" in table[1] and "l_hip_pitch[rad]" not in table[1]
    # a wrong robot in a study: one line, exit 2, before any worker starts
    study.write_text(study.read_text().replace("robot: map.yaml", "robot: nomap.yaml"))
    r = _run(gait_tuner_cmd, ["tune", str(study), "--workers", "2", "--runs", str(tmp_path / "runs2")], run_env)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "robot: robot" in r.stderr and "nomap.yaml" in r.stderr


def _table(path):
    """Columns of a joint table CSV by name (unit suffix dropped), after its comment line."""
    lines = path.read_text().splitlines()
    assert lines[0].startswith("# ")
    header = [h.split("[")[0] for h in lines[1].split(",")]
    data = np.array([[float(v) for v in row.split(",")] for row in lines[2:]])
    return {h: data[:, k] for k, h in enumerate(header)}


def test_exported_joint_table_in_the_robots_signs(gait_tuner_cmd, run_env, tmp_path):
    path = T.write(tmp_path, yaml_text=T.map_yaml(T.joint_map(legs_only=True)))
    out = tmp_path / "tab"
    r = _run(gait_tuner_cmd, ["trajectory", "--gait", "tlipfm", "--robot", str(path), "--out", str(out),
                              "--no-plot"], run_env)
    assert r.returncode == 0, r.stderr
    theirs = _table(out / "joints.csv")
    r = _run(gait_tuner_cmd, ["trajectory", "--gait", "tlipfm", "--robot", str(path), "--out", str(tmp_path / "o"),
                              "--no-plot", "--joint-names", "ours"], run_env)
    ours = _table(tmp_path / "o" / "joints.csv")
    assert np.allclose(theirs["HipPitch_R"], -ours["r_hip_pitch"])        # the file's mirrored axis
    assert np.allclose(theirs["Knee_L"], ours["l_knee"])
    assert np.allclose(theirs["ShoRoll_L"], 1.25)                          # a held joint, constant
    # the IK used this robot's legs, not the built-in's
    builtin = gaits.generate(gaits.load_baseline("tkux-table2").params).joint("l_knee")
    assert np.max(np.abs(ours["l_knee"] - builtin)) > 0.01


def test_compare_uses_the_studys_robot_and_names_it(gait_tuner_cmd, run_env, tmp_path):
    T.write(tmp_path)
    study = tmp_path / "study.yaml"
    study.write_text("gait: tlipfm\nrobot: map.yaml\nsurfaces: [rigid]\ntrials: 1\nduration: 2.0\n"
                     "base: tkux-table2\nspace:\n  t1: {low: 0.12, high: 0.18}\n")
    r = _run(gait_tuner_cmd, ["tune", str(study), "--runs", str(tmp_path / "runs")], run_env)
    assert r.returncode == 0, r.stderr
    r = _run(gait_tuner_cmd, ["compare", "tkux-table2", "--study", str(study), "--surfaces", "rigid",
                              "--no-baselines", "--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "cmp"),
                              "--workers", "1"], run_env)
    assert r.returncode == 0, r.stderr
    md = (tmp_path / "cmp" / "compare.md").read_text()
    assert md.startswith("Robot map (") and "study study" in md.splitlines()[0]


def test_bad_map_inputs_in_process(tmp_path):
    path = T.write(tmp_path)
    (tmp_path / "bin.yaml").write_bytes(b"\x00\x01binary")
    with pytest.raises(UserError, match="is a binary file"):
        load_robot(str(tmp_path / "bin.yaml"))
    (tmp_path / "latin.yaml").write_bytes("mjcf: caf\xe9.xml\n".encode("latin-1"))
    with pytest.raises(UserError, match="is not UTF-8 text"):
        load_robot(str(tmp_path / "latin.yaml"))
    with pytest.raises(UserError, match="is a directory"):
        load_robot(str(tmp_path))
    path.write_text(T.map_yaml().replace("torso: body_link", "torso: shank_l"))
    with pytest.raises(UserError, match="must carry the model's free joint"):
        load_robot(str(path))


def test_shipped_example_robot_checks_and_stands(gait_tuner_cmd, run_env):
    from conftest import ROOT
    r = _run(gait_tuner_cmd, ["robot", "check", str(ROOT / "examples" / "robots" / "kid3kg" / "kid3kg.yaml"),
                              "--json"], run_env)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["robot"] == "kid3kg" and doc["stand"]["stays_up"]
    assert "speed from the map" in doc["sources"]["servos.legs"]


def test_a_robot_whose_hips_turn_in_another_order_gets_the_numerical_ik_composed_so(tmp_path):
    """A hip built pitch, roll, yaw from the torso loads (before, it was refused): robot check
    says so, and the legs' chains, composed in that order, put the soles where MuJoCo's own
    kinematics of the file does at random joint angles (1e-9 m)."""
    xml = T.mjcf()
    for side in "LR":                      # hip pitch joint in the first hip body, hip yaw in the thigh
        yaw = next(line for line in xml.splitlines() if f'name="HipYaw_{side}"' in line).strip()
        pitch = next(line for line in xml.splitlines() if f'name="HipPitch_{side}"' in line).strip()
        xml = xml.replace(yaw, "@@").replace(pitch, yaw).replace("@@", pitch)
    path = T.write(tmp_path, xml)
    robot = load_robot(str(path))
    chains = robot.leg.chains
    LEG = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
    assert chains is not None and robot.leg.ik == "numerical"
    assert "the leg turns hip pitch, hip roll, hip yaw, knee, ankle pitch, ankle roll going from the torso" \
        in chains.reason, chains.reason
    assert chains.left.order == (2, 1, 0, 3, 4, 5) == chains.right.order
    m = mujoco.MjModel.from_xml_string(robot.xml)
    d, d0 = mujoco.MjData(m), mujoco.MjData(m)
    tb = m.body(robot.torso).id
    mujoco.mj_kinematics(m, d0)
    R_t0 = d0.xmat[tb].reshape(3, 3)
    rng = np.random.default_rng(2)
    for _ in range(20):
        q = {p + k: rng.uniform(-0.3, 0.3) for p in ("l_", "r_") for k in LEG}
        d.qpos[:] = m.qpos0
        for ours, (theirs, sign) in robot.joint_map.items():
            if ours in q:
                d.qpos[m.jnt_qposadr[m.joint(theirs).id]] = sign * q[ours]
        mujoco.mj_kinematics(m, d)
        R_t, p_t = d.xmat[tb].reshape(3, 3), d.xpos[tb]
        for p, chain, foot in (("l_", chains.left, robot.feet[0]), ("r_", chains.right, robot.feet[1])):
            f = m.body(foot).id
            p_sole, R_sole = chain.fk(np.array([q[p + k] for k in LEG]))
            p0, R0 = chain.fk(np.zeros(6))
            # the sole point rides on the foot body: its place in the foot frame does not move
            R_f, p_f = R_t.T @ d.xmat[f].reshape(3, 3), R_t.T @ (d.xpos[f] - p_t)
            R_f0, p_f0 = R_t0.T @ d0.xmat[f].reshape(3, 3), R_t0.T @ (d0.xpos[f] - d0.xpos[tb])
            np.testing.assert_allclose(p_sole, p_f + R_f @ (R_f0.T @ (p0 - p_f0)), atol=1e-9)
            np.testing.assert_allclose(R_sole @ R0.T, R_f @ R_f0.T, atol=1e-9)


def test_a_torso_whose_origin_lies_at_its_feet_is_judged_by_its_centre_of_mass(tmp_path):
    """A torso frame at the floor (an Onshape export's base: Berkeley Humanoid Lite's lies 478 mm
    below its hips) said nothing of a fall: the first tick's sag put it under 60 % of its start
    height. The same robot with its torso frame moved 0.4 m down (its bodies where they were) now
    stands and walks as the robot does, and a fall is still one."""
    xml = T.mjcf()
    low = (xml.replace('<body name="body_link" pos="0 0 0.3">', '<body name="body_link" pos="0 0 -0.1">')
              .replace('<inertial pos="-0.015 0.0001 0.066"', '<inertial pos="-0.015 0.0001 0.466"')
              .replace("      <freejoint/>\n", '      <freejoint/>\n      <frame pos="0 0 0.4">\n')
              .replace("    </body>\n  </worldbody>", "      </frame>\n    </body>\n  </worldbody>"))
    assert low.count("<frame pos") == 1 and low.count("</frame>") == 1 and "0.466" in low
    walks = []
    for name, text in (("robot", xml), ("low", low)):
        path = T.write(tmp_path / name, text)
        robot = load_robot(str(path))
        sim = Simulator(robot, SURFACES["rigid"])
        traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, sim.control_period)
        walks.append(summarize(sim.rollout(traj, duration=4.0)))
        assert (robot.leg.hip_offset_z < 0) == (name == "low")
    assert walks[0].outcome == walks[1].outcome == "completed"
    assert walks[1].distance_m > 0.7 * walks[0].distance_m > 0.05
    # knocked over by a shove, it still falls
    path = T.write(tmp_path / "low2", low)
    robot = load_robot(str(path))
    sim = Simulator(robot, SURFACES["rigid"])
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, sim.control_period)
    from gaits.control import TablePlayer
    fallen = summarize(sim.run(TablePlayer(traj), duration=4.0, pushes=[(1.0, (0.0, 6.0, 0.0))]))
    assert fallen.outcome == "fell"


def test_a_map_extends_another_group_by_group(tmp_path):
    """extends: the other map's keys under this one's, paths from where each map is, servo: merged
    group by group and field by field (a preset name kept under new fields); a cycle or a missing
    map is one line."""
    import pytest as _pytest
    import third_party_robot as T
    from tuner.errors import UserError
    from tuner.robots import load_robot
    base = T.write(tmp_path / "team", T.mjcf(), T.map_yaml(extra="servo:\n  legs: {preset: MX-64, p_gain: 20}\n"
                                                                 "  arms: MX-28\n"))
    (tmp_path / "study").mkdir()
    child = tmp_path / "study" / "robot.yaml"
    child.write_text("extends: ../team/map.yaml\nservo:\n  legs: {p_gain: 40}\n  arms: {voltage: 12}\n")
    robot, team = load_robot(str(child)), load_robot(str(base))
    knee, team_knee = (r.servos[r.joint_map["l_knee"][0]] for r in (robot, team))
    assert knee.p_gain == 40 and team_knee.p_gain == 20 and knee.voltage == team_knee.voltage
    elbow = robot.servos[robot.joint_map["l_elbow"][0]]
    assert elbow.voltage == 12 and robot.name == team.name and robot.leg == team.leg
    (tmp_path / "study" / "loop.yaml").write_text("extends: loop.yaml\n")
    with _pytest.raises(UserError, match="more than 8 maps deep"):
        load_robot(str(tmp_path / "study" / "loop.yaml"))
    (tmp_path / "study" / "xml.yaml").write_text("extends: ../team/robot.xml\n")
    with _pytest.raises(UserError, match=r"xml.yaml: extends: .*robot.xml"):
        load_robot(str(tmp_path / "study" / "xml.yaml"))
    (tmp_path / "study" / "gone.yaml").write_text("extends: nowhere.yaml\n")
    with _pytest.raises(UserError, match="extends: .*nowhere.yaml is not a file"):
        load_robot(str(tmp_path / "study" / "gone.yaml"))
