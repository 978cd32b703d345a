"""The grass drag gate in MuJoCo's step (``tuner/sim/native_step.c`` through ``native_step.py``): the
Python gate's numbers to the bit, walk by walk, and inert on every model it was not armed on."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys

import mujoco
import numpy as np
import pytest

import gaits
from gaits import CommandStream, EngineParams, WalkEngine
from tuner.params_io import resolve_params
from tuner.robots import load_robot
from tuner.sim import native_step as native_gate
from tuner.sim.randomisation import EVALUATE, Randomisation, draw
from tuner.sim.rollout import Simulator
from tuner.sim.ground.layer import drag_gate
from tuner.sim.surfaces import SURFACES

from test_native_rollout import same  # the field-by-field comparison of two walks

ROBOT = load_robot("kidsize")

if not native_gate.install():
    pytest.skip(f"the native drag gate is not available here: {native_gate.status()}", allow_module_level=True)


def pair(surface):
    s = SURFACES[surface] if isinstance(surface, str) else surface
    a, b = Simulator(ROBOT, s), Simulator(ROBOT, s, native_gate=False)
    assert a.ground.native and not b.ground.native
    return a, b


@pytest.mark.parametrize("surface", ["grass10", "grass30", "grass50"])
def test_a_table_walks_the_same_with_either_gate(surface):
    a, b = pair(surface)
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, ROBOT.leg, a.control_period)
    ta, tb = a.rollout(traj, record_qpos=True), b.rollout(traj, record_qpos=True)
    same(ta, tb)
    assert ta.completed


def test_a_closed_loop_randomised_pushed_walk_the_same_with_either_gate():
    """The walk engine on a command stream (the tick loop), under the default randomisation (the
    blades' height drawn, backlash, latency, noise) with a push, on a grass with a drag depth."""
    a, b = pair(dataclasses.replace(SURFACES["grass50"], drag_depth=0.02))
    fast = resolve_params("kidsize-omni-grass50", None).params
    limits = gaits.family("tlipfm").step_limits(fast, ROBOT)
    stream = CommandStream([0.0, 2.0, 3.5], [[0.2, 0, 0], [0.1, 0.0, 0.6], [0, 0, 0]], tail=1.5)
    traces = []
    for sim in (a, b):
        p = draw(Randomisation(), 3, *sim.n_random(), namespace=EVALUATE)
        e = WalkEngine(fast, EngineParams(), ROBOT, sim.control_period, limits)
        traces.append(sim.run(e, commands=stream, duration=stream.duration, perturb=p, record_qpos=True,
                              pushes=[(2.5, np.array([0.6, 0.2, 0.0]))]))
    assert p.layer_height != 1.0 and np.any(p.backlash > 0)
    same(*traces)


@pytest.mark.parametrize("depth", [0.0, 0.015])
def test_the_callback_gates_as_drag_gate_does(depth):
    """Corners put in, at and over the blade tips: the callback's ctrl is drag_gate's of the
    heights MuJoCo computed, exactly, for both the x and the y damper."""
    sim = Simulator(ROBOT, dataclasses.replace(SURFACES["grass30"], drag_depth=depth))
    m, d = sim.model, sim.data
    mujoco.mj_resetData(m, d)
    h = sim.surface.layer_height
    first, values = sim._n_act, []
    for z0 in (h - 0.03, h - 0.01, h - 0.002, h, h + 0.004):
        d.qpos[3:7] = [np.cos(0.1), 0.0, np.sin(0.1), 0.0]     # pitched: the corners at four heights
        d.qpos[2] = 1.0
        mujoco.mj_forward(m, d)
        d.qpos[2] += z0 - d.site_xpos[sim.ground.site_ids, 2].min()  # the lowest corner at z0
        d.time = 0.0
        native_gate.arm(m, d, height=h, depth=depth, nstep=sim.nstep, first=first, n_points=8)
        mujoco.mj_forward(m, d)
        z = d.site_xpos[sim.ground.site_ids, 2]
        expect = np.repeat(drag_gate(z, h, depth), 2)
        assert np.array_equal(d.ctrl[first:], expect)
        values.extend(d.ctrl[first:])
    values = np.array(values)
    assert (values == 0.0).any() and (values == 1.0).any()
    assert depth == 0.0 or ((values > 0.0) & (values < 1.0)).any()
    native_gate.disarm(m, d)


def test_the_gate_holds_over_a_tick_and_takes_the_last_steps_heights():
    """Over a control tick the gate stays; the next tick's comes from the kinematics of this tick's
    last physics step (what the loop read between ticks)."""
    sim = Simulator(ROBOT, SURFACES["grass50"])
    m, d = sim.model, sim.data
    mujoco.mj_resetData(m, d)
    d.qpos[2] = sim.surface.layer_height + 0.3                 # the corners fall through the tips
    d.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
    mujoco.mj_forward(m, d)
    first, seen = sim._n_act, []
    native_gate.arm(m, d, height=sim.surface.layer_height, depth=0.0, nstep=sim.nstep, first=first, n_points=8)
    for tick in range(40):
        heights_before = d.site_xpos[sim.ground.site_ids, 2].copy()
        for _ in range(sim.nstep):
            mujoco.mj_step(m, d)
            seen.append(d.ctrl[first:].copy())
        tick_rows = np.array(seen[-sim.nstep:])
        assert (tick_rows == tick_rows[0]).all()
        assert np.array_equal(tick_rows[0], np.repeat(drag_gate(heights_before, sim.surface.layer_height), 2))
    assert seen[0].max() == 0.0 and seen[-1].min() == 1.0      # out of the blades, then in
    native_gate.disarm(m, d)


def test_the_callback_leaves_other_models_and_unarmed_walks_alone():
    sim = Simulator(ROBOT, SURFACES["grass50"])
    m, d = sim.model, sim.data
    mujoco.mj_resetData(m, d)
    d.ctrl[sim._n_act:] = 0.25
    mujoco.mj_step(m, d, nstep=7)                               # ours, not armed
    assert (d.ctrl[sim._n_act:] == 0.25).all()
    other = mujoco.MjModel.from_xml_string(
        '<mujoco><size nuserdata="40"/><worldbody><body><freejoint/><geom size=".1"/>'
        '<site name="s"/></body></worldbody><actuator><motor site="s" gear="1 0 0 0 0 0"/></actuator></mujoco>')
    od = mujoco.MjData(other)
    od.userdata[:] = 3.0
    od.ctrl[:] = 0.5
    mujoco.mj_step(other, od, nstep=5)
    assert (od.ctrl == 0.5).all() and (od.userdata == 3.0).all()


def test_without_the_callback_the_python_gate_walks(tmp_path):
    """GAIT_TUNER_NATIVE_STEP=0 (or no compiler, or another callback) keeps the gate in Python and
    says so."""
    code = ("from tuner.sim import native_step as native_gate; from tuner.sim.cache import simulator; import gaits\n"
            "s = simulator('kidsize', 'grass50'); assert not s.ground.native\n"
            "t = gaits.generate(gaits.load_baseline('tkux-table2').params, s.robot.leg, s.control_period)\n"
            "print(native_gate.status()); print(s.rollout(t).completed)")
    env = {**os.environ, "GAIT_TUNER_NATIVE_STEP": "0"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[:2] == ["off (GAIT_TUNER_NATIVE_STEP=0): the drag gate runs in Python", "True"]


def test_a_broken_compiler_keeps_the_python_gate(tmp_path):
    """A compiler that fails (here CC=false, with an empty cache): one status line, the Python gate."""
    code = ("from tuner.sim import native_step as native_gate; from tuner.sim.cache import simulator\n"
            "s = simulator('kidsize', 'grass10'); print(s.ground.native); print(native_gate.status())")
    env = {**os.environ, "CC": "false", "XDG_CACHE_HOME": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().split("\n")
    assert lines[0] == "False" and lines[1].startswith("off (") and lines[1].endswith("the drag gate runs in Python")
    assert not list(tmp_path.rglob("*.so"))


def test_the_gate_compiles_into_an_empty_cache(tmp_path):
    """On a machine that has not built it yet: compiled once into the user cache, then used."""
    code = ("from tuner.sim import native_step as native_gate; from tuner.sim.cache import simulator\n"
            "s = simulator('kidsize', 'grass30'); print(s.ground.native); print(native_gate.status())")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    env.pop("CC", None)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[:2] == ["True", "native (native_step.c as mjcb_control)"]
    built = list((tmp_path / "gait-tuner").glob("native_step-*.so"))
    assert len(built) == 1 and not [p for p in (tmp_path / "gait-tuner").iterdir() if p not in built]


def test_a_damaged_cached_library_is_rebuilt(tmp_path):
    """A cached file that does not load (here overwritten with text) is built again, once."""
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    code = "from tuner.sim import native_step as native_gate; print(native_gate.install(), native_gate.status())"
    first = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert first.stdout.strip() == "True native (native_step.c as mjcb_control)", first.stderr
    [built] = list((tmp_path / "gait-tuner").glob("native_step-*.so"))
    built.unlink()                                             # not in place: a loaded copy keeps its pages
    built.write_text("not a library")
    again = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert again.stdout.strip() == "True native (native_step.c as mjcb_control)"
    assert built.stat().st_size > 1000 and b"not a library" not in built.read_bytes()


def test_which_surfaces_gate_their_drag():
    from pathlib import Path

    from tuner.sim.surfaces import load_surface
    from tuner.sim.ground import kind_of
    assert {n: kind_of(s).runs_in_step for n, s in SURFACES.items()} == {
        "rigid": False, "carpet4": False, "grass10": True, "grass30": True, "grass50": True}
    blades = load_surface(str(Path(__file__).resolve().parents[1] / "examples" / "surfaces" / "grass50-blades.yaml"))
    assert blades.drag > 0.0 and not kind_of(blades).runs_in_step
    ground = Simulator(ROBOT, blades).ground
    assert ground.name == "blades" and ground.python_tick and not hasattr(ground, "native")
