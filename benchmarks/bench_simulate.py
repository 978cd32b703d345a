"""Rollout cost: ``Simulator.rollout`` against the same walk's physics alone, side by side.

Usage: ``python benchmarks/bench_simulate.py [--repeats 5]``

For each surface, one model, one gait (TLIPFM Table 2, 10.96 s). ``simulate`` is the full
rollout (the table player, the rate limiter and joint ranges, the grass drag gate, sensors
copied every tick, fall and divergence checks, trace post-processing); nothing reads the state
between ticks (on grass the drag gate runs inside MuJoCo's step, ``tuner/sim/native_step.c``), so
it runs the walk through MuJoCo's native rollout in chunks of ``NATIVE_CHUNK`` ticks, judged
after each. On grass, ``py-gate`` is the same rollout with the gate in Python between ticks (the
tick loop; ``Simulator(..., native_gate=False)``, what runs where no C compiler is), checked
bit-identical. Its controls are recorded
as MuJoCo applied them each tick (every actuator: the servos' rate-limited targets and the drag
dampers' gate), with its initial state, and played again two ways, so that the physics compared
is the same walk's:

* ``replay``: a Python loop that sets those controls every 10 ms and calls
  ``mj_step(m, d, nstep=5)``, nothing else;
* ``native``: ``mujoco.rollout.rollout`` of the same controls (one control row per physics
  step) from the same state, in C.

Each row checks that both replays end in the rollout's final state (``same``: bit-identical
qpos). Timings are interleaved and the best of ``--repeats`` is kept. Also: real-time factor,
rollouts per hour with 1 and 2 processes, and one robust trial (``kidsize-robust-grass50``'s
set, K = 16 randomised walks per pedestal, no early stop) on 1 and 2 threads, its result checked
identical.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import mujoco
import mujoco.rollout
import numpy as np

import gaits
from tuner.robots import load_robot
from tuner.sim import native_step as native_gate
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def recorded(sim: Simulator, traj) -> tuple[np.ndarray, np.ndarray, np.ndarray, object]:
    """The rollout's initial state, its controls per tick, its final qpos, and its trace."""
    m, d = sim.model, sim.data
    state0 = np.empty(mujoco.mj_stateSize(m, FULL))
    controls: list[np.ndarray] = []

    def first(m_, d_):
        mujoco.mj_getState(m_, d_, state0, FULL)

    def tick(k, d_):
        controls.append(d_.ctrl.copy())

    trace = sim.run(gaits.control.TablePlayer(traj), hooks={0: first}, on_tick=tick)
    return state0, np.array(controls), d.qpos.copy(), trace


def replay(sim: Simulator, state0: np.ndarray, controls: np.ndarray) -> np.ndarray:
    m, d = sim.model, sim.data
    mujoco.mj_setState(m, d, state0, FULL)
    for c in controls:
        d.ctrl[:] = c
        mujoco.mj_step(m, d, nstep=sim.nstep)
    return d.qpos.copy()


def native(sim: Simulator, state0: np.ndarray, per_step: np.ndarray, data: mujoco.MjData) -> np.ndarray:
    """The native rollout's last state (timed: nothing else happens here)."""
    state, _ = mujoco.rollout.rollout(sim.model, data, state0[None], per_step[None])
    return state[0, -1]


def qpos_of(sim: Simulator, state: np.ndarray) -> np.ndarray:
    d = mujoco.MjData(sim.model)
    mujoco.mj_setState(sim.model, d, state, FULL)
    return d.qpos.copy()


def _one(args):
    surface, n = args
    robot = load_robot("kidsize")
    sim = Simulator(robot, SURFACES[surface])
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, sim.control_period)
    t0 = time.perf_counter()
    for _ in range(n):
        sim.rollout(traj)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--pool-rollouts", type=int, default=20)
    args = ap.parse_args()
    robot = load_robot("kidsize")
    native_gate.install()
    print(f"drag gate: {native_gate.status()}")
    print(f"{'surface':8s} {'simulate':>9s} {'replay':>8s} {'native':>8s} {'sim/replay':>10s} {'sim/native':>10s}"
          f" {'RTF':>6s}  same  completed")
    rigid_time = None
    for name in ("rigid", "carpet4", "grass10", "grass30", "grass50"):
        sim = Simulator(robot, SURFACES[name])
        traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, sim.control_period)
        state0, controls, q_end, trace = recorded(sim, traj)
        per_step = np.repeat(controls, sim.nstep, axis=0)
        data = mujoco.MjData(sim.model)
        same = (np.array_equal(replay(sim, state0, controls), q_end)
                and np.array_equal(qpos_of(sim, native(sim, state0, per_step, data)), q_end))
        full, rep, nat, pyg = [], [], [], []
        slow = Simulator(robot, SURFACES[name], native_gate=False) if getattr(sim.ground, "native", False) else None
        if slow is not None:
            a, b = sim.rollout(traj, record_qpos=True), slow.rollout(traj, record_qpos=True)
            same = same and np.array_equal(a.qpos, b.qpos) and np.array_equal(a.force, b.force)
        for _ in range(args.repeats):
            if slow is not None:
                t0 = time.perf_counter()
                slow.rollout(traj)
                pyg.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            sim.rollout(traj)
            full.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            replay(sim, state0, controls)
            rep.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            native(sim, state0, per_step, data)
            nat.append(time.perf_counter() - t0)
        f, r, n_ = min(full), min(rep), min(nat)
        rigid_time = rigid_time or f
        print(f"{name:8s} {f:8.4f}s {r:7.4f}s {n_:7.4f}s {f / r:9.2f}x {f / n_:9.2f}x {traj.duration / f:5.0f}x"
              f"  {'yes' if same else 'NO':>4s}  {trace.completed}   (cost vs rigid simulate: {f / rigid_time:.2f}x)"
              + (f"  py-gate {min(pyg):.4f}s = {min(pyg) / n_:.2f}x native" if pyg else ""))
    n = args.pool_rollouts
    for workers in (1, 2):
        t0 = time.perf_counter()
        with ProcessPoolExecutor(workers) as pool:
            list(pool.map(_one, [("grass50", n // workers)] * workers))
        el = time.perf_counter() - t0
        print(f"{workers} process(es): {n} rollouts of 11 s on grass50 in {el:.2f} s -> "
              f"{n / el * 3600:,.0f} rollouts/hour")
    robust_trial(max(1, args.repeats // 2))


def robust_trial(repeats: int) -> None:
    from dataclasses import replace

    from tuner.search.objective import Evaluator
    from tuner.search.study import load_study
    spec = load_study("kidsize-robust-grass50")
    spec = replace(spec, settings=replace(spec.settings, rollouts=16, min_survival=0.0))
    drive = spec.drive_for({}, source="bench")
    evs = {n: Evaluator(spec, threads=n) for n in (1, 2)}
    times = {1: [], 2: []}
    results = {}
    for _ in range(repeats):
        for n, ev in evs.items():
            t0 = time.perf_counter()
            results[n] = ev.evaluate(drive)
            times[n].append(time.perf_counter() - t0)
    t1, t2 = min(times[1]), min(times[2])
    walks = 16 * len(spec.surfaces)
    print(f"robust trial ({walks} walks): {t1:.2f} s on 1 thread, {t2:.2f} s on 2 ({t1 / t2:.2f}x), "
          f"result identical: {'yes' if results[1] == results[2] else 'NO'}")


if __name__ == "__main__":
    main()
