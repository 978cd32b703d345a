"""Walks spread over processes: forked workers (a worker starts in milliseconds and inherits
the parent's loaded robot), results in task order whatever the number of workers."""

from __future__ import annotations

import multiprocessing as mp
from typing import Any, Callable, Sequence

__all__ = ["mp_context", "map_in_order"]


def mp_context() -> Any:
    """fork on Linux; spawn (which re-imports MuJoCo, Optuna and CasADi) elsewhere."""
    return mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")


def map_in_order(fn: Callable[[Any], Any], tasks: Sequence[Any], workers: int,
                 progress: Callable[[int], None] | None = None, chunksize: int = 1) -> list[Any]:
    """``[fn(t) for t in tasks]`` on ``workers`` processes; ``progress(1)`` after each result."""
    rows: list[Any] = []
    if workers > 1 and len(tasks) > 1:
        with mp_context().Pool(min(workers, len(tasks))) as pool:
            for row in pool.imap(fn, tasks, chunksize=chunksize):
                rows.append(row)
                if progress is not None:
                    progress(1)
    else:
        for task in tasks:
            rows.append(fn(task))
            if progress is not None:
                progress(1)
    return rows
