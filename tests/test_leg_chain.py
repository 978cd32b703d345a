"""The numerical leg IK (gaits/leg_chain.py) and the robots that need it: exact against the closed
form on ideal legs, exact on legs that are not ideal, and a robot written here as URDF with a hip
yaw axis 20 mm off the hip centre, legs bent at the zero pose and a tilted ankle roll axis, which
loads, stands and walks."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import run_cli

import third_party_robot as T
from gaits.leg_chain import IKNotConverged, LegChain, LegChains, chains_from_mapping, chains_to_mapping, ideal_chain
from gaits.leg_kinematics import LegGeometry, UnreachableTargetError, leg_fk, leg_ik, leg_ik_pose, rot_x, rot_y, rot_z
from gaits.params import ParamError


def random_legs(rng, n):
    q = rng.uniform(-0.4, 0.4, (n, 6))
    q[:, 3] = rng.uniform(0.2, 1.6, n)                  # the knee bent: away from the straight leg's singularity
    return q


def numerical(leg: LegGeometry) -> LegGeometry:
    import dataclasses
    return dataclasses.replace(leg, chains=LegChains(ideal_chain(leg, 1), ideal_chain(leg, -1), "test"))


@pytest.mark.parametrize("leg", [LegGeometry(), LegGeometry(hip_offset_x=0.02, hip_offset_z=0.03, thigh=0.17,
                                                                shank=0.16, ankle_height=0.05)])
def test_the_chain_of_an_ideal_leg_is_the_closed_forms(leg):
    """The product of exponentials of an ideal leg's axes gives leg_fk's poses (1e-12), and the
    numerical IK the closed form's angles (1e-7 rad) and soles (1e-6 m, the issue's bound; 1e-9 here)."""
    rng = np.random.default_rng(3)
    legn = numerical(leg)
    for side in (1, -1):
        q = random_legs(rng, 200)
        p, R = leg_fk(q, leg, side)
        pn, Rn = leg_fk(q, legn, side)
        assert np.abs(pn - p).max() < 1e-12 and np.abs(Rn - R).max() < 1e-12
        for k in range(len(q)):
            closed = leg_ik_pose(p[k], R[k], leg, side)
            solved = legn.chains.side(side).solve(p[k], R[k], q0=closed + rng.normal(0.0, 0.05, 6))
            assert np.abs(solved - closed).max() < 1e-7
            assert np.abs(leg_fk(solved, legn, side)[0] - p[k]).max() < 1e-9
    # the flat-foot table IK (every gait family's) the same, sample after sample warm-started
    targets = leg_fk(random_legs(rng, 50) * np.array([0, 0.3, 0.3, 1, 0.3, 0.3]), leg, 1)[0]
    np.testing.assert_allclose(leg_ik(targets, 0.0, legn, 1), leg_ik(targets, 0.0, leg, 1), atol=1e-7)


def bent_chain() -> LegChain:
    """A leg that is not ideal, as a team's: the yaw axis 20 mm ahead of the hip, the knee 30 mm and
    the ankle 40 mm ahead at the zero pose, the ankle roll axis tilted 15 deg, the axes' points
    anywhere on their lines."""
    t = math.radians(15)
    hip = np.array([0.0, 0.035, -0.03])
    knee = hip + np.array([0.03, 0.0, -math.sqrt(0.11 ** 2 - 0.03 ** 2)])
    ankle = knee + np.array([0.01, 0.0, -math.sqrt(0.11 ** 2 - 0.01 ** 2)])
    return LegChain(axes=[(0, 0, 1), (1, 0, 0), (0, 1, 0), (0, 1, 0), (0, 1, 0), (math.cos(t), 0, math.sin(t))],
                    points=[hip + (0.02, 0.0, 0.05), hip + (0.3, 0, 0), hip + (0, -0.2, 0), knee, ankle,
                            ankle + (0.0, 0.006, 0.0)],
                    sole=ankle + (0.0, 0.0, -0.035), sole_rotation=np.eye(3))


def test_the_numerical_ik_solves_a_leg_that_is_not_ideal():
    """FK(IK(FK(q))) = FK(q) to 1e-9 over random poses, from the last tick's answer (a walk's warm
    start), and the angles found are the ones that made the pose (one branch, near the start); with
    no start given, the same answer whatever was solved before (nothing kept between calls)."""
    chain = bent_chain()
    rng = np.random.default_rng(5)
    q_prev = np.array([0.0, 0.0, -0.4, 0.8, -0.4, 0.0])
    for k in range(300):
        q = q_prev + rng.normal(0.0, 0.02, 6)
        p, R = chain.fk(q)
        solved = chain.solve(p, R, q0=q_prev)              # from the last tick's answer
        p2, R2 = chain.fk(solved)
        assert np.abs(p2 - p).max() < 1e-9 and np.abs(R2 - R).max() < 1e-9
        assert np.abs(solved - q).max() < 1e-7
        q_prev = q
    p, R = chain.fk(q_prev)
    first = LegGeometry(chains=LegChains(chain, chain, "t"))
    a = leg_ik_pose(p, R, first, 1)
    chain.solve(*chain.fk(np.array([0.5, -0.3, -1.0, 2.0, 0.4, 0.3])))   # another solve in between
    np.testing.assert_array_equal(leg_ik_pose(p, R, first, 1), a)


def hip_roll_first_chain() -> LegChain:
    """A leg whose hip turns roll first, then yaw (as Berkeley Humanoid Lite's: both axes 45 deg
    from the vertical), its axes on lines that do not meet."""
    c = math.sqrt(0.5)
    hip = np.array([-0.01, 0.05, -0.09])
    knee = hip + np.array([0.0, -0.018, -0.15])
    ankle = knee + np.array([0.0, -0.003, -0.16])
    return LegChain(axes=[(c, 0, -c), (c, 0, c), (0, 1, 0), (0, 1, 0), (0, 1, 0), (1, 0, 0)],
                    points=[hip + (-0.037, 0.027, 0.037), hip + (-0.019, 0.027, 0.093), hip, knee, ankle,
                            ankle + (0.03, 0.025, -0.05)],
                    sole=ankle + (0.0, 0.0, -0.07), sole_rotation=np.eye(3), order=(1, 0, 2, 3, 4, 5))


def test_a_chain_composes_in_the_files_order_and_solves_in_ours():
    """The pose is the product of exponentials in the file's order (hip roll's factor first, a
    numpy reference from Rodrigues' formula), the joints in our order; the IK finds the angles that
    made a pose; the same axes composed yaw first give another pose; a bad order is named."""
    chain = hip_roll_first_chain()

    def screw(u, a, q):
        K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        R = np.eye(3) + math.sin(q) * K + (1 - math.cos(q)) * K @ K
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, (np.eye(3) - R) @ a
        return T

    rng = np.random.default_rng(7)
    q_prev = np.array([0.0, 0.0, -0.4, 0.8, -0.4, 0.0])
    for _ in range(100):
        q = q_prev + rng.normal(0.0, 0.03, 6)
        q[3] = min(max(q[3], 0.4), 1.4)                   # the knee bent: one branch
        T = np.eye(4)
        for i in (1, 0, 2, 3, 4, 5):
            T = T @ screw(np.array(chain.axes[i]), np.array(chain.points[i]), q[i])
        p, R = chain.fk(q)
        np.testing.assert_allclose(p, T[:3, :3] @ np.array(chain.sole) + T[:3, 3], atol=1e-12)
        np.testing.assert_allclose(R, T[:3, :3], atol=1e-12)
        solved = chain.solve(p, R, q0=q_prev)
        assert np.abs(solved - q).max() < 1e-7
        q_prev = q
    import dataclasses
    yaw_first = dataclasses.replace(chain, order=(0, 1, 2, 3, 4, 5))
    assert np.abs(yaw_first.fk(q_prev)[0] - chain.fk(q_prev)[0]).max() > 1e-3
    with pytest.raises(ValueError, match=r"order is the six joints 0-5 each once, got \[0, 0, 2, 3, 4, 5\]"):
        dataclasses.replace(chain, order=(0, 0, 2, 3, 4, 5))
    chains = LegChains(chain, chain, "t")
    assert chains_from_mapping(chains_to_mapping(chains), "robot.yaml") == chains
    doc = chains_to_mapping(chains)
    doc["left"]["order"] = [1, 0, 2, 3, 4.5, 5]
    with pytest.raises(ParamError, match=r"leg_chains.left: order .* expected whole numbers 0-5"):
        chains_from_mapping(doc, "robot.yaml")


def test_a_target_out_of_reach_is_named_and_keeps_the_closest_pose():
    chain = bent_chain()
    with pytest.raises(IKNotConverged, match=r"out of the leg's reach") as info:
        chain.solve(np.array([0.0, 0.035, -0.5]), np.eye(3))
    p, _ = chain.fk(info.value.best)
    assert p[2] > -0.5 and info.value.error > 0.01          # the leg stretched toward it, short of it
    leg = LegGeometry(chains=LegChains(chain, chain, "test"))
    with pytest.raises(UnreachableTargetError, match=r"left sole target .* out of the leg's reach") as info:
        leg_ik_pose(np.array([0.0, 0.035, -0.5]), np.eye(3), leg, 1)
    assert info.value.best.shape == (6,)                     # the engine walks on with it (as it clamps)


def test_chains_round_trip_through_a_robot_file_mapping_and_bad_ones_are_named():
    chains = LegChains(bent_chain(), bent_chain(), "both legs: the hip yaw axis passes 20.0 mm from the hip centre")
    assert chains_from_mapping(chains_to_mapping(chains), "robot.yaml") == chains
    doc = chains_to_mapping(chains)
    doc["left"]["axes"] = doc["left"]["axes"][:5]
    with pytest.raises(ParamError, match=r"robot.yaml: leg_chains.left.axes: expected 6 x 3"):
        chains_from_mapping(doc, "robot.yaml")
    doc = chains_to_mapping(chains)
    doc["right"]["axes"][0] = [0.0, 0.0, 0.0]
    with pytest.raises(ParamError, match=r"leg_chains.right: a leg chain's axes must be unit vectors"):
        chains_from_mapping(doc, "robot.yaml")


def test_the_solver_keeps_the_walk_engines_leg_on_a_smooth_path():
    """Along a stepping cycle each tick converges in at most 3 Newton steps from the last, to the
    solver's own tolerance, and in 2 to the walk engine's (``IK_TOL``), within it; taking a step under
    ``IK_STEP`` unevaluated saves evaluations and stays within it (counted, not timed: the time per
    tick is a figure, docs/robots.md)."""
    from gaits.engine.walk import IK_STEP, IK_TOL
    chain = bent_chain()
    calls = []
    inner = chain.chain_floats
    object.__setattr__(chain, "chain_floats", lambda q: calls.append(1) or inner(q))
    p0, _ = chain.fk(np.array([0.0, 0.0, -0.5, 1.0, -0.5, 0.0]))
    start = chain.solve(p0 + np.array([0.0, 0.01, 0.0]), rot_x(0.03), q0=np.array([0.0, 0.0, -0.5, 1.0, -0.5, 0.0]))

    def worst_over_a_cycle(tol, step_tol=0.0):
        q, counts = start, []
        for k in range(1, 200):
            ph = 2 * math.pi * k / 60
            yaw = 0.2 * math.sin(ph)
            target = p0 + np.array([0.04 * math.sin(ph), 0.01 * math.cos(ph), 0.02 * max(math.sin(ph), 0.0)])
            R = rot_z(yaw) @ rot_y(0.05 * math.sin(ph)) @ rot_x(0.03 * math.cos(ph))
            calls.clear()
            q = chain.solve(target, R, q0=q, tol=tol, step_tol=step_tol)
            counts.append(len(calls))
            p, Rq = chain.fk(q)
            assert np.linalg.norm(p - target) + np.linalg.norm(Rq - R) < 2 * tol
        return max(counts), float(np.mean(counts))
    assert worst_over_a_cycle(1e-10)[0] <= 4         # 3 steps and the final check
    worst, mean = worst_over_a_cycle(IK_TOL)
    assert worst <= 3                                # 2 steps and the check
    worst_taken, mean_taken = worst_over_a_cycle(IK_TOL, IK_STEP)   # a small last step taken unevaluated
    assert worst_taken <= 3 and mean_taken < mean - 0.1, (worst_taken, mean_taken, mean)


# --- a robot whose legs are not ideal, written as URDF --------------------------------------

BENT = dict(yaw_offset=0.02, knee_ahead=0.03, ankle_ahead=0.04, ankle_tilt_deg=15.0)


@pytest.fixture(scope="module")
def bent_robot(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bent")
    (tmp / "robot.urdf").write_text(T.urdf(T.mjcf(**BENT)))
    (tmp / "map.yaml").write_text(T.map_yaml(mjcf_name="robot.urdf").replace("mjcf:", "urdf:"))
    return tmp / "map.yaml"


def run(cmd, args, env):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env)


def test_the_bent_robot_loads_unedited_and_robot_check_says_which_ik(bent_robot, gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["robot", "check", bent_robot, "--json"], run_env)
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout)
    ik = rep["leg_ik"]
    assert ik["kind"] == "numerical"
    for words in ("hip yaw axis passes 19.9 mm from the hip centre", "knee axis is 30.0 mm ahead",  # 0.1 mm: its hips
                  "ankle roll axis is tilted 15.0 deg"):
        assert words in ik["why"], ik["why"]
    assert ik["p99_ms"] > 0
    assert rep["stand"]["stays_up"] if "stays_up" in rep["stand"] else rep["stand"]["outcome"] == "completed"
    plain = run(gait_tuner_cmd, ["robot", "check", "kidsize", "--json", "--no-stand"], run_env)
    assert json.loads(plain.stdout)["leg_ik"]["kind"] == "closed form"


def test_the_robot_file_of_a_bent_robot_carries_its_chains(bent_robot, tmp_path, gait_tuner_cmd, run_env):
    from gaits.robot.robot_file import load_robot_file
    from tuner.robots import load_robot
    out = tmp_path / "robot.yaml"
    r = run(gait_tuner_cmd, ["robot", "export", bent_robot, "--out", out], run_env)
    assert r.returncode == 0, r.stderr
    rf = load_robot_file(out)
    assert rf.leg.chains == load_robot(str(bent_robot)).leg.chains and rf.leg.ik == "numerical"


@pytest.mark.parametrize("surface", ["rigid", "grass30"])
@pytest.mark.parametrize("walk", [["--gait", "tlipfm"], ["--params", "kidsize-engine-carpet4", "--command", "0.15,0,0"]],
                         ids=["tlipfm-baseline", "engine"])
def test_the_bent_robot_walks(bent_robot, gait_tuner_cmd, run_env, surface, walk):
    r = run(gait_tuner_cmd, ["simulate", "--robot", bent_robot, "--surface", surface, "--json", *walk], run_env)
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)["metrics"]
    assert m["outcome"] == "completed" and m["distance_m"] > 0.2, (surface, m)


def test_the_engine_starts_each_legs_ik_where_its_last_two_ticks_point():
    """On a robot whose legs take the numerical IK, the engine starts each leg's Newton steps at
    2 q[k-1] - q[k-2] (the targets move smoothly): its targets are the closed form's within the
    engine's tolerance, and it evaluates the legs fewer times than from the last targets sent
    (counted, not timed)."""
    import dataclasses
    from types import SimpleNamespace

    import gaits
    from gaits import EngineParams, WalkEngine
    from gaits.control import Measurement
    from gaits.engine.walk import _LEG
    from gaits.leg_chain import LegChains, ideal_chain
    from tuner.params_io import resolve_params
    from tuner.robots import load_robot
    kidsize = load_robot("kidsize")
    gait = resolve_params("kidsize-omni-carpet4", None).params
    limits = gaits.family("tlipfm").step_limits(gait, kidsize)
    chains = LegChains(ideal_chain(kidsize.leg, 1), ideal_chain(kidsize.leg, -1), "tests")
    chained = SimpleNamespace(leg=dataclasses.replace(kidsize.leg, chains=chains), foot_size=kidsize.foot_size)

    def walk(robot, extrapolate=True):
        e = WalkEngine(gait, EngineParams(), robot, 0.01, limits)
        if not extrapolate:                        # the start before: the last targets sent
            e._ik_start = lambda side: None if e._last_q is None else e._last_q[_LEG[side]]
        calls = []
        for c in chains.left, chains.right:
            inner = c.chain_floats
            object.__setattr__(c, "chain_floats", lambda q, _inner=inner: calls.append(1) or _inner(q))
        try:
            e.reset(Measurement(0.0))
            e.start_pose()
            out = [e.step(Measurement(0.01 * k), np.array([0.2, 0.0, 0.1])) for k in range(1, 300)]
        finally:
            for c in chains.left, chains.right:
                object.__delattr__(c, "chain_floats")
        return np.array(out), len(calls), e.steps_taken
    closed, _, steps = walk(kidsize)
    q, evaluations, _ = walk(chained)
    q_before, evaluations_before, _ = walk(chained, extrapolate=False)
    assert steps > 5
    assert np.max(np.abs(q - closed)) < 1e-5 and np.max(np.abs(q_before - closed)) < 1e-5
    # measured: 1180 against 1302 evaluations over 299 ticks (2.0 a leg a tick against 2.2)
    assert evaluations < 0.95 * evaluations_before, (evaluations, evaluations_before)
