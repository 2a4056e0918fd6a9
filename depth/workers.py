"""Per-face work spread over forked worker processes: `fork_map` runs independent tasks on every core.

`reconstruct` outlines and estimates each face on its own; the work is numpy on small arrays and
scipy's least squares, which hold the GIL (two threads ran slower than one), so the faces go to
processes. They are forked: a task is a closure over the parent's image, masks and ray function,
which the workers inherit without pickling; only task indices and results cross the pipes.

`fork_helper` forks a process at once that imports modules while this one goes on, then runs one task
on what this process sends it: `reconstruct`'s helper (forked by `depth.reconstruct.start_helper` before the
image is read, or on `reconstruct`'s first call in a process) imports scipy's modules and the estimators' on
the other core while this one reads the image and detects the cubes (in a thread here, the import held the
GIL against the detection: 0.3–0.5 s of a 2048×1536 image's 2.6–3.2 s), then outlines and estimates the
faces. A helper forked before its task is known takes the task with its first payload, and the arrays it is
to share with this process in a `SharedMemory` made before the fork. `import_in_background` imports modules
in a thread: where no helper can be forked, and on `reconstruct`'s second call.
"""

from __future__ import annotations

import atexit
import contextlib
import importlib
import mmap
import multiprocessing
import os
import signal
import sys
import tempfile
import threading
import weakref
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, as_completed, wait
from multiprocessing.reduction import ForkingPickler

import numpy as np

from raytrace.render import keep_freed_memory, single_threaded_blas

__all__ = ["available_cores", "fork_map", "fork_chain", "fork_helper", "will_fork_helper", "SharedMemory", "Helper",
           "Inbox", "import_in_background"]

_TASK = None  # the running `fork_map`'s task, inherited by its workers when they fork
_LOCK = threading.Lock()  # one `fork_map` pool at a time per process (it owns `_TASK`)
_IN_WORKER = False  # set in the workers: a task that calls `fork_map` runs it serially


def opencv_serial() -> None:
    """OpenCV's own thread pool turned off in this (forked) process, where the parent had OpenCV loaded. A
    process forked while one of the parent's OpenCV pool threads held the pool's lock inherits the lock held, and
    its first parallel OpenCV call waits for ever (opencv/opencv#5150): `bench.holdout` hung so, in a worker's
    `cv2.connectedComponentsWithStats`, with the machine busy; a parent running one parallel OpenCV call before each
    fork hung 7 of 1100 children under load (three runs), none of 1100 with this. The forked processes are one per
    core already."""
    cv2 = sys.modules.get("cv2")
    if cv2 is not None:
        cv2.setNumThreads(0)


def _worker_start() -> None:
    global _IN_WORKER
    _IN_WORKER = True
    opencv_serial()
    keep_freed_memory()


def _call(i: int):
    return _TASK(i)


def _call_first(i: int):
    return _TASK[0](i)


def _call_second(i: int, arg):
    return _TASK[1](i, arg)


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform says, else the count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _can_fork() -> bool:
    return not _IN_WORKER and "fork" in multiprocessing.get_all_start_methods()


def _pool_plan(n: int, workers, cost) -> tuple[int, list, bool]:
    """(workers, the tasks' order, whether they run in a pool: the pool's lock is then taken and must be
    released) for `fork_map` and `fork_chain`."""
    workers = available_cores() if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"workers: expected an integer >= 1, got {workers}")
    workers = min(workers, n)
    order = sorted(range(n), key=lambda i: -cost[i]) if cost is not None else list(range(n))
    return workers, order, workers > 1 and _can_fork() and _LOCK.acquire(blocking=False)


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
    workers, order, parallel = _pool_plan(n, workers, cost)
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


def fork_chain(first, second, n: int, plan, workers: int | None = None, cost=None) -> tuple[list, list]:
    """Two stages of tasks in one pool of forked worker processes: ([first(0), ..., first(n − 1)], and per i
    second(i, arg) where plan(i, first(i)) gives (cost, arg), else None).

    Parameters
    ----------
    first : callable(int) -> picklable result; a closure is fine (inherited, not pickled)
    second : callable(int, arg) -> picklable result; inherited, its `arg` pickled
    n : int, the number of first tasks
    plan : callable(i, first's result) -> (cost, arg) or None, called in this process as each first task ends
    workers : int >= 1 or None (every available core); never more than n
    cost : (n,) numbers, optional: the first tasks are handed out costliest first

    A task is handed to a worker only as one comes free: the first tasks before any second one, then the
    costliest second task ready. So a worker that ends its last first task starts a second one while the
    others still run theirs, where two `fork_map` pools, one a stage, would leave it idle until they end and
    then fork the second pool's workers (on a 2048×1536 image's faces, outlined then estimated: 0.04–0.09 s
    of a core idle). Run here, one task after another, where `fork_map` would be; the results do not
    depend on it. An exception raised by a task is raised here.
    """
    global _TASK
    workers, order, parallel = _pool_plan(n, workers, cost)
    firsts, seconds = [None] * n, [None] * n
    if not parallel:
        ready = []
        for i in order:
            firsts[i] = first(i)
            if (planned := plan(i, firsts[i])) is not None:
                ready.append((planned[0], i, planned[1]))
        for _, i, arg in sorted(ready, key=lambda item: -item[0]):
            seconds[i] = second(i, arg)
        return firsts, seconds
    try:
        _TASK = (first, second)
        ready = []  # (cost, i, arg) of the second tasks not handed out yet
        running = {}  # future: (stage, i)
        todo = list(order)
        with single_threaded_blas(), ProcessPoolExecutor(
                max_workers=workers, mp_context=multiprocessing.get_context("fork"),
                initializer=_worker_start) as pool:
            try:
                while todo or ready or running:
                    while len(running) < workers and (todo or ready):
                        if todo:
                            i = todo.pop(0)
                            running[pool.submit(_call_first, i)] = (0, i)
                        else:
                            k = max(range(len(ready)), key=lambda j: ready[j][0])
                            _, i, arg = ready.pop(k)
                            running[pool.submit(_call_second, i, arg)] = (1, i)
                    done, _ = wait(running, return_when=FIRST_COMPLETED)
                    for fut in done:
                        stage, i = running.pop(fut)
                        if stage == 0:
                            firsts[i] = fut.result()
                            if (planned := plan(i, firsts[i])) is not None:
                                ready.append((planned[0], i, planned[1]))
                        else:
                            seconds[i] = fut.result()
            except BaseException:
                pool.shutdown(wait=True, cancel_futures=True)
                raise
        return firsts, seconds
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


class Helper:
    """A process forked by `fork_helper`: `run` sends it a payload and returns its task's result. Payloads
    sent before (`send`) reach the task first: the first starts it, the others wait in its `Inbox`, as does
    `run`'s where one was sent before it."""

    def __init__(self, process, conn):
        self._process, self._conn, self._done = process, conn, False
        self._writing = None  # the thread writing `send`'s last payload to the pipe

    def send(self, payload) -> None:
        """Send the helper a payload without waiting: the first one sent starts its task, which works on it
        while this process goes on; the others are its `Inbox`'s, in order. It is pickled here and written to
        the pipe by a thread: a payload larger than the pipe holds waits there until the helper reads it,
        which it does only once it has imported its modules (the parent of `depth.reconstruct` sat 0.14 s
        in that write)."""
        data = ForkingPickler.dumps(payload)
        self._written()

        def write():
            with contextlib.suppress(OSError):  # the helper has gone: `run` or `close` says so
                self._conn.send_bytes(data)
        self._writing = threading.Thread(target=write, name="Helper.send", daemon=True)
        self._writing.start()

    def _written(self) -> None:
        """Wait for `send`'s last payload to be written."""
        if self._writing is not None:
            self._writing.join()
            self._writing = None

    def run(self, payload, progress=None):
        """Send the helper `payload` (`send`), then wait for its task's result, or its exception, raised
        here. `progress` (callable(done, total), optional) is called here for each call the task makes of
        its own."""
        try:
            self._written()
            with contextlib.suppress(BrokenPipeError, ConnectionResetError):
                # (the helper has ended: the error it sent, or its end without one, is read below)
                self._conn.send(payload)
            while True:
                try:
                    kind, *rest = self._conn.recv()
                except EOFError:
                    self._process.join(timeout=1.0)
                    raise RuntimeError(f"the helper process ended without a result "
                                       f"(exit code {self._process.exitcode})") from None
                if kind == "progress":
                    if progress is not None:
                        progress(*rest)
                else:
                    self._done = True
                    if kind == "result":
                        return rest[0]
                    raise rest[0]
        finally:
            self.close()

    def close(self) -> None:
        """End the helper and wait for it: one that has sent its result ends by itself; one still importing
        or running its task (this process is leaving early, on an error or an interrupt) is terminated,
        with the workers it forked."""
        if self._process is None:
            return
        process, self._process = self._process, None
        if self._writing is not None:  # a payload still being written: the helper reads no more of it
            if process.is_alive():
                _end_group(process)
            self._written()
        self._conn.close()
        if self._done:
            process.join(timeout=5.0)
        if process.is_alive():
            _end_group(process)
        process.join()


class Inbox:
    """The payloads sent to a helper after the one its task started on (`Helper.send`, `Helper.run`)."""

    def __init__(self, conn):
        self._conn = conn

    def ready(self) -> bool:
        """Whether the next payload has come."""
        return self._conn.poll()

    def get(self):
        """The next payload, waited for (EOFError where the parent closed the helper first)."""
        return self._conn.recv()


def _helper_main(conn, task, modules, parent_end) -> None:
    opencv_serial()
    parent_end.close()  # (inherited: held here, it would keep `recv` from seeing the parent leave)
    _own_group(os.getpid())
    for name in modules:
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001 - raised again, with its error, where the module is used
            break
    try:
        payload = conn.recv()
    except EOFError:  # the parent closed the helper (or ended) before sending anything
        return
    try:
        if task is None:  # the task came with the payload (`fork_helper`)
            task, payload = payload
        result = ("result", task(payload, lambda *args: conn.send(("progress",) + args), Inbox(conn)))
    except BaseException as exc:  # noqa: BLE001 - raised again in the parent
        result = ("error", exc)
    gone = (BrokenPipeError, ConnectionResetError)  # the parent has gone (an interrupt): nobody to tell
    try:
        conn.send(result)
    except gone:
        return
    except Exception as exc:  # an unpicklable result or exception (pickled before anything is sent): its message
        with contextlib.suppress(*gone):
            conn.send(("error", RuntimeError(f"{type(exc).__name__}: {exc} (sending the helper's {result[0]})")))
    conn.close()


def _end_group(process) -> None:
    """End a helper and the workers it forked (its process group: `_own_group`)."""
    try:
        os.killpg(process.pid, signal.SIGTERM)
    except OSError:
        process.terminate()


def _own_group(pid: int) -> None:
    """Put process `pid` (a helper) in a process group of its own, which its workers join as it forks them:
    a Ctrl-C at the terminal then reaches this process alone, which ends the helper's group as a whole
    (`Helper.close`). (Interrupted with the rest, the helper printed an import's traceback, or was ended
    before its workers, which then waited for it for ever.) Called by both processes, so that whichever
    runs first does it."""
    with contextlib.suppress(OSError):  # already done by the other side, or the helper has ended
        os.setpgid(pid, pid)


def will_fork_helper(modules) -> bool:
    """Whether `fork_helper(task, modules)` called now would fork a helper (some of `modules` are not
    imported yet, and this process can fork)."""
    return any(name not in sys.modules for name in modules) and _can_fork()


class SharedMemory:
    """Memory shared with the processes forked after it is made: a memfd (an unlinked temporary file where the
    platform has none), which this process sizes and maps as arrays (`arrays`) once it knows their shapes, and
    which those processes map as the same arrays when they are told the shapes: what one writes, the others
    read. It pickles as its file descriptor, which those processes hold too (inherited at the fork), so it
    may go to them in a payload; anywhere else it is not the same memory. `close` it in each process once
    mapped (the mappings outlive it)."""

    def __init__(self, fd: int | None = None):
        if fd is not None:  # (unpickled: the descriptor inherited from the process that made it)
            self.fd = fd
        elif hasattr(os, "memfd_create"):
            self.fd = os.memfd_create("depth.workers.SharedMemory")
        else:
            self.fd, path = tempfile.mkstemp(prefix="depth-workers-")
            os.unlink(path)

    def __reduce__(self):
        return SharedMemory, (self.fd,)

    def arrays(self, specs) -> list[np.ndarray]:
        """Arrays of the given (shape, dtype) pairs, one after another in this memory, zeroed where nobody
        has written yet; the same specs give the same arrays in every process that shares it."""
        specs = [(tuple(int(n) for n in shape), np.dtype(dtype)) for shape, dtype in specs]
        counts = [int(np.prod(shape)) for shape, _ in specs]
        offsets, end = [], 0
        for (_, dtype), count in zip(specs, counts):
            offsets.append(end)
            end += -(-count * dtype.itemsize // 64) * 64  # each array 64-byte aligned
        end = max(end, 1)
        if os.fstat(self.fd).st_size < end:
            os.ftruncate(self.fd, end)
        buffer = mmap.mmap(self.fd, end)  # MAP_SHARED
        return [np.frombuffer(buffer, dtype=dtype, count=count, offset=offset).reshape(shape)
                for (shape, dtype), count, offset in zip(specs, counts, offsets)]

    def close(self) -> None:
        """Close this process's descriptor (its arrays stay mapped); twice does nothing."""
        fd, self.fd = self.fd, -1
        if fd >= 0:
            os.close(fd)


def fork_helper(task, modules) -> Helper | None:
    """A process forked now, which imports `modules` (those not imported here yet) while this process goes
    on, then waits for the first payload sent (`Helper.send` or `Helper.run`) and runs
    task(payload, progress, inbox) on it (`inbox`: an `Inbox` of the payloads sent after it); or None where no
    helper is worth forking (every module imported already) or none can be (no fork on this platform, or
    inside a `fork_map` worker).

    The task is inherited, not pickled: it may be a closure over this process's state as it is now (an
    image, a camera). Only the payload, the progress calls and the result cross the pipe. With task None,
    the helper is forked before its task is known: the first payload is then (task, payload), the task
    pickled by reference (a module-level function), and what it shares with this process goes in a
    `SharedMemory` made before this call. A helper must be `Helper.run` or `Helper.close`d. Fork it before
    starting threads (`import_in_background`, a thread reading a file): a process forked while another
    thread holds a lock (an import's, a library's) inherits it held."""
    if not will_fork_helper(modules):
        return None
    todo = tuple(name for name in modules if name not in sys.modules)
    ctx = multiprocessing.get_context("fork")
    here, there = ctx.Pipe()
    process = ctx.Process(target=_helper_main, args=(there, task, todo, here), name="fork_helper")
    process.start()
    _own_group(process.pid)
    there.close()
    helper = Helper(process, here)
    _OPEN_HELPERS.add(helper)
    return helper


_OPEN_HELPERS = weakref.WeakSet()  # the helpers forked here, to be closed when this process exits


@atexit.register
def _close_open_helpers() -> None:
    """Close the helpers this process leaves open as it exits. Registered after multiprocessing's own exit
    handler (imported above), so run before it: that one waits for every child process, and a helper still
    waiting for its first payload would wait for ever (`start_helper` without a `reconstruct` call)."""
    for helper in list(_OPEN_HELPERS):
        helper.close()
