"""Where a study's trial walks: its robot, one simulator per surface, and how walks are spread
over threads. Built once per worker (``tuner/search/objective.py``'s :class:`Evaluator` is one)
and handed to a scenario's ``evaluate``."""

from __future__ import annotations

import queue
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Iterator, Sequence

import numpy as np

import gaits

from ..sim import cache as sim_cache
from ..sim.metrics import planned_forward_distance
from ..sim.randomisation import TUNE
from ..sim.rollout import Simulator

__all__ = ["World"]


class World:
    """The study's robot on each of its surfaces.

    ``threads``: the walks of one surface that a trial makes (a robust trial's randomised walks,
    an engine study's match walks, a speed study's directions) run on this many threads, each
    on its own copy of the surface's simulator (MuJoCo steps without Python's lock, so two
    threads walk ~1.9x as fast on 2 cores while the tick logic is light); the walks are the same
    and are consumed in order, so the result, the early stop included, is the one-at-a-time
    result (tested). ``namespace``: the seed stream randomised walks draw from (tuning's)."""

    def __init__(self, robot: str, surfaces: Sequence[str], *, aggregate: str = "worst",
                 duration: float | None = None, threads: int = 1, namespace: int = TUNE) -> None:
        self.robot = sim_cache.robot(robot)
        self.surfaces = tuple(surfaces)
        self.sims = [sim_cache.simulator(self.robot, s) for s in self.surfaces]
        self.aggregate_rule = aggregate
        self.duration = duration
        self.threads = threads
        self.namespace = namespace
        self._copies: dict[int, "queue.SimpleQueue"] = {}
        self._with_pendulum: dict[float, list[Simulator]] = {}

    @property
    def control_period(self) -> float:
        return self.sims[0].control_period

    def aggregate(self, scores: Sequence[float]) -> float:
        """The study's aggregate over surfaces of a score to minimise: the worst (max) or the mean."""
        return float(max(scores) if self.aggregate_rule == "worst" else np.mean(scores))

    def sims_with_pendulum(self, rope: float, bottle: Any = None) -> list[Simulator]:
        """One simulator per surface with the challenge's ``bottle`` (default: the 2019 rules') on a
        rope of ``rope`` m (built on first use, kept)."""
        from ..sim.scene import BOTTLE_2019
        bottle = bottle or BOTTLE_2019
        if (rope, bottle) not in self._with_pendulum:
            self._with_pendulum[(rope, bottle)] = [Simulator(self.robot, sim.surface, pendulum=rope, bottle=bottle)
                                                   for sim in self.sims]
        return self._with_pendulum[(rope, bottle)]

    def plan(self, drive: gaits.Drive) -> tuple[Any, float, float]:
        """(table, planned walking time [s], planned forward distance [m]) of what ``drive`` walks:
        an online drive has no table (its walk lasts the study's duration) and is built once, so a
        controller that cannot be built is refused at once. ParamError or UnreachableTargetError
        for a set that cannot be walked."""
        dt = self.control_period
        if drive.online:
            drive.controller(self.robot, dt)
            return None, float(self.duration), 0.0
        traj = drive.table(self.robot, dt)
        planned = traj.duration - float(traj.t[np.flatnonzero(traj.support != 0)[0]]) \
            if np.any(traj.support != 0) else traj.duration
        return traj, planned, planned_forward_distance(traj)

    def in_order(self, n: int, walk: Callable[[Any, int], Any],
                 sims: list | None = None) -> Iterator[tuple[str, Any]]:
        """``(surface, walk(simulator, i))`` for every surface in turn and i in 0..n-1, yielded in
        that order; on ``self.threads`` threads when more than one (one stream over all surfaces,
        so no thread waits at a surface's end), each walk on a free copy of its surface's
        simulator (of ``sims``, one per surface, when given: the challenge's, with its pendulum);
        what the caller does not consume is cancelled."""
        sims = self.sims if sims is None else sims
        tasks = [(name, sim, i) for name, sim in zip(self.surfaces, sims) for i in range(n)]
        if self.threads <= 1 or len(tasks) <= 1:
            for name, sim, i in tasks:
                yield name, walk(sim, i)
            return
        for sim in sims:
            if id(sim) not in self._copies:
                free = self._copies[id(sim)] = queue.SimpleQueue()
                free.put(sim)
                for _ in range(self.threads - 1):
                    free.put(Simulator(self.robot, sim.surface, pendulum=sim.rope, bottle=sim.bottle))

        def task(sim: Any, i: int) -> Any:
            free = self._copies[id(sim)]
            s = free.get()
            try:
                return walk(s, i)
            finally:
                free.put(s)
        with ThreadPoolExecutor(self.threads) as pool:
            futures = [(name, pool.submit(task, sim, i)) for name, sim, i in tasks]
            try:
                for name, f in futures:
                    yield name, f.result()
            finally:
                for _, f in futures:
                    f.cancel()
