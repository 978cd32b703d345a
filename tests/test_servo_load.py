"""The servos' give under the stance load and their lag, put back into the engine's targets
(gaits/engine/servo_load.py): exact tests against finite differences and hand-worked cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaits.engine.servo_load import LoadCompensation, ServoTerms, servo_terms
from gaits.leg_chain import LegChains, _log_rotation
from gaits.leg_kinematics import LegGeometry
from gaits.trajectory import JOINT_NAMES
from test_leg_chain import bent_chain

LEFT = slice(JOINT_NAMES.index("l_hip_yaw"), JOINT_NAMES.index("l_hip_yaw") + 6)
RIGHT = slice(JOINT_NAMES.index("r_hip_yaw"), JOINT_NAMES.index("r_hip_yaw") + 6)


def terms(kp: float = 20.0, damping: float = 2.0, torque: float = 8.0) -> ServoTerms:
    n = len(JOINT_NAMES)
    return ServoTerms(np.full(n, kp), np.full(n, damping), np.full(n, torque))


def comp(leg=None, masses=(0.0, 0.0), load=1.0, lag=0.0, **kw) -> LoadCompensation:
    return LoadCompensation(leg or LegGeometry(), terms(**kw), 0.01, load, lag, masses)


def jacobian_fd(chain, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """The sole's 6 x 6 Jacobian (linear; angular in the pelvis frame) by central differences."""
    J = np.empty((6, 6))
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        (p1, R1), (p0, R0) = chain.fk(q + dq), chain.fk(q - dq)
        J[:3, i] = (p1 - p0) / (2 * h)
        J[3:, i] = _log_rotation(R1 @ R0.T) / (2 * h)
    return J


@pytest.mark.parametrize("which", ["ideal", "bent"])
def test_ground_torques_are_the_jacobian_transpose_of_the_wrench(which):
    """tau = J^T [f; m] for a vertical force at a point off the sole, J by finite differences of the
    chain's own kinematics, over random poses and pelvis tilts (the bent leg: a team's, its axes'
    points anywhere on their lines)."""
    leg = LegGeometry()
    if which == "bent":
        c = bent_chain()
        leg = LegGeometry(chains=LegChains(c, c))
    lc = comp(leg)
    chain = lc.chains[1]
    rng = np.random.default_rng(4)
    for _ in range(20):
        q = rng.uniform(-0.3, 0.3, 6) + np.array([0, 0, -0.4, 0.8, -0.4, 0])
        a, b = rng.uniform(-0.2, 0.2, 2)
        R_wp = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]]) @ \
            np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
        sole = rng.uniform(-0.1, 0.1, 3)
        cop = sole + np.array([*rng.uniform(-0.04, 0.04, 2), 0.0])
        F = 45.0
        f = R_wp.T @ np.array([0, 0, F])
        m = R_wp.T @ np.cross(cop - sole, np.array([0, 0, F]))
        expected = jacobian_fd(chain, q).T @ np.concatenate([f, m])
        np.testing.assert_allclose(lc.leg_torques(q, 1, F, cop, sole, R_wp), expected, atol=1e-6)


def test_a_straight_leg_under_its_hip_feels_no_torque():
    """The ideal leg straight down, the force up through the sole point: every axis it meets."""
    lc = comp()
    tau = lc.leg_torques(np.zeros(6), 1, 50.0, np.zeros(3), np.zeros(3), np.eye(3))
    np.testing.assert_allclose(tau, 0.0, atol=1e-12)


def test_a_bent_knee_carries_the_force_times_its_lever():
    """Hip pitch -a, knee 2a, ankle -a (the sole under the hip, level): the knee is l sin(a) ahead of
    the line of action, so it feels F l sin(a) (flexing it), the hip and ankle pitch none."""
    leg = LegGeometry()
    a = 0.4
    q = np.array([0.0, 0.0, -a, 2 * a, -a, 0.0])
    tau = comp(leg).leg_torques(q, 1, 50.0, np.zeros(3), np.zeros(3), np.eye(3))
    lever = leg.shank * math.sin(a)
    assert abs(abs(tau[3]) - 50.0 * lever) < 1e-9
    np.testing.assert_allclose(tau[[0, 1, 2, 4, 5]], 0.0, atol=1e-9)


def test_link_weights_are_the_gradient_of_their_potential():
    """Each link's weight (thigh at the middle of hip and knee, calf of knee and ankle) acts on the
    joints above it as -dV/dq, V = m g z of its point: central differences of the chain's points."""
    c = bent_chain()
    leg = LegGeometry(chains=LegChains(c, c))
    masses = (0.6, 0.7)
    lc = comp(leg, masses=masses)
    rng = np.random.default_rng(5)
    R_wp = np.eye(3)

    def potential(q):
        _, _, _, pts = c._chain(q)
        return 9.81 * (masses[0] * ((pts[2] + pts[3]) / 2)[2] + masses[1] * ((pts[3] + pts[4]) / 2)[2])
    for _ in range(10):
        q = rng.uniform(-0.4, 0.4, 6)
        h = 1e-6
        grad = np.array([(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(6)])
        np.testing.assert_allclose(lc.leg_torques(q, 1, 0.0, np.zeros(3), np.zeros(3), R_wp), -grad, atol=1e-6)


def test_offsets_move_the_stance_leg_against_its_load_within_the_servo():
    """Single support on the left: the left leg's offsets are -tau / kp, the right's zero (no link
    masses), each bounded by torque / kp; standing on both, the ZMP at the right sole puts it all
    there."""
    leg = LegGeometry()
    q = np.zeros(len(JOINT_NAMES))
    q[LEFT] = q[RIGHT] = [0.0, 0.0, -0.4, 0.8, -0.4, 0.0]
    feet = {1: np.array([0.0, 0.05, 0.0, 0.0]), -1: np.array([0.0, -0.05, 0.0, 0.0])}
    soles = {s: np.array([f[0], f[1], 0.0]) for s, f in feet.items()}
    lc = comp(leg)
    off = lc.offsets(q, feet, soles, np.array([0.0, 0.05]), 1, 40.0, np.eye(3), (0.1, 0.06))
    tau = lc.leg_torques(q[LEFT], 1, 40.0, soles[1], soles[1], np.eye(3))
    np.testing.assert_allclose(off[LEFT], -tau / 20.0)
    np.testing.assert_allclose(off[RIGHT], 0.0)
    assert abs(off[LEFT][3]) > 0.05
    heavy = comp(leg, torque=0.5)
    capped = heavy.offsets(q, feet, soles, np.array([0.0, 0.05]), 1, 40.0, np.eye(3), (0.1, 0.06))
    assert np.max(np.abs(capped)) <= 0.5 / 20.0 + 1e-15
    both = comp(leg).offsets(q, feet, soles, np.array([0.0, -0.05]), 0, 40.0, np.eye(3), (0.1, 0.06))
    np.testing.assert_allclose(both[LEFT], 0.0)
    np.testing.assert_allclose(both[RIGHT], off[LEFT] * np.array([1, -1, 1, 1, 1, -1]), atol=1e-12)


def test_targets_lead_by_the_servos_lag():
    """A target moving at a steady rate leads by lag_share x damping / kp x the rate."""
    lc = comp(load=0.0, lag=0.5, kp=20.0, damping=2.0)
    feet = {1: np.zeros(4), -1: np.zeros(4)}
    q0 = np.zeros(len(JOINT_NAMES))
    rate = np.linspace(-1, 1, len(JOINT_NAMES))
    assert not np.any(lc.offsets(q0, feet, feet, np.zeros(2), 0, 40.0, np.eye(3), (0.1, 0.06)))
    off = lc.offsets(q0 + rate * 0.01, feet, feet, np.zeros(2), 0, 40.0, np.eye(3), (0.1, 0.06))
    np.testing.assert_allclose(off, 0.5 * 2.0 / 20.0 * rate)


def test_servo_terms_come_from_a_robot_file_or_the_simulator():
    from gaits.robot.robot_file import JointSpec, RobotFile
    from tuner.robots import load_robot
    joints = {n: JointSpec(n, kp=25.0, damping=1.5, torque=7.0) for n in JOINT_NAMES}
    t = servo_terms(RobotFile("r", LegGeometry(), (0.1, 0.06), joints))
    assert np.all(t.kp == 25.0) and np.all(t.damping == 1.5) and np.all(t.torque == 7.0)
    unstated = {n: JointSpec(n) for n in JOINT_NAMES}
    assert servo_terms(RobotFile("r", LegGeometry(), (0.1, 0.06), unstated)) is None
    robot = load_robot("kidsize")
    sim = servo_terms(robot)
    knee = robot.servos[robot.joint_map["l_knee"][0]].pieces()
    i = JOINT_NAMES.index("l_knee")
    assert sim.kp[i] == pytest.approx(knee.kp) and sim.damping[i] == pytest.approx(knee.kv + knee.back_emf + knee.damping)


def test_the_engine_refuses_compensation_without_the_servos_gains():
    """A robot file written before it stated gains: one line saying so, not a walk silently without."""
    import gaits
    from gaits.engine import EngineParams, WalkEngine
    from gaits.params import ParamError
    from gaits.robot.robot_file import JointSpec, RobotFile
    from tuner.params_io import resolve_params
    params = resolve_params("kidsize-omni-carpet4", None).params
    robot = RobotFile("r", LegGeometry(), (0.1, 0.06), {n: JointSpec(n) for n in JOINT_NAMES})
    limits = gaits.family("tlipfm").step_limits(params, robot)
    WalkEngine(params, EngineParams(), robot, 0.01, limits)
    with pytest.raises(ParamError, match="load_share = 1.*export it again"):
        WalkEngine(params, EngineParams(load_share=1.0), robot, 0.01, limits)


def test_the_wolfgang_example_states_its_training_servos():
    """examples/robots/wolfgang: a map of Bit-Bots' Wolfgang-OP (its URDF cloned beside it, not
    shipped) whose leg servos are the ones its learned walks were trained on (their MuJoCo model's
    mx106 class: kp 21, 8 N m, damping 1.7, armature 0.025, friction loss 0.1), and soft enough that
    init has the engine put their give back (13.7 deg at the knee, docs/walk.md)."""
    import yaml
    from conftest import ROOT
    from tuner.robots.robot_map import MAP_KEYS
    doc = yaml.safe_load((ROOT / "examples" / "robots" / "wolfgang" / "wolfgang.yaml").read_text())
    assert set(doc) <= set(MAP_KEYS)
    assert doc["servo"]["legs"] == {"law": "pd", "kp": 21, "kv": 0, "torque": 8, "speed": 20, "armature": 0.025,
                                    "damping": 1.7, "frictionloss": 0.1}
    assert doc["urdf"].startswith("wolfgang_robot/") and sorted(doc["joints"]) == sorted(JOINT_NAMES[8:20])
