"""A robot with joints beyond our 20 roles (a 22-joint robot: each arm with a shoulder yaw): its map
names them under ``extra_joints:``, the engines hold them at their pose, a policy drives them by that
name and reads their encoders, and the robot side (which drives the 20 roles) holds them."""

from __future__ import annotations

import numpy as np
import pytest

import gaits
import third_party_robot as T
from gaits.params import ParamError
from tuner.errors import UserError
from tuner.robots import load_robot
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES

EXTRA = "extra_joints:\n  l_shoulder_yaw: ShoulderYaw_L\n  r_shoulder_yaw: {name: ShoulderYaw_R, sign: -1}\n"


def robot_22(tmp_path, extra: str = EXTRA):
    return load_robot(str(T.write(tmp_path, T.mjcf(shoulder_yaw=True), T.map_yaml(extra=extra))))


def test_a_22_joint_map_loads_with_its_extra_joints_last(tmp_path):
    robot = robot_22(tmp_path)
    assert robot.extra_joints == ("l_shoulder_yaw", "r_shoulder_yaw")
    assert len(robot.servo_joints) == 22 and robot.servo_joints[-2:] == robot.extra_joints
    assert robot.joint_map["r_shoulder_yaw"] == ("ShoulderYaw_R", -1)
    assert "ShoulderYaw_L" not in robot.held_joints and "ShoulderYaw_L" in robot.servos
    # without extra_joints: the same file's shoulder yaws are held joints, as before
    plain = load_robot(str(T.write(tmp_path / "plain", T.mjcf(shoulder_yaw=True), T.map_yaml())))
    assert plain.extra_joints == () and {"ShoulderYaw_L", "ShoulderYaw_R"} <= set(plain.held_joints)


@pytest.mark.parametrize("extra, words", [
    ("extra_joints:\n  l_elbow: ShoulderYaw_L\n", "extra_joints.l_elbow: one of our 20 roles; map it under joints:"),
    ("extra_joints:\n  LShoulderYaw: ShoulderYaw_L\n", "a name of lower-case letters, digits and underscores"),
    ("extra_joints:\n  l_shoulder_yaw: ShoulderYaw_X\n", "'ShoulderYaw_X' is not a joint of robot.xml"),
    ("extra_joints:\n  l_shoulder_yaw: Elbow_L\n", "'Elbow_L' is mapped twice"),
    ("extra_joints: [ShoulderYaw_L]\n", "extra_joints must be a mapping"),
])
def test_a_bad_extra_joint_is_one_line_naming_it(tmp_path, extra, words):
    with pytest.raises(UserError, match=words.replace("(", r"\(").replace(")", r"\)")):
        robot_22(tmp_path, extra)


def test_an_unknown_joint_under_joints_points_at_extra_joints(tmp_path):
    text = T.map_yaml(jmap={**T.joint_map(), "l_shoulder_yaw": "ShoulderYaw_L"})
    with pytest.raises(UserError, match="a joint beyond them goes under extra_joints:"):
        load_robot(str(T.write(tmp_path, T.mjcf(shoulder_yaw=True), text)))


def test_an_engine_walk_holds_the_extra_joints_at_their_pose(tmp_path):
    robot = robot_22(tmp_path)
    sim = Simulator(robot, SURFACES["rigid"])
    assert sim.joint_names == robot.servo_joints and sim.target_names[20:] == robot.extra_joints
    trace = sim.rollout(gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, sim.control_period),
                        duration=1.0)
    extra = [sim.joint_names.index(j) for j in robot.extra_joints]
    assert trace.q.shape[1] == 22 and np.all(trace.q_cmd[:, extra] == 0.0)
    assert np.abs(trace.q[:, extra]).max() < 0.05                  # held where they stand
    # a controller may also give the extra joints' targets (22 numbers, the extras last)
    held = gaits.control.HoldPose(np.zeros(20), sim.control_period, 0.3)

    class WithArms:
        senses, dt, walk_start, duration = frozenset(), held.dt, 0.0, 0.3

        def start_pose(self):
            return held.start_pose()

        def reset(self, m):
            pass

        def step(self, m, command=None):
            return np.concatenate([held.step(m, command), [0.4, -0.3]])

        def plan(self, n):
            return held.plan(n)
    moved = sim.run(WithArms(), duration=0.3)
    assert np.allclose(moved.q_ref[-1, extra], [0.4, -0.3]) and moved.q[-1, extra[0]] > 0.2
    with pytest.raises(UserError, match=r"expected \(20,\), one per gaits.JOINT_NAMES \(or \(22,\): then the extra "
                                        r"joints l_shoulder_yaw, r_shoulder_yaw\)"):
        WithArms.step = lambda self, m, command=None: np.zeros(21)
        sim.run(WithArms(), duration=0.1)


def test_a_policy_drives_and_reads_the_extra_joints(tmp_path):
    pytest.importorskip("onnxruntime", reason="onnxruntime (the onnx extra) runs policies")
    from test_policy import LEGS, crouch, write_onnx

    from gaits.policy import PolicyController, PolicyFactory, policy_from_mapping
    robot = robot_22(tmp_path)
    joints = LEGS + ["l_shoulder_yaw", "r_shoulder_yaw"]
    n = len(joints)
    doc = {"model": "walk.onnx", "period": 0.02, "joints": joints,
           "default_pose": {**crouch(), "l_shoulder_yaw": 0.2},
           "observation": [{"term": "gravity"}, {"term": "joint_pos"}, {"term": "last_action"}],
           "action": {"scale": 0.25, "clip": 2.0}}
    write_onnx(tmp_path / "walk.onnx", 3 + 2 * n, n, seed=2, gain=2.0)
    spec = policy_from_mapping(doc, str(tmp_path / "policy.yaml"))
    factory = PolicyFactory(spec, str(tmp_path / "walk.onnx"), "policy.yaml")
    sim = Simulator(robot, SURFACES["rigid"])
    seen = []

    class Watched(PolicyController):
        def observe(self, m, command):
            obs = super().observe(m, command)
            seen.append((m.q[[m.joint_names.index(j) for j in robot.extra_joints]].copy(), obs))
            return obs
    c = factory({}, robot, sim.control_period)
    c.__class__ = Watched
    assert len(c.start_pose().q) == 22 and c.start_pose().q[20] == 0.2
    trace = sim.run(c, duration=0.5)
    extra = [sim.joint_names.index(j) for j in robot.extra_joints]
    # the extras' targets are the policy's: default + scale x action, every policy tick
    assert np.ptp(trace.q_ref[:, extra[1]]) > 0.0 and not np.allclose(trace.q_ref[:, extra[0]], 0.2)
    # its joint_pos term reads the extras' encoders (the last two of the term), minus their default
    q_extra, obs = seen[-1]
    assert np.allclose(obs[3 + n - 2:3 + n], q_extra - np.array([0.2, 0.0]))
    # a policy naming an extra joint the robot lacks: one line naming the robot's extra joints
    other = dict(doc, joints=LEGS + ["l_wrist"], default_pose=crouch())
    bad = PolicyFactory(policy_from_mapping(other, "policy.yaml"), str(tmp_path / "walk.onnx"), "policy.yaml")
    with pytest.raises(ParamError, match=r"'l_wrist' is not a joint of robot"):
        bad({}, robot, sim.control_period)
    with pytest.raises(ParamError, match=r"'l_wrist' is neither one of our 20 roles nor an extra joint of robot .* "
                                         r"\(its extra joints: l_shoulder_yaw, r_shoulder_yaw"):
        PolicyController(policy_from_mapping(other, "policy.yaml"), lambda x: np.zeros(n), robot,
                         sim.control_period)


def test_the_robot_side_holds_the_extra_joints(tmp_path):
    """The robot side's controllers drive the 20 roles: its robot file lists the extras as held, at
    their pose, and reads back."""
    from gaits.robot.robot_file import load_robot_file, save_robot_file
    robot = robot_22(tmp_path, EXTRA + "pose: {ShoulderYaw_L: 0.1}\n")
    rf = robot.robot_file()
    assert "l_shoulder_yaw" not in rf.joints and len(rf.joints) == 20
    assert rf.held["ShoulderYaw_L"] == pytest.approx(0.1)
    back = load_robot_file(save_robot_file(tmp_path / "robot-file.yaml", rf))
    assert back.held == pytest.approx(rf.held) and set(back.joints) == set(rf.joints)


def test_the_simulated_bus_reads_the_robots_encoders_by_our_roles_whatever_it_maps(tmp_path, monkeypatch):
    """A legs-only robot with two extra joints: the controller's reading has 14 encoders in the
    robot's order; the simulated bus answers each servo with its own joint's angle and rate (it took
    the 20 roles' order for the reading's and gave a hip the head's angle)."""
    import os
    import struct

    import tuner.sim.bus as bus
    from gaits.control import Measurement
    from gaits.robot.dynamixel import (ADDR_PRESENT_VELOCITY, SYNC_READ, VELOCITY_UNIT, instruction_packet,
                                       parse_packet)
    from gaits.robot.robot_file import from_units
    legs = T.joint_map(legs_only=True)
    ids = {theirs: i + 1 for i, theirs in enumerate(legs.values())}
    servos = "servos:\n  default: {ticks_per_turn: 4096, centre: 2048}\n" + \
        "".join(f"  {theirs}: {{id: {i}}}\n" for theirs, i in ids.items())
    text = T.map_yaml(jmap=legs, extra=EXTRA + "foot_sensors: false\n" + servos)
    robot = load_robot(str(T.write(tmp_path, T.mjcf(shoulder_yaw=True), text)))
    rf = robot.robot_file()
    names = robot.servo_joints
    assert len(names) == 14 and names[-2:] == robot.extra_joints
    q = np.linspace(-0.5, 0.6, len(names))
    dq = np.linspace(1.0, -1.2, len(names))
    master, slave, _ = bus.open_pty(1_000_000)
    sent = []
    try:
        bridge = bus.BusBridge(master, rf, 0.01, 1_000_000)
        monkeypatch.setattr(bridge, "_send", lambda k, data: sent.append(parse_packet(data)[0]))
        bridge.state.m = Measurement(0.0, q=q, dq=dq, joint_names=names)
        asked = sorted(ids.values())
        read = instruction_packet(0xFE, SYNC_READ, struct.pack("<HH", ADDR_PRESENT_VELOCITY, 8) + bytes(asked))
        bridge._answer(0, parse_packet(read)[0])
    finally:
        os.close(master)
        os.close(slave)
    assert [p.id for p in sent] == asked
    by_id = {ours: j.servo.id for ours, j in rf.joints.items()}
    for p in sent:
        ours = next(o for o, sid in by_id.items() if sid == p.id)
        j = rf.joints[ours]
        vel, pos = struct.unpack("<ii", p.params)
        k = names.index(ours)
        assert j.sign * float(from_units(pos, j.servo)) == pytest.approx(q[k], abs=2e-3)
        assert vel == round(j.sign * j.servo.direction * dq[k] / VELOCITY_UNIT)


def test_a_controller_of_ones_own_may_start_the_extra_joints_too(tmp_path):
    """A user's controller class on the 22-joint robot: a start pose of 22 angles (the extras last)
    is taken, and walks them there; 21 is one line naming the extra joints."""
    from gaits.drive import UserController
    robot = robot_22(tmp_path)
    sim = Simulator(robot, SURFACES["rigid"])

    class Arms:
        senses, walk_start, duration = frozenset(), 0.0, 0.3

        def __init__(self, params, robot, dt):
            self.dt, self.n = dt, params["n"]

        def start_pose(self):
            return gaits.control.StartPose(np.r_[np.zeros(20), [0.3, -0.2]][:int(self.n)])

        def reset(self, m):
            pass

        def step(self, m, command=None):
            return self.start_pose().q

        def plan(self, n):
            return gaits.control.HoldPose(np.zeros(20), self.dt).plan(n)
    ctl = UserController(Arms, {"n": 22.0}, "arms.py:Arms").build(robot, sim.control_period)
    trace = sim.run(ctl, duration=0.3)
    extra = [sim.joint_names.index(j) for j in robot.extra_joints]
    assert np.allclose(trace.q_ref[:, extra], [0.3, -0.2])
    short = UserController(Arms, {"n": 21.0}, "arms.py:Arms").build(robot, sim.control_period)
    with pytest.raises(ParamError, match=r"returned 21 angles: expected .* with 20 joint angles \(JOINT_NAMES\) "
                                         r"\(or 22: then the robot's extra joints l_shoulder_yaw, r_shoulder_yaw\)"):
        sim.run(short, duration=0.1)
