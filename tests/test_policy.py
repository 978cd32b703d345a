"""Learned walk policies as controllers (gaits/policy.py, a controller file's ``policy:`` section):
a small ONNX policy built here with onnx's helper runs through the spec, its observation vector
tick by tick the one built by hand; a wrong spec is one line, exit 2."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import gaits
from gaits.control import Measurement
from gaits.params import ParamError
from gaits.trajectory import JOINT_NAMES
from gaits.policy import PolicyController, gravity_in_body, policy_from_mapping

from conftest import run_cli

onnx = pytest.importorskip("onnx", reason="onnx (the dev extra) builds the test's policy")
pytest.importorskip("onnxruntime", reason="onnxruntime (the onnx extra) runs policies")

LEGS = [f"{s}_{k}" for s in "lr" for k in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")]


def mlp(n_in: int, n_out: int, seed: int = 0, gain: float = 1.0):
    """Weights of a two-layer tanh MLP, and its numpy reference."""
    rng = np.random.default_rng(seed)
    W1 = rng.normal(0, 1 / math.sqrt(n_in), (n_in, 16)).astype(np.float32)
    b1 = rng.normal(0, 0.1, 16).astype(np.float32)
    W2 = (gain * rng.normal(0, 0.25, (16, n_out))).astype(np.float32)
    b2 = np.zeros(n_out, dtype=np.float32)

    def ref(x: np.ndarray) -> np.ndarray:
        h = np.tanh(x.astype(np.float32) @ W1 + b1)
        return h @ W2 + b2
    return (W1, b1, W2, b2), ref


def write_onnx(path: Path, n_in: int, n_out: int, seed: int = 0, gain: float = 1.0, batched: bool = True):
    from onnx import TensorProto, helper, numpy_helper
    (W1, b1, W2, b2), ref = mlp(n_in, n_out, seed, gain)
    shape_in, shape_out = ([1, n_in], [1, n_out]) if batched else ([n_in], [n_out])
    nodes = [helper.make_node("MatMul", ["obs", "W1"], ["h0"]), helper.make_node("Add", ["h0", "b1"], ["h1"]),
             helper.make_node("Tanh", ["h1"], ["h2"]), helper.make_node("MatMul", ["h2", "W2"], ["a0"]),
             helper.make_node("Add", ["a0", "b2"], ["action"])]
    graph = helper.make_graph(nodes, "walk", [helper.make_tensor_value_info("obs", TensorProto.FLOAT, shape_in)],
                              [helper.make_tensor_value_info("action", TensorProto.FLOAT, shape_out)],
                              [numpy_helper.from_array(a, n) for a, n in ((W1, "W1"), (b1, "b1"), (W2, "W2"), (b2, "b2"))])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    path.write_bytes(model.SerializeToString())
    return ref


def crouch() -> dict[str, float]:
    leg = gaits.LegGeometry()
    out = {}
    for side, s in ((1, "l"), (-1, "r")):
        q = gaits.leg_ik(leg.hip_in_pelvis(side) + np.array([0.0, 0.0, -0.85 * leg.max_hip_height]), 0.0, leg, side)
        for name, v in zip(("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll"), q):
            out[f"{s}_{name}"] = round(float(v), 6)
    return out


def spec_doc(model: str = "walk.onnx", **over) -> dict:
    doc = {"model": model, "period": 0.02, "joints": list(LEGS), "default_pose": crouch(),
           "observation": [{"term": "gyro", "scale": 0.25}, {"term": "gravity"},
                           {"term": "command", "scale": [2.0, 2.0, 0.25]},
                           {"term": "joint_pos", "clip": 1.0}, {"term": "joint_vel", "scale": 0.05},
                           {"term": "last_action"}, {"term": "phase", "period": 0.6},
                           {"term": "imu_rpy", "offset": [0.0, 0.05, 0.0]}],
           "action": {"scale": 0.25, "clip": 2.0},
           "commands": {"vx": [-0.1, 0.2], "vy": [-0.1, 0.1], "wz": [-0.5, 0.5]}}
    doc.update(over)
    return doc


N_OBS = 3 + 3 + 3 + 12 + 12 + 12 + 2 + 3


def test_the_observation_and_the_targets_tick_by_tick_against_a_hand_built_one(tmp_path):
    from gaits.policy import onnx_runner
    ref = write_onnx(tmp_path / "walk.onnx", N_OBS, 12, seed=1, gain=4.0)
    spec = policy_from_mapping(spec_doc(), "policy.yaml")
    run, n_in, n_out = onnx_runner(tmp_path / "walk.onnx")
    assert (n_in, n_out) == (N_OBS, 12)
    ctl = PolicyController(spec, run, None, 0.01, (n_in, n_out))
    q0 = ctl.start_pose().q
    default = np.array([crouch().get(j, 0.0) for j in gaits.JOINT_NAMES])
    np.testing.assert_array_equal(q0, default)
    rng = np.random.default_rng(7)
    last = np.zeros(12)
    target = default.copy()
    idx = [gaits.JOINT_NAMES.index(j) for j in LEGS]
    for k in range(12):
        t = 0.01 * k
        m = Measurement(t, q=default + rng.normal(0, 0.3, 20), dq=rng.normal(0, 5, 20),
                        imu_rpy=rng.normal(0, 0.2, 3), gyro=rng.normal(0, 1, 3))
        command = np.array([0.5, -0.05, 0.3])                 # vx beyond the envelope: clipped to 0.2
        out = ctl.step(m, command)
        if k % 2 == 0:                                        # the policy's period is two ticks
            r, p = m.imu_rpy[0], m.imu_rpy[1]
            grav = np.array([math.sin(p), -math.sin(r) * math.cos(p), -math.cos(r) * math.cos(p)])
            by_hand = np.concatenate([
                m.gyro * 0.25, grav, np.array([0.2, -0.05, 0.3]) * np.array([2.0, 2.0, 0.25]),
                np.clip((m.q - default)[idx], -1.0, 1.0), m.dq[idx] * 0.05, last,
                [math.sin(2 * math.pi * t / 0.6), math.cos(2 * math.pi * t / 0.6)],
                m.imu_rpy - np.array([0.0, 0.05, 0.0])])
            np.testing.assert_allclose(ctl.last_observation, by_hand, atol=1e-12)
            np.testing.assert_allclose(ctl.last_action, np.clip(ref(by_hand).reshape(-1), -2.0, 2.0), atol=1e-5)
            last = ctl.last_action.copy()                     # onnxruntime's float32, carried exactly
            target = default.copy()
            target[idx] += 0.25 * last
        np.testing.assert_allclose(out, target, atol=1e-12)
    assert ctl.calls == 6
    np.testing.assert_allclose(gravity_in_body(np.array([0.0, 0.0, 1.0])), [0.0, 0.0, -1.0], atol=1e-15)


def test_the_two_feet_phase_of_playgrounds_bipeds(tmp_path):
    """mujoco_playground's biped joysticks observe [cos pL, cos pR, sin pL, sin pR], the feet half a
    cycle apart (pL = 0 at the start): the term gives exactly that, after the terms before it."""
    from gaits.policy import onnx_runner
    doc = spec_doc(observation=[{"term": "gyro"}, {"term": "feet_phase", "period": 0.667}])
    write_onnx(tmp_path / "walk.onnx", 3 + 4, 12)
    spec = policy_from_mapping(doc, "policy.yaml")
    run, n_in, n_out = onnx_runner(tmp_path / "walk.onnx")
    ctl = PolicyController(spec, run, None, 0.01, (n_in, n_out))
    ctl.start_pose()
    for t, pl in ((0.0, 0.0), (0.02, 2 * math.pi * 0.02 / 0.667), (0.5, 2 * math.pi * 0.5 / 0.667)):
        m = Measurement(t, q=np.zeros(20), dq=np.zeros(20), imu_rpy=np.zeros(3), gyro=np.array([0.1, 0.2, 0.3]))
        obs = ctl.observe(m, None)
        pr = pl + math.pi
        np.testing.assert_allclose(obs, [0.1, 0.2, 0.3, math.cos(pl), math.cos(pr), math.sin(pl), math.sin(pr)],
                                   atol=1e-12)
    with pytest.raises(ParamError, match=r"feet_phase\)\.period = None"):
        policy_from_mapping(spec_doc(observation=[{"term": "feet_phase"}]), "policy.yaml")


@pytest.mark.parametrize("edit, needle", [
    (lambda d: d["observation"].append({"term": "gyro"}), "the observation has 53 numbers (gyro 3, gravity 3, command 3, "
                                                           "joint_pos 12, joint_vel 12, last_action 12, phase 2, imu_rpy 3, "
                                                           "gyro 3) but the model takes 50"),
    (lambda d: d["observation"].append({"term": "foot_contact"}), "unknown term 'foot_contact'"),
    (lambda d: d["joints"].__setitem__(0, "l_wrist"), "policy.joints: 'l_wrist' is not a joint of robot kidsize"),
    (lambda d: d["observation"][0].__setitem__("scale", [1.0, 2.0]), "policy.observation[0] (gyro).scale has 2 numbers"),
    (lambda d: d.__setitem__("period", 0.015), "policy.period = 0.015 s is not a whole number of the loop's 0.01 s ticks"),
    (lambda d: d["joints"].pop(), "the observation has 47 numbers"),
])
def test_a_wrong_spec_is_one_line_exit_2(tmp_path, gait_tuner_cmd, run_env, edit, needle):
    import yaml
    write_onnx(tmp_path / "walk.onnx", N_OBS, 12)
    doc = spec_doc()
    edit(doc)
    (tmp_path / "policy.yaml").write_text(yaml.safe_dump({"policy": doc}))
    r = run_cli(gait_tuner_cmd, ['simulate', '--controller', str(tmp_path / 'policy.yaml'), '--surface', 'rigid',
                                 '--duration', '1'], run_env, timeout=300)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert needle in lines[0], lines[0]


def test_a_joint_the_robot_lacks_and_gains_it_was_not_trained_with_are_named(tmp_path):
    import yaml
    import third_party_robot as T
    from gaits.policy import PolicyFactory, check_robot
    from tuner.robots import load_robot
    legs_only = load_robot(str(T.write(tmp_path, T.mjcf(), T.map_yaml(T.joint_map(legs_only=True)))))
    spec = policy_from_mapping(spec_doc(joints=LEGS + ["l_elbow"]), "policy.yaml")
    with pytest.raises(ParamError, match=r"policy.yaml: policy.joints: 'l_elbow' is not a joint of robot"):
        check_robot(spec, legs_only, "policy.yaml")
    spec = policy_from_mapping(spec_doc(gains={"kp": 80.0}), "policy.yaml")
    with pytest.raises(ParamError, match=r"trained with l_hip_yaw's servo at kp 80 N m/rad .* is at kp 21.1: give its "
                                         r"map servo: \{l_hip_yaw: \{kp: 80\}\}"):
        check_robot(spec, legs_only, "policy.yaml")
    check_robot(policy_from_mapping(spec_doc(gains={"kp": 20.0}), "p"), legs_only, "p")     # within 25 %
    # joint by joint: one knee trained on other servos is named, whatever the others' median
    kps = [20.0] * len(LEGS)
    kps[LEGS.index("r_knee")] = 60.0
    with pytest.raises(ParamError, match=r"trained with r_knee's servo at kp 60 N m/rad"):
        check_robot(policy_from_mapping(spec_doc(gains={"kp": kps}), "p"), legs_only, "p")
    # kd: the servo's derivative gain
    kv = legs_only.servo_of("l_knee").pieces().kv
    check_robot(policy_from_mapping(spec_doc(gains={"kp": 20.0, "kd": kv}), "p"), legs_only, "p")
    with pytest.raises(ParamError, match=r"trained with l_hip_yaw's servo at kd 3 N m s/rad"):
        check_robot(policy_from_mapping(spec_doc(gains={"kp": 20.0, "kd": 3.0}), "p"), legs_only, "p")
    # a servo law without a derivative gain (the built-in robot's dc motors) is said so, not given a kv
    kidsize = load_robot("kidsize")
    with pytest.raises(ParamError, match=r"its servo law \(dc-motor\) has no kv: give its map a servo that has"):
        check_robot(policy_from_mapping(spec_doc(gains={"kp": kidsize.servo_of("l_knee").pieces().kp, "kd": 2.0}),
                                        "p"), kidsize, "p")
    with pytest.raises(ParamError, match=r"policy.gains.kp has 3 numbers: expected 1 or 12"):
        policy_from_mapping(spec_doc(gains={"kp": [1.0, 2.0, 3.0]}), "p")
    assert isinstance(PolicyFactory(spec, "walk.onnx", "p"), PolicyFactory)
    assert yaml is not None


def test_a_policy_walks_like_any_set_and_a_study_tunes_what_its_spec_exposes(tmp_path, gait_tuner_cmd, run_env):
    """A policy whose output is nearly zero stands in its default crouch through simulate, robustness
    and the challenge's first trial; its params are the spec's tunables."""
    import yaml
    from tuner.controllers import load_controller
    write_onnx(tmp_path / "walk.onnx", N_OBS, 12, gain=0.01)
    (tmp_path / "policy.yaml").write_text(yaml.safe_dump({
        "policy": spec_doc(), "params": {"action_scale": 0.2},
        "ranges": {"action_scale": {"low": 0.1, "high": 0.3}, "vx_max": {"low": 0.1, "high": 0.4}}}))
    user = load_controller(tmp_path / "policy.yaml")
    assert user.params == {"action_scale": 0.2, "vx_min": -0.1, "vx_max": 0.2, "vy_max": 0.1, "wz_max": 0.5}
    assert set(user.ranges) == {"action_scale", "vx_max"}
    r = run_cli(gait_tuner_cmd, ['simulate', '--controller', str(tmp_path / 'policy.yaml'), '--surface', 'grass30',
                                 '--command', '0.1,0,0', '--duration', '3', '--json'], run_env, timeout=600)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["metrics"]["outcome"] == "completed"
    # its file states no gains: said, once, that it runs on these servos unchecked
    assert r.stderr.count("the policy states no servo gains (policy.gains): it runs on this robot's servos as they "
                          "are, unchecked") == 1, r.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"policy": spec_doc(), "params": {"kp": 3.0}}))
    with pytest.raises(Exception, match=r"params.kp: not tunable"):
        load_controller(bad)


def test_the_berkeley_humanoid_lite_example_states_its_policys_layout():
    """examples/robots/berkeley-humanoid-lite: the policy file says the public 50 Hz walk's layout
    (45 numbers in, 12 out: its config's num_observations and num_actions), in the order its Isaac
    Lab task builds them, its hip yaw's sign turned as the map's axis says, and the gains it was
    trained with are the ones the map gives its servos (the robot and the ONNX model are not
    shipped: docs/controllers.md says how to fetch them)."""
    import yaml
    from conftest import ROOT
    from gaits.policy import policy_from_mapping
    from tuner.robots.robot_map import MAP_KEYS
    here = ROOT / "examples" / "robots" / "berkeley-humanoid-lite"
    spec = policy_from_mapping(yaml.safe_load((here / "policy-biped-50hz.yaml").read_text())["policy"], "p")
    assert spec.observation_size == 45 and len(spec.joints) == 12 and spec.period == 0.02
    assert [t.term for t in spec.observation] == ["command", "gyro", "gravity", "joint_pos", "joint_vel",
                                                   "last_action"]
    flips = [j for j, s in zip(spec.joints, spec.observation[3].scale) if s < 0]
    assert flips == ["l_hip_yaw", "r_hip_yaw"]
    assert [j for j, s in zip(spec.joints, spec.action_scale) if s < 0] == flips
    for name in ("bhl-biped.yaml", "bhl-biped-engine.yaml"):
        doc = yaml.safe_load((here / name).read_text())
        assert set(doc) <= set(MAP_KEYS)
    policy_map = yaml.safe_load((here / "bhl-biped.yaml").read_text())
    assert spec.gains == {"kp": policy_map["servo"]["legs"]["kp"], "kd": policy_map["servo"]["legs"]["kv"]}
    # the engine's set for it (a study's trial, docs/controllers.md) reads as a set of the online engine
    from gaits.gait_file import load_gait_file
    engine = load_gait_file(here / "engine-grass30.yaml")
    assert engine.engine is not None and 0.3 < engine.params.period < 0.4


def test_the_wolfgang_example_states_its_policys_layout():
    """examples/robots/wolfgang: the policy file says Bit-Bots' published walk's layout (52 numbers
    in, 12 out: the exported model's), right leg first, each joint's sign the map's (the same in the
    joint angles, rates and actions), the knees' home less their 0.15 rad ref, the feet's phase at
    1.5 Hz, and the gains it was trained with are the map's servos' (the robot and the ONNX model are
    not shipped: docs/walk.md says how to fetch them)."""
    import yaml
    from conftest import ROOT
    from gaits.policy import policy_from_mapping
    here = ROOT / "examples" / "robots" / "wolfgang"
    spec = policy_from_mapping(yaml.safe_load((here / "policy-wolfgang.yaml").read_text())["policy"], "p")
    assert spec.observation_size == 52 and spec.period == 0.02
    assert [t.term for t in spec.observation] == ["base_velocity", "gyro", "gravity", "command", "joint_pos",
                                                   "joint_vel", "last_action", "feet_phase"]
    assert list(spec.joints[:6]) == ["r_hip_yaw", "r_hip_roll", "r_hip_pitch", "r_knee", "r_ankle_pitch", "r_ankle_roll"]
    signs = list(spec.observation[4].scale)
    assert signs == list(spec.observation[5].scale) == [2 * a for a in spec.action_scale]
    assert spec.default_pose["l_knee"] > 1.4 and spec.default_pose["r_knee"] > 1.4
    assert spec.observation[7].period == pytest.approx(1 / 1.5, abs=1e-3)
    legs = yaml.safe_load((here / "wolfgang.yaml").read_text())["servo"]["legs"]
    assert spec.gains["kp"] == legs["kp"]


def test_the_trunks_velocity_is_read_from_the_encoders_and_the_gyro():
    """base_velocity: with the lower sole standing still, the trunk's velocity in its own axes is what
    finite differences of its place in the world give (the trunk turning at the gyro's rate, the legs
    moving at the encoders' rates), from whichever foot is lower."""
    from gaits.engine.estimator import sole_in_pelvis
    from gaits.leg_kinematics import LegGeometry, rot_x, rot_y
    from gaits.policy import base_velocity
    leg = LegGeometry()
    rng = np.random.default_rng(7)
    L, R = slice(JOINT_NAMES.index("l_hip_yaw"), JOINT_NAMES.index("l_hip_yaw") + 6), \
        slice(JOINT_NAMES.index("r_hip_yaw"), JOINT_NAMES.index("r_hip_yaw") + 6)
    for stance, swing in ((L, R), (R, L)):
        q = np.zeros(len(JOINT_NAMES))
        q[stance] = [0.05, 0.03, -0.4, 0.8, -0.4, -0.03]
        q[swing] = [0.0, 0.0, -0.8, 1.4, -0.6, 0.0]          # lifted: its sole higher
        dq = rng.uniform(-1, 1, len(JOINT_NAMES))
        gyro = rng.uniform(-0.5, 0.5, 3)
        rpy = np.array([0.05, -0.08, 0.0])
        m = Measurement(0.0, q=q, dq=dq, gyro=gyro, imu_rpy=rpy)
        side = 1 if stance == L else -1

        def trunk_in_world(t):
            w = gyro * t
            angle = float(np.linalg.norm(w))
            K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / (angle or 1.0)
            turn = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
            Rw = rot_y(rpy[1]) @ rot_x(rpy[0]) @ turn
            return -Rw @ sole_in_pelvis(q[stance] + t * dq[stance], leg, side)[0]
        h = 1e-6
        expected = (rot_y(rpy[1]) @ rot_x(rpy[0])).T @ (trunk_in_world(h) - trunk_in_world(-h)) / (2 * h)
        np.testing.assert_allclose(base_velocity(m, leg), expected, atol=2e-4)


def test_the_trunks_velocity_needs_the_robots_legs():
    doc = spec_doc()
    doc["observation"] = [{"term": "base_velocity"}] + doc["observation"]
    spec = policy_from_mapping(doc, "p")
    with pytest.raises(ParamError, match="base_velocity needs the robot's legs"):
        PolicyController(spec, lambda o: np.zeros(len(spec.joints)), object(), 0.01)


def test_a_policy_file_runs_on_the_robot_loop_as_in_the_simulator(tmp_path, capsys):
    """``gait-tuner-loop POLICY.yaml``: the robot side runs a learned walk's policy file (its params
    in place, its model beside it), its targets tick by tick the ones the simulator's controller
    gives from the same readings; the loop imports neither the simulator nor the search; a policy
    file it cannot run is one line, exit 2."""
    import subprocess
    import sys

    import yaml

    from gaits.robot.loop import RobotGeometry, controller, load_walk, main
    from tuner.controllers import load_controller
    write_onnx(tmp_path / "walk.onnx", N_OBS, 12, seed=3, gain=2.0)
    path = tmp_path / "policy.yaml"
    path.write_text(yaml.safe_dump({"policy": spec_doc(), "params": {"action_scale": 0.2}}))
    assert main([str(path), "--dry-run", "--seconds", "1", "--record", str(tmp_path / "run.mcap")]) is None
    out = capsys.readouterr().out
    assert "100 ticks: 50 policy call(s)" in out and "recorded" in out
    geometry = RobotGeometry(gaits.LegGeometry(), (0.10, 0.055))
    on_robot, _ = controller(load_walk(str(path)), geometry, 0.01)
    in_sim = load_controller(path).build(geometry, 0.01)
    assert on_robot.spec.action_scale == 0.2
    rng = np.random.default_rng(5)
    n = len(JOINT_NAMES)
    for k in range(8):
        m = Measurement(0.01 * k, q=rng.normal(0, 0.1, n), dq=rng.normal(0, 0.5, n), imu_rpy=rng.normal(0, 0.05, 3),
                        gyro=rng.normal(0, 0.2, 3), accel=np.array([0.0, 0.0, 9.81]), foot_force=np.full(8, 6.0))
        got = on_robot.step(m, np.array([0.1, 0.0, 0.2]))
        assert got.tolist() == np.asarray(in_sim.step(m, np.array([0.1, 0.0, 0.2]))).tolist()
        moved = got - on_robot.default
        assert k > 0 or np.any(moved != 0)          # the policy acts (its params: scale 0.2)
    code = ("import runpy, sys\nsys.argv = ['robot_loop.py', %r, '--dry-run', '--seconds', '0.2']\n"
            "runpy.run_path(%r, run_name='__main__')\n"
            "print('imported:', sorted(m for m in ('mujoco', 'optuna', 'casadi', 'tuner') if m in sys.modules))"
            % (str(path), str(Path(__file__).resolve().parents[1] / "examples" / "robot_loop.py")))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "imported: []" in r.stdout, r.stdout + r.stderr
    for doc, words in (({"policy": spec_doc(), "params": {"gain": 2}}, "unknown parameter 'gain'"),
                       ({"policy": spec_doc(model="gone.onnx")}, "policy.model: no such file"),
                       ({"policy": spec_doc(), "extra": 1}, "unknown key 'extra' in a policy file")):
        path.write_text(yaml.safe_dump(doc))
        with pytest.raises(SystemExit) as stop:
            main([str(path), "--dry-run", "--seconds", "0.5"])
        err = capsys.readouterr().err.strip()
        assert stop.value.code == 2 and len(err.splitlines()) == 1 and words in err, err
