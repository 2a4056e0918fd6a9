"""Per-face work spread over forked worker processes: `fork_map` runs independent tasks on every core.

`reconstruct` outlines and estimates each face on its own; the work is numpy on small arrays and
scipy's least squares, which hold the GIL (two threads ran slower than one), so the faces go to
processes. They are forked: a task is a closure over the parent's image, masks and ray function,
which the workers inherit without pickling; only task indices and results cross the pipes.

`import_in_background` imports modules in a thread: `reconstruct` imports scipy's modules and the
estimators' while it detects the cubes, before anything forks.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import sys
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed

from raytrace.render import keep_freed_memory, single_threaded_blas

__all__ = ["available_cores", "fork_map", "import_in_background"]

_TASK = None  # the running `fork_map`'s task, inherited by its workers when they fork
_LOCK = threading.Lock()  # one `fork_map` pool at a time per process (it owns `_TASK`)
_IN_WORKER = False  # set in the workers: a task that calls `fork_map` runs it serially


def _worker_start() -> None:
    global _IN_WORKER
    _IN_WORKER = True
    keep_freed_memory()


def _call(i: int):
    return _TASK(i)


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform says, else the count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def fork_map(task, n: int, workers: int | None = None, cost=None, progress=None) -> list:
    """[task(0), ..., task(n − 1)], the tasks run in forked worker processes.

    Parameters
    ----------
    task : callable(int) -> picklable result; a closure is fine (inherited, not pickled)
    n : int, the number of tasks
    workers : int >= 1 or None (every available core); never more than n
    cost : (n,) numbers, optional: the tasks are handed out costliest first, so that a long one
        does not start last while the other workers sit idle
    progress : callable(done, n), optional, called in this process as each task finishes

    The tasks run here, one after another, where processes cannot help or cannot be had: one task
    or one worker, a platform without fork, inside a worker of another `fork_map`, or while another
    thread's `fork_map` holds the pool. The results are the same either way; an exception raised by a
    task is raised here.
    """
    global _TASK
    workers = available_cores() if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"workers: expected an integer >= 1, got {workers}")
    workers = min(workers, n)
    order = sorted(range(n), key=lambda i: -cost[i]) if cost is not None else list(range(n))
    parallel = (workers > 1 and not _IN_WORKER and "fork" in multiprocessing.get_all_start_methods()
                and _LOCK.acquire(blocking=False))
    if not parallel:
        out = [None] * n
        for done, i in enumerate(order, 1):
            out[i] = task(i)
            if progress is not None:
                progress(done, n)
        return out
    try:
        _TASK = task
        out = [None] * n
        with single_threaded_blas(), ProcessPoolExecutor(
                max_workers=workers, mp_context=multiprocessing.get_context("fork"),
                initializer=_worker_start) as pool:
            futures = {pool.submit(_call, i): i for i in order}
            try:
                for done, fut in enumerate(as_completed(futures), 1):
                    out[futures[fut]] = fut.result()
                    if progress is not None:
                        progress(done, n)
            except BaseException:
                pool.shutdown(wait=True, cancel_futures=True)
                raise
        return out
    finally:
        _TASK = None
        _LOCK.release()


def import_in_background(names) -> Callable[[], None]:
    """Import the modules `names` not imported yet in a thread; returns the function that waits for it.

    An import runs Python code and holds the GIL, while numpy's and OpenCV's work on whole images mostly
    lets go of it, so an import overlaps such work. Until the returned function is called, the caller
    must import nothing itself (two threads importing modules that import each other can deadlock) and
    must not fork (`fork_map`: a process forked during an import inherits its held locks). An import
    that fails here is left to fail again, with its error, where the module is used.
    """
    todo = [name for name in names if name not in sys.modules]
    if not todo:
        return lambda: None

    def run():
        for name in todo:
            try:
                importlib.import_module(name)
            except ImportError:  # raised again, in the caller's thread, where the module is first used
                return

    thread = threading.Thread(target=run, name="import_in_background", daemon=True)
    thread.start()
    return thread.join
