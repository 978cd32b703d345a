"""Domain randomisation and the IMU stabiliser: each perturbation has its intended effect."""

import dataclasses
import multiprocessing as mp

import mujoco
import numpy as np
import pytest

import gaits
from gaits import StabiliserParams
from tuner.errors import UserError
from tuner.sim.randomisation import EVALUATE, NONE, TUNE, Randomisation, draw, randomisation_from_mapping
from tuner.robots import load_robot
from tuner.report.robot_check import stand_trajectory
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES

ROBOT = load_robot("kidsize")
SIMS = {}


def sim_for(surface="rigid"):
    if surface not in SIMS:
        SIMS[surface] = Simulator(ROBOT, SURFACES[surface])
    return SIMS[surface]


def walk(sim):
    return gaits.generate(gaits.load_baseline("tkux-table2").params, ROBOT.leg, sim.control_period)


def quiet(**kw):
    """No randomisation but the fields given (so each test sees one effect)."""
    return dataclasses.replace(NONE, **kw)


def pert(sim, r, seed=1, namespace=TUNE, **replace):
    p = draw(r, seed, *sim.n_random(), namespace=namespace)
    return dataclasses.replace(p, **replace) if replace else p


def _walk_in_child(seed):
    sim = Simulator(load_robot("kidsize"), SURFACES["grass50"])
    tr = sim.rollout(walk(sim), duration=3.0, perturb=draw(Randomisation(), seed, *sim.n_random()))
    return tr.p_torso.tobytes(), tr.q.tobytes()


def test_same_seed_same_rollout_bit_for_bit_in_any_process():
    sim = sim_for("grass50")
    p = draw(Randomisation(), 7, *sim.n_random())
    a = sim.rollout(walk(sim), duration=3.0, perturb=p)
    b = sim.rollout(walk(sim), duration=3.0, perturb=draw(Randomisation(), 7, *sim.n_random()))
    assert a.p_torso.tobytes() == b.p_torso.tobytes() and a.q.tobytes() == b.q.tobytes()
    with mp.get_context("spawn").Pool(1) as pool:
        child = pool.apply(_walk_in_child, (7,))
    assert child == (a.p_torso.tobytes(), a.q.tobytes())
    c = sim.rollout(walk(sim), duration=3.0, perturb=draw(Randomisation(), 8, *sim.n_random()))
    assert c.p_torso.tobytes() != a.p_torso.tobytes()
    # the model is restored after a perturbed rollout: a plain rollout is unchanged
    plain = [sim.rollout(walk(sim), duration=3.0).p_torso for _ in range(2)]
    assert plain[0].tobytes() == plain[1].tobytes()


def test_tuning_and_evaluation_seeds_are_disjoint_streams():
    sim = sim_for()
    for seed in range(20):
        t = draw(Randomisation(), seed, *sim.n_random(), namespace=TUNE)
        e = draw(Randomisation(), seed, *sim.n_random(), namespace=EVALUATE)
        assert t.noise_seed != e.noise_seed and not np.allclose(t.body_mass, e.body_mass)


def test_added_torso_mass_moves_the_com():
    sim = sim_for()
    m = sim.model
    torso = m.body(ROBOT.torso).id
    f = np.ones(m.nbody)
    f[torso] = 1.5
    p = pert(sim, NONE, body_mass=f)
    d0 = mujoco.MjData(m)
    mujoco.mj_forward(m, d0)
    com0, M = d0.subtree_com[torso].copy(), m.body_subtreemass[torso]
    sim._apply(p)
    try:
        d1 = mujoco.MjData(m)
        mujoco.mj_forward(m, d1)
        dm = 0.5 * sim._nominal["body_mass"][torso]
        expected = com0 + dm * (d0.xipos[torso] - com0) / (M + dm)
        assert d1.subtree_com[torso] == pytest.approx(expected, abs=1e-9)
        assert m.body_subtreemass[torso] == pytest.approx(M + dm)
    finally:
        sim._restore()
    assert sim.model.body_mass[torso] == pytest.approx(sim._nominal["body_mass"][torso])


@pytest.mark.parametrize("ticks", [1, 2])
def test_latency_delays_the_servo_command_by_its_ticks(ticks):
    sim = sim_for()
    tr = sim.rollout(walk(sim), duration=3.0, perturb=pert(sim, quiet(latency_ticks=ticks), latency=ticks))
    assert np.array_equal(tr.q_sent[ticks:], tr.q_cmd[:-ticks])
    fast = sim.rollout(walk(sim), duration=3.0)
    # the joints follow later: the knee's lag behind its (undelayed) command grows by ~ticks x its speed
    k = fast.joint_names.index("l_knee")
    lag = lambda tr: np.mean(np.abs(tr.q_cmd[150:, k] - tr.q[150:, k]))
    assert lag(tr) > lag(fast) + 0.2 * ticks * np.mean(np.abs(np.diff(fast.q_cmd[150:, k])))


def test_backlash_is_a_dead_band():
    sim = sim_for()
    b = 0.03
    p = pert(sim, NONE, backlash=np.full(sim.n_random()[2], b))
    from tuner.sim.rollout import dead_band
    assert dead_band(np.array([0.10, 0.10, 0.10]), np.array([0.095, 0.12, 0.05]), np.full(3, 0.015)) == \
        pytest.approx([0.095, 0.115, 0.085])     # inside the band: hold; outside: move by the excess
    tr = sim.rollout(stand_trajectory(ROBOT, 1.0, sim.control_period), perturb=p)
    assert np.max(np.abs(tr.q_sent - tr.q_cmd)) <= b / 2 + 1e-3
    ref = sim.rollout(stand_trajectory(ROBOT, 1.0, sim.control_period))
    # standing, the load-bearing knees give way by about half the band more
    k = tr.joint_names.index("l_knee")
    extra = abs(tr.q[-1, k] - tr.q_cmd[-1, k]) - abs(ref.q[-1, k] - ref.q_cmd[-1, k])
    assert 0.3 * b / 2 < extra < 1.5 * b / 2


def test_push_changes_the_com_velocity_by_impulse_over_mass():
    sim = Simulator(ROBOT, SURFACES["rigid"])
    sim._nominal_gravity = np.zeros(3)            # afloat over the floor: no contact takes part
    impulse = 2.0                                 # [N s]
    base = pert(sim, NONE, push_impulse=0.0, push_time=0.3, push_angle=np.pi / 2)
    pushed = dataclasses.replace(base, push_impulse=impulse)
    traj = walk(sim)
    a = sim.rollout(traj, duration=3.0, perturb=base)
    b = sim.rollout(traj, duration=3.0, perturb=pushed)
    k = int(round(b.meta["push_t"] / sim.control_period))
    dt = sim.control_period
    v = lambda tr, j: (tr.p_com[j + 1, 1] - tr.p_com[j, 1]) / dt
    mass = float(np.sum(sim.model.body_mass))
    assert v(b, k + 2) - v(a, k + 2) == pytest.approx(impulse / mass, rel=0.02)    # +y: 0.404 m/s
    assert np.array_equal(a.p_com[:k], b.p_com[:k])


def test_tilt_friction_and_layer_reach_the_model():
    sim = sim_for("grass50")
    p = pert(sim, NONE, gravity_dir=np.array([np.sin(0.05), 0.0, -np.cos(0.05)]), friction=0.5,
             layer_height=0.8, layer_timeconst=1.2, drag=2.0)
    m = sim.model
    sim._apply(p)
    try:
        assert m.opt.gravity == pytest.approx([9.81 * np.sin(0.05), 0.0, -9.81 * np.cos(0.05)])
        layer = m.geom("gt/layer").id
        assert m.geom_margin[layer] == pytest.approx(0.8 * SURFACES["grass50"].layer_height)
        assert m.geom_friction[layer, 0] == pytest.approx(0.5 * SURFACES["grass50"].friction)
        assert m.geom_solref[layer, 0] == pytest.approx(1.2 * SURFACES["grass50"].layer_timeconst)
        drag = [a for a in range(m.nu) if "/drag/" in m.actuator(a).name]
        assert m.actuator_gainprm[drag[0], 2] == pytest.approx(-2.0 * SURFACES["grass50"].drag)
    finally:
        sim._restore()
    assert m.opt.gravity == pytest.approx([0, 0, -9.81])


def test_stabiliser_reduces_torso_pitch_after_a_push():
    sim = sim_for()
    traj = stand_trajectory(ROBOT, 3.0, sim.control_period)
    p = pert(sim, NONE, push_impulse=1.0, push_time=0.3, push_angle=np.pi)          # pushed backward
    traj = dataclasses.replace(traj, support=np.ones_like(traj.support))      # push time counts from t = 0
    off = sim.rollout(traj, perturb=p)
    on = sim.rollout(traj, perturb=p, stabiliser=StabiliserParams(enabled=True, k_ankle_pitch=0.5,
                                                                   d_ankle_pitch=0.05, k_hip_pitch=0.5,
                                                                   d_hip_pitch=0.05))
    k = int(round(off.meta["push_t"] / sim.control_period))
    after = slice(k, None)
    assert not on.fell and not off.fell
    rms = lambda tr: np.sqrt(np.mean(tr.pitch[after] ** 2))
    assert rms(on) < 0.6 * rms(off)               # measured 1.06 vs 2.32 deg


def test_randomisation_fields_are_validated():
    with pytest.raises(UserError, match=r"randomisation.latency_ticks = 1.5: expected a whole number in \[0, 5\]"):
        Randomisation(latency_ticks=1.5)
    with pytest.raises(UserError, match=r"robust: unknown field 'mass' \(allowed: mass_scale"):
        randomisation_from_mapping({"mass": 0.1}, "robust")
    with pytest.raises(UserError, match=r"randomisation.tilt_deg = nan"):
        Randomisation(tilt_deg=float("nan"))


class _Stepped(gaits.control.TablePlayer):
    """The same table, stepped tick by tick (its own ``step``: no targets ahead)."""

    def step(self, m, command=None):
        return super().step(m, command)


@pytest.mark.parametrize("surface,randomised", [("rigid", False), ("grass30", True)])
def test_a_table_taken_ahead_walks_bit_for_bit_as_one_stepped(surface, randomised):
    """The rollout takes a table's targets ahead (`TablePlayer.ahead`) instead of stepping it:
    the same walk to the bit, with latency, backlash and the grass's drag gate."""
    sim = sim_for(surface)
    traj = walk(sim)
    p = pert(sim, Randomisation(), seed=3) if randomised else None
    assert _Stepped(traj).ahead(5) is None and gaits.control.TablePlayer(traj).ahead(5).shape == (5, 20)
    a = sim.run(gaits.control.TablePlayer(traj), duration=4.0, perturb=p, record_qpos=True)
    b = sim.run(_Stepped(traj), duration=4.0, perturb=p, record_qpos=True)
    for field in ("qpos", "q", "q_cmd", "q_ref", "q_sent", "force", "p_com"):
        assert np.array_equal(getattr(a, field), getattr(b, field), equal_nan=True), field
    assert a.reason == b.reason
