"""A walk whose servo commands are all known before it starts (a joint table, nothing in the plant
reading the state) runs in MuJoCo's native rollout, in chunks (`Simulator._native`): bit for bit
the tick loop's walk, whatever ends it."""

import dataclasses

import mujoco
import numpy as np
import pytest

import gaits
from tuner.robots import load_robot
from tuner.sim.randomisation import NONE, TUNE, draw
from tuner.sim.rollout import NATIVE_CHUNK, Simulator, rate_limited
from tuner.sim.surfaces import SURFACES

ROBOT = load_robot("kidsize")
SIMS: dict[str, Simulator] = {}
FIELDS = ("t", "pitch", "roll", "p_torso", "p_com", "force", "zmp", "q", "q_cmd", "q_ref", "q_sent", "tau", "qpos")


def sim_for(surface):
    if surface not in SIMS:
        SIMS[surface] = Simulator(ROBOT, SURFACES[surface])
    return SIMS[surface]


def table(sim):
    return gaits.generate(gaits.load_baseline("tkux-table2").params, ROBOT.leg, sim.control_period)


def counting(monkeypatch, sim):
    """Counts the walks ``sim`` hands to its native rollout."""
    calls = []
    native = sim._native

    def spy(*args, **kw):
        calls.append(1)
        return native(*args, **kw)

    monkeypatch.setattr(sim, "_native", spy)
    return calls


def ticked(sim, traj, **kw):
    """The same walk through the tick loop: an ``on_tick`` keeps it there (it could end the walk)."""
    return sim.run(gaits.control.TablePlayer(traj), on_tick=lambda k, d: None, record_qpos=True, **kw)


def same(a, b):
    for f in FIELDS:
        assert np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True), f
    assert a.reason == b.reason and a.outcome == b.outcome


def _loop(target, c0, step, lo, hi):
    """The tick loop's rate limiter, verbatim."""
    cmd, out = c0.copy(), [c0.copy()]
    for k in range(1, len(target)):
        delta = target[k] - cmd
        cmd += np.minimum(np.maximum(delta, -step, out=delta), step, out=delta)
        np.minimum(np.maximum(cmd, lo, out=cmd), hi, out=cmd)
        out.append(cmd.copy())
    return np.array(out)


@pytest.mark.parametrize("seed", range(40))
def test_rate_limited_is_the_loops_limiter_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    n, j = int(rng.integers(2, 400)), int(rng.integers(1, 8))
    t = np.arange(n)[:, None] * 0.01
    target = rng.uniform(-1, 1, j) * np.sin(2 * np.pi * rng.uniform(0.2, 3, j) * t + rng.uniform(0, 6, j))
    target += rng.uniform(-0.3, 0.3, j)
    if seed % 3 == 0:                                              # jumps: the limit binds
        target[rng.integers(0, n, 5)] += rng.normal(0, 0.5, (5, j))
    if seed % 5 == 0:                                              # a joint held at zero
        target[:, 0] = 0.0
    step = rng.uniform(0.005, 0.1, j)
    lo = np.where(rng.random(j) < 0.5, -np.inf, rng.uniform(-1, -0.2, j))
    hi = np.where(rng.random(j) < 0.5, np.inf, rng.uniform(0.2, 1, j))
    c0 = target[0].copy() if seed % 2 else target[0] + rng.normal(0, 0.2, j)
    ours, loop = rate_limited(target, c0, step, lo, hi), _loop(target, c0, step, lo, hi)
    assert np.array_equal(ours, loop)
    assert np.array_equal(np.signbit(ours), np.signbit(loop))


@pytest.mark.parametrize("surface", ["rigid", "carpet4", "grass50"])
def test_a_table_runs_natively_bit_for_bit(surface, monkeypatch):
    sim = sim_for(surface)
    traj = table(sim)
    calls = counting(monkeypatch, sim)
    a = sim.run(gaits.control.TablePlayer(traj), duration=4.0, record_qpos=True)
    end = sim.data.qpos.copy()
    assert calls and a.completed
    b = ticked(sim, traj, duration=4.0)
    assert len(calls) == 1                                       # the loop's walk did not go native
    same(a, b)
    assert np.array_equal(end, sim.data.qpos)                    # the data left in the walk's last state


@pytest.mark.parametrize("surface", ["carpet4", "grass30"])
@pytest.mark.parametrize("impulse,outcome", [(0.5, "completed"), (3.0, "fell")])
def test_pushes_and_falls_natively_bit_for_bit(impulse, outcome, surface, monkeypatch):
    """A push is a chunk of its own (MuJoCo's applied force); a fall inside a chunk ends the walk at
    the loop's tick, the data in that tick's state; command latency and a perturbed model (no
    backlash: a dead band reads the state) too; on grass the drag gate in MuJoCo's step."""
    sim = sim_for(surface)
    traj = table(sim)
    calls = counting(monkeypatch, sim)
    p = dataclasses.replace(draw(NONE, 4, *sim.n_random(), namespace=TUNE), latency=2)
    pushes = [(2.005, np.array([impulse, 0.3 * impulse, 0.0]))]
    a = sim.run(gaits.control.TablePlayer(traj), duration=5.0, pushes=pushes, perturb=p, record_qpos=True)
    end = sim.data.qpos.copy()
    b = ticked(sim, traj, duration=5.0, pushes=pushes, perturb=p)
    same(a, b)
    assert a.outcome == outcome and len(calls) == 1
    assert np.array_equal(end, sim.data.qpos)
    if outcome == "fell":
        assert len(a.t) % NATIVE_CHUNK != 1                      # it fell inside a chunk, not at its end


def test_a_warning_inside_a_chunk_hands_the_walk_back_to_the_loop(monkeypatch):
    """MuJoCo's native rollout stops at a warning; the loop decides what it means (here a blow-up:
    the walk "diverged"), from the state at the start of that chunk."""
    sim = sim_for("rigid")
    traj = table(sim)

    def blow_up(m, d):
        d.qvel[10] = 1e30

    calls = counting(monkeypatch, sim)
    a = sim.run(gaits.control.TablePlayer(traj), duration=2.0, start=blow_up, record_qpos=True)
    b = ticked(sim, traj, duration=2.0, start=blow_up)
    assert a.outcome == "diverged", a.reason
    assert len(calls) == 1
    same(a, b)


@pytest.mark.parametrize("surface,chunk", [("carpet4", 3), ("grass50", 13)])
def test_a_walk_handed_back_mid_way_goes_on_in_the_loop_bit_for_bit(surface, chunk, monkeypatch):
    """A warning that does not end the walk (here a contact arena said full, in a chunk mid-walk):
    the loop takes the walk from that chunk's start, its servo commands and the ones still on
    their way (command latency) where the native chunks left them, and ends it as the loop alone
    would (on grass, with the drag gate's state where the chunk's start left it)."""
    import tuner.sim.rollout as R

    sim = sim_for(surface)
    traj = table(sim)
    real, calls = R._ROLLOUT, []

    class Warns:
        def rollout(self, model, data, *args, **kw):
            out = real.rollout(model, data, *args, **kw)
            calls.append(1)
            if len(calls) == chunk:
                data[0].warning[mujoco.mjtWarning.mjWARN_CONTACTFULL].number = 1
            return out

    monkeypatch.setattr(R, "_ROLLOUT", Warns())
    p = dataclasses.replace(draw(NONE, 4, *sim.n_random(), namespace=TUNE), latency=2)
    pushes = [(3.005, np.array([0.5, 0.2, 0.0]))]
    a = sim.run(gaits.control.TablePlayer(traj), duration=4.0, perturb=p, pushes=pushes, record_qpos=True)
    assert len(calls) == chunk and a.completed                   # no native chunk after that one
    b = ticked(sim, traj, duration=4.0, perturb=p, pushes=pushes)
    same(a, b)


def test_the_fall_sensors_are_the_torsos_frame():
    sim = sim_for("carpet4")
    sim.rollout(table(sim), duration=1.0)
    m, d = sim.model, sim.data
    mujoco.mj_forward(m, d)
    s = d.sensordata[sim._s_fall]
    assert np.array_equal(s[:3], d.xmat[sim._torso].reshape(3, 3)[:, 2])
    assert np.array_equal(s[3:], d.xpos[sim._torso])
