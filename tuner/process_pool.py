"""Walks spread over processes: forked workers (a worker starts in milliseconds and inherits
the parent's loaded robot), results in task order whatever the number of workers.

Every worker dies with its parent, whatever ends the parent (SIGKILL included: Linux's
``PR_SET_PDEATHSIG``), and ignores Ctrl-C: the parent decides what an interrupt stops, ends its
workers and says so in one line; no worker prints a traceback."""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
from typing import Any, Callable, Iterator, Sequence

__all__ = ["mp_context", "map_in_order", "die_with_parent", "forking_without_ctrl_c", "ignore_ctrl_c"]


@contextlib.contextmanager
def forking_without_ctrl_c() -> Iterator[None]:
    """Block SIGINT in this thread while it forks workers: a Ctrl-C (sent to the whole process group)
    that lands in a child between its fork and its :func:`ignore_ctrl_c` would raise in Python's own
    after-fork code there and print a traceback. The child inherits the blocked mask; the parent
    takes a Ctrl-C that came meanwhile when the block ends."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def ignore_ctrl_c() -> None:
    """In a worker: Ctrl-C is the parent's to handle; then SIGINT unblocked (a pending one is dropped)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def die_with_parent(parent: int) -> None:
    """Linux: the kernel kills this process when its parent dies (no orphaned workers); a parent
    already gone ends it at once."""
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)    # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:
        os._exit(1)


def _pool_worker(parent: int) -> None:
    die_with_parent(parent)
    ignore_ctrl_c()                                    # the parent decides what Ctrl-C stops


def mp_context() -> Any:
    """fork on Linux; spawn (which re-imports MuJoCo, Optuna and CasADi) elsewhere."""
    return mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")


def map_in_order(fn: Callable[[Any], Any], tasks: Sequence[Any], workers: int,
                 progress: Callable[[int], None] | None = None, chunksize: int = 1) -> list[Any]:
    """``[fn(t) for t in tasks]`` on ``workers`` processes; ``progress(1)`` after each result."""
    rows: list[Any] = []
    if workers > 1 and len(tasks) > 1:
        with forking_without_ctrl_c():
            pool = mp_context().Pool(min(workers, len(tasks)), initializer=_pool_worker, initargs=(os.getpid(),))
        with pool:
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
