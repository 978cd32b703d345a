"""Rollout throughput: ``Simulator.rollout`` against a bare ``mj_step`` loop, side by side.

Usage: ``python benchmarks/bench_simulate.py [--repeats 5]``

For each surface, one model, one gait (TLIPFM Table 2, 10.96 s): the bare loop
sets the same joint targets every 10 ms and calls ``mj_step(m, d, nstep=5)``,
nothing else; ``simulate`` is the full rollout (rate limiter, drag, sensors
copied every tick, fall and divergence checks, trace post-processing). Timings
are interleaved and the best of ``--repeats`` is kept, on this machine, in
one run. Also: real-time factor, and rollouts per hour with 1 and 2 processes.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import mujoco
import numpy as np

import gaits
from tuner.robots import load_robot
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES


def bare_loop(sim: Simulator, q_ref: np.ndarray) -> None:
    m, d = sim.model, sim.data
    sim._place(q_ref[0], np.zeros(2))
    for k in range(1, len(q_ref)):
        d.ctrl[:sim._n_servo] = q_ref[k]
        mujoco.mj_step(m, d, nstep=sim.nstep)


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
    print(f"{'surface':8s} {'bare [s]':>9s} {'simulate [s]':>12s} {'ratio':>6s} {'RTF':>6s}  completed")
    rigid_time = None
    for name in ("rigid", "carpet4", "grass10", "grass30", "grass50"):
        sim = Simulator(robot, SURFACES[name])
        traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, sim.control_period)
        q_ref = traj.q_ref[:, sim._col_in_gait] * sim._sign
        bare, full = [], []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            bare_loop(sim, q_ref)
            bare.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            trace = sim.rollout(traj)
            full.append(time.perf_counter() - t0)
        b, f = min(bare), min(full)
        rigid_time = rigid_time or f
        print(f"{name:8s} {b:9.4f} {f:12.4f} {b / f:6.0%} {traj.duration / f:6.0f}x  {trace.completed}"
              f"   (cost vs rigid simulate: {f / rigid_time:.2f}x)")
    n = args.pool_rollouts
    for workers in (1, 2):
        t0 = time.perf_counter()
        with ProcessPoolExecutor(workers) as pool:
            list(pool.map(_one, [("grass50", n // workers)] * workers))
        el = time.perf_counter() - t0
        print(f"{workers} process(es): {n} rollouts of 11 s on grass50 in {el:.2f} s -> "
              f"{n / el * 3600:,.0f} rollouts/hour")


if __name__ == "__main__":
    main()
