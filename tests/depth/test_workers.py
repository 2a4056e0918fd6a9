"""Tests of `depth.workers.fork_map`: the same results as a plain loop, run in other processes."""

import os

import numpy as np
import pytest

from depth.workers import available_cores, fork_map


def test_results_come_back_in_task_order_from_forked_processes():
    data = np.arange(10) ** 2  # a closure over this process's state, inherited by the workers
    out = fork_map(lambda i: (int(data[i]), os.getpid()), 7, workers=2, cost=[3, 1, 4, 1, 5, 9, 2])
    assert [v for v, _ in out] == [i * i for i in range(7)]
    pids = {p for _, p in out}
    assert os.getpid() not in pids and 1 <= len(pids) <= 2


def test_one_worker_runs_here():
    assert {p for p in fork_map(lambda i: os.getpid(), 3, workers=1)} == {os.getpid()}


def test_progress_counts_every_task_in_this_process():
    calls = []
    fork_map(lambda i: i, 5, workers=2, progress=lambda done, total: calls.append((done, total, os.getpid())))
    assert [(d, t) for d, t, _ in calls] == [(k, 5) for k in range(1, 6)]
    assert {p for _, _, p in calls} == {os.getpid()}


def test_the_costliest_tasks_are_handed_out_first():
    # serially (one worker) the hand-out order is the order they run in
    seen = []
    fork_map(lambda i: seen.append(i), 4, workers=1, cost=[1.0, 7.0, 3.0, 5.0])
    assert seen == [1, 3, 2, 0]


def test_a_task_error_is_raised_here():
    def task(i):
        if i == 2:
            raise ValueError("task 2 failed")
        return i
    with pytest.raises(ValueError, match="task 2 failed"):
        fork_map(task, 4, workers=2)


def test_a_task_may_itself_map_without_forking_again():
    outer = os.getpid()
    out = fork_map(lambda i: fork_map(lambda j: (i, j, os.getpid()), 2, workers=2), 2, workers=2)
    for i, inner in enumerate(out):
        assert [(a, b) for a, b, _ in inner] == [(i, 0), (i, 1)]
        pids = {p for _, _, p in inner}
        assert len(pids) == 1 and outer not in pids  # both in the worker that ran task i


def test_no_tasks_and_bad_worker_counts():
    assert fork_map(lambda i: i, 0) == []
    with pytest.raises(ValueError, match="workers"):
        fork_map(lambda i: i, 3, workers=0)
    assert available_cores() >= 1


def test_import_in_background_imports_the_modules_it_is_given(tmp_path, monkeypatch):
    import sys
    import threading

    from depth.workers import import_in_background
    (tmp_path / "bg_first.py").write_text("import bg_second\nVALUE = bg_second.VALUE + 1\n")
    (tmp_path / "bg_second.py").write_text("VALUE = 41\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ("bg_first", "bg_second"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    before = threading.active_count()
    wait = import_in_background(["bg_first"])
    wait()
    assert sys.modules["bg_first"].VALUE == 42 and "bg_second" in sys.modules
    assert threading.active_count() == before  # the thread has ended once waited for
    # modules already imported: no thread at all
    started = []
    monkeypatch.setattr(threading.Thread, "start", lambda self: started.append(self))
    import_in_background(["bg_first", "numpy"])()
    assert started == []


def test_import_in_background_leaves_a_failed_import_to_the_caller(tmp_path, monkeypatch, capfd):
    import sys

    from depth.workers import import_in_background
    (tmp_path / "bg_broken.py").write_text("raise ImportError('bg_broken: no such thing')\n")
    (tmp_path / "bg_after.py").write_text("VALUE = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ("bg_broken", "bg_after"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    import_in_background(["bg_broken", "bg_after"])()
    assert "bg_broken" not in sys.modules and "bg_after" not in sys.modules  # stopped at the failure
    assert capfd.readouterr().err == ""  # nothing printed from the thread
    with pytest.raises(ImportError, match="no such thing"):
        __import__("bg_broken")


def test_the_estimators_scipy_modules_are_not_imported_with_the_package():
    # `depth.reconstruct` imports them beside the detection (`import_in_background`), which only
    # saves time when importing the package has not already done it
    import subprocess
    import sys

    from depth.estimate import SOLVER_MODULES
    code = ("import sys, depth.reconstruct, catadioptric.reconstruct; "
            f"print(sorted(set({list(SOLVER_MODULES)!r}) & set(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize("workers", [1, 2])
def test_fork_chain_runs_the_second_tasks_planned_on_the_first_ones_results(workers):
    from depth.workers import fork_chain
    data = np.arange(6) * 3  # inherited by the workers
    planned = []

    def plan(i, result):  # here, as each first task ends
        planned.append((i, os.getpid()))
        return None if i % 3 == 0 else (float(i), np.full(2, result[0]))  # the arg goes to the worker pickled

    firsts, seconds = fork_chain(lambda i: (int(data[i]), os.getpid()),
                                 lambda i, arg: (int(arg.sum()) + i, os.getpid()), 6, plan, workers=workers,
                                 cost=[1, 5, 2, 6, 3, 4])
    assert [v for v, _ in firsts] == [0, 3, 6, 9, 12, 15]
    assert [None if s is None else s[0] for s in seconds] == [None, 7, 14, None, 28, 35]
    assert sorted(i for i, _ in planned) == list(range(6)) and {p for _, p in planned} == {os.getpid()}
    pids = {p for _, p in firsts} | {s[1] for s in seconds if s is not None}
    assert (os.getpid() in pids) == (workers == 1)


def test_fork_chain_starts_a_second_task_while_a_first_one_still_runs(tmp_path):
    """A worker that ends its first tasks takes a second one at once, while the other still runs a long first
    task: no stage waits for the whole of the one before it. With one worker, the order is the first tasks,
    costliest first, then the second ones, costliest first."""
    import time

    from depth.workers import fork_chain

    def first(i):
        if i == 0:
            time.sleep(1.5)
        return time.perf_counter()  # (CLOCK_MONOTONIC: one clock for every process)

    def second(i, arg):
        return time.perf_counter()

    firsts, seconds = fork_chain(first, second, 3, lambda i, end: (float(i), None) if i else None, workers=2,
                                 cost=[3.0, 2.0, 1.0])
    assert seconds[0] is None and seconds[1] < firsts[0] and seconds[2] < firsts[0]
    order = []
    fork_chain(lambda i: order.append(("first", i)), lambda i, arg: order.append(("second", i)), 3,
               lambda i, _: (float(i), None), workers=1, cost=[1.0, 3.0, 2.0])
    assert order == [("first", 1), ("first", 2), ("first", 0), ("second", 2), ("second", 1), ("second", 0)]


def test_fork_chain_raises_a_task_error_here():
    from depth.workers import fork_chain

    def second(i, arg):
        raise ValueError(f"face {i}: {arg}")

    with pytest.raises(ValueError, match="face 1: x"):
        fork_chain(lambda i: i, second, 3, lambda i, _: (1.0, "x") if i == 1 else None, workers=2)


def _fresh_module(tmp_path, monkeypatch, name, body="VALUE = 7\n"):
    """A module `name` importable from tmp_path and not imported in this process."""
    import sys
    (tmp_path / f"{name}.py").write_text(body)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, name, raising=False)


def test_a_helper_imports_its_modules_there_and_runs_its_task_on_the_payload(tmp_path, monkeypatch):
    import sys

    from depth.workers import fork_helper
    _fresh_module(tmp_path, monkeypatch, "helper_mod")
    state = np.arange(6) * 10  # this process's state when the helper forks: inherited, not sent

    def task(payload, progress, inbox):
        for k in range(3):
            progress(k + 1, 3)
        return int(state[payload]) + sys.modules["helper_mod"].VALUE, os.getpid()

    helper = fork_helper(task, ["helper_mod", "numpy"])
    assert helper is not None
    state[4] = -1  # changed here after the fork: the helper keeps its own copy
    calls = []
    value, pid = helper.run(4, progress=lambda done, total: calls.append((done, total, os.getpid())))
    assert value == 47 and pid != os.getpid()
    assert [(d, t) for d, t, _ in calls] == [(1, 3), (2, 3), (3, 3)] and {p for *_, p in calls} == {os.getpid()}
    assert "helper_mod" not in sys.modules  # imported in the helper only


def test_a_helper_starts_on_the_first_payload_sent_and_takes_the_later_ones_from_its_inbox(tmp_path, monkeypatch):
    import time

    from depth.workers import fork_helper
    _fresh_module(tmp_path, monkeypatch, "helper_mod5")

    def task(first, progress, inbox):
        # the first payload's work, done while nothing else has come; then the second, waited for
        waited = not inbox.ready()  # (before "started": the test sends the second payload only after it)
        (tmp_path / "starting").write_text(str(first))
        os.replace(tmp_path / "starting", tmp_path / "started")  # whole when the poll below sees it
        second = inbox.get()
        return first, second, waited, inbox.ready()

    helper = fork_helper(task, ["helper_mod5"])
    helper.send([1, 2])
    deadline = time.perf_counter() + 30
    while not (tmp_path / "started").exists() and time.perf_counter() < deadline:
        time.sleep(0.02)
    assert (tmp_path / "started").read_text() == "[1, 2]"  # at work before `run` sent anything more
    assert helper.run({"rest": 3}) == ([1, 2], {"rest": 3}, True, False)


def test_a_payload_larger_than_the_pipe_is_sent_without_waiting_for_the_helper_to_read_it(tmp_path, monkeypatch):
    # The helper reads its first payload only once it has imported its modules; the parent goes on meanwhile.
    # Here the helper's module import waits (up to 60 s) for a file the parent writes after `send` returns.
    from depth.workers import fork_helper
    flag = tmp_path / "sent"
    body = (f"import pathlib, time\n"
            f"deadline = time.perf_counter() + 60.0\n"
            f"while not pathlib.Path({str(flag)!r}).exists() and time.perf_counter() < deadline:\n"
            f"    time.sleep(0.02)\n"
            f"SAW_IT = pathlib.Path({str(flag)!r}).exists()\n")
    _fresh_module(tmp_path, monkeypatch, "helper_mod6", body)

    def task(payload, progress, inbox):
        import sys
        return sys.modules["helper_mod6"].SAW_IT, int(payload.sum()), inbox.get()

    helper = fork_helper(task, ["helper_mod6"])
    big = np.ones(4_000_000, dtype=np.uint8)  # 4 MB, many times a pipe's buffer
    helper.send(big)
    flag.write_text("")
    assert helper.run("rest") == (True, 4_000_000, "rest")


_PRIVATE = np.zeros(3)  # this module's own state: a forked helper has its copy as it was at the fork


def _read_shared(job, progress, inbox):
    """A helper task sent with its first payload (pickled by reference): once the next payload comes, the
    values at fixed places of the arrays `job` describes in its shared memory, and of `_PRIVATE`."""
    memory, specs = job
    image, flags = memory.arrays(specs)
    memory.close()
    rest = inbox.get()
    return float(image[2, 1, 0]), int(flags[4]), float(_PRIVATE[1]), rest


@pytest.mark.parametrize("memfd", [True, False])
def test_shared_memory_written_after_the_fork_is_read_by_a_helper_given_its_task_with_the_payload(
        tmp_path, monkeypatch, memfd):
    """A helper forked before its task and its arrays' shapes are known (`fork_helper(None, ...)`) maps the
    arrays of a `SharedMemory` made before the fork, sized after it, sent to it in its first payload: what
    this process writes into them after sending that payload, it reads (an ordinary array written then it
    would not see: it has its own copy); where the platform has no memfd, through an unlinked temporary
    file. `will_fork_helper` says beforehand whether `fork_helper` forks."""
    import pickle

    from depth.workers import SharedMemory, fork_helper, will_fork_helper
    if not memfd:
        monkeypatch.delattr(os, "memfd_create", raising=False)
    elif not hasattr(os, "memfd_create"):
        pytest.skip("no memfd on this platform")
    _fresh_module(tmp_path, monkeypatch, "helper_mod_shared")
    memory = SharedMemory()
    assert pickle.loads(pickle.dumps(memory)).fd == memory.fd  # (the descriptor the forked processes hold too)
    assert not will_fork_helper(["numpy"]) and fork_helper(None, ["numpy"]) is None
    assert will_fork_helper(["helper_mod_shared", "numpy"])
    helper = fork_helper(None, ["helper_mod_shared", "numpy"])
    assert helper is not None
    specs = [((3, 4, 2), np.float64), ((5,), np.uint8)]
    image, flags = memory.arrays(specs)
    assert image.shape == (3, 4, 2) and image.dtype == np.float64 and flags.shape == (5,) and flags.dtype == np.uint8
    assert not image.any() and not flags.any()
    helper.send((_read_shared, (memory, specs)))
    memory.close()
    memory.close()  # twice: nothing more to do
    image[2, 1, 0], flags[4], _PRIVATE[1] = 0.25, 7, 0.5
    try:
        assert helper.run("rest") == (0.25, 7, 0.0, "rest")
    finally:
        _PRIVATE[1] = 0.0


def test_no_helper_where_every_module_is_imported_already():
    from depth.workers import fork_helper
    assert fork_helper(lambda payload, progress, inbox: payload, ["numpy", "os"]) is None


def test_a_helper_task_error_is_raised_here_and_a_helper_never_run_ends(tmp_path, monkeypatch):
    from depth.workers import fork_helper
    _fresh_module(tmp_path, monkeypatch, "helper_mod2")

    def task(payload, progress, inbox):
        raise KeyError(f"no face {payload}")

    helper = fork_helper(task, ["helper_mod2"])
    with pytest.raises(KeyError, match="no face 3"):
        helper.run(3)
    process = helper._process
    assert process is None  # closed by run
    idle = fork_helper(task, ["helper_mod2"])  # closed without a payload (this process left early)
    child = idle._process
    idle.close()
    assert not child.is_alive() and child.exitcode is not None
    idle.close()  # twice: nothing more to do


def _gone(pid: int) -> bool:
    """Whether process `pid` has ended (a zombie until whoever adopted it reaps it)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] in "ZX"
    except FileNotFoundError:
        return True


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc")
@pytest.mark.parametrize("leaving", ["exits", "killed"])
def test_a_helper_left_open_ends_with_the_process_that_forked_it(tmp_path, leaving):
    """A helper never sent anything (`depth.reconstruct.start_helper` without a `reconstruct` call) does not
    outlive the process that forked it: closed as that process exits (else multiprocessing's exit handler waits
    for it for ever), and ending by itself where that process is killed (it holds no end of the parent's
    pipe, so its wait for a payload sees the parent leave)."""
    import subprocess
    import sys
    import time
    (tmp_path / "helper_mod7.py").write_text("")
    end = "os.kill(os.getpid(), signal.SIGKILL)" if leaving == "killed" else "sys.exit(0)"
    script = (f"import os, signal, sys\nsys.path.insert(0, {str(tmp_path)!r})\n"
              f"from depth.workers import fork_helper\n"
              f"helper = fork_helper(lambda payload, progress, inbox: payload, ['helper_mod7'])\n"
              f"print(helper._process.pid, flush=True)\n{end}\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60,
                          cwd=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    pid = int(done.stdout.split()[0])
    deadline = time.perf_counter() + 20
    while not _gone(pid) and time.perf_counter() < deadline:
        time.sleep(0.05)
    try:
        assert _gone(pid)
        assert done.returncode == (-9 if leaving == "killed" else 0)
    finally:
        if not _gone(pid):
            os.kill(pid, 9)


def test_a_helper_that_ended_on_an_error_before_the_last_payload_reports_its_error(tmp_path, monkeypatch):
    """The helper's task failed on its first payload, and it has ended, before `run` sends the last one: the
    send finds the pipe closed, and the error the helper sent is raised (not the broken pipe, which the
    command would take for its output's reader leaving)."""
    from depth.workers import fork_helper
    _fresh_module(tmp_path, monkeypatch, "helper_mod8")

    def task(payload, progress, inbox):
        raise KeyError(f"no face {payload}")

    helper = fork_helper(task, ["helper_mod8"])
    process = helper._process
    helper.send(3)
    process.join(timeout=30)
    assert not process.is_alive()
    with pytest.raises(KeyError, match="no face 3"):
        helper.run("rest", progress=lambda done, total: None)


def test_a_helper_closed_while_it_runs_its_task_is_ended_not_waited_for(tmp_path, monkeypatch):
    import signal
    import time

    from depth.workers import fork_helper
    _fresh_module(tmp_path, monkeypatch, "helper_mod4")

    def work(i):  # in the workers the helper forks
        # written under another name and renamed: the file that the poll below sees appear is whole (written in
        # place, it was once read between its creation and its write, empty)
        (tmp_path / f"pid{i}").write_text(str(os.getpid()))
        os.replace(tmp_path / f"pid{i}", tmp_path / f"worker{i}")
        time.sleep(60)

    def task(payload, progress, inbox):
        progress(0, 2)
        fork_map(work, 2, workers=2)

    def interrupted(done, total):  # this process is interrupted while the helper's workers still work
        deadline = time.perf_counter() + 30
        while len(list(tmp_path.glob("worker*"))) < 2 and time.perf_counter() < deadline:
            time.sleep(0.05)
        raise KeyboardInterrupt

    helper = fork_helper(task, ["helper_mod4"])
    child = helper._process
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        helper.run(0, progress=interrupted)
    workers = [int(p.read_text()) for p in tmp_path.glob("worker*")]
    try:
        assert len(workers) == 2 and not child.is_alive()
        deadline = time.perf_counter() + 10
        while not all(_gone(pid) for pid in workers) and time.perf_counter() < deadline:
            time.sleep(0.05)
        assert all(_gone(pid) for pid in workers)  # the workers it forked ended with it
        assert time.perf_counter() - t0 < 40
    finally:  # none left behind if not (they would hold this process's output open for a minute)
        for pid in workers:
            if not _gone(pid):
                os.kill(pid, signal.SIGKILL)


def test_a_helper_that_dies_is_reported_not_waited_for(tmp_path, monkeypatch):
    from depth.workers import fork_helper
    _fresh_module(tmp_path, monkeypatch, "helper_mod3")
    helper = fork_helper(lambda payload, progress, inbox: os._exit(3), ["helper_mod3"])
    with pytest.raises(RuntimeError, match="ended without a result"):
        helper.run(1)


def test_forked_workers_and_helpers_run_opencv_without_its_thread_pool(tmp_path, monkeypatch):
    """A process forked while the parent's OpenCV pool held its lock would wait for ever on its first parallel
    OpenCV call (`depth.workers.opencv_serial`): the workers and helpers run OpenCV serially, this process as
    before."""
    import cv2

    from depth.workers import fork_helper
    before = cv2.getNumThreads()
    cv2.setNumThreads(2)
    try:
        cv2.GaussianBlur(np.ones((256, 256), np.float32), (0, 0), 2.0)  # the pool in use here before the forks
        out = fork_map(lambda i: (cv2.getNumThreads(), os.getpid()), 2, workers=2)
        assert {threads for threads, _ in out} == {1} and os.getpid() not in {pid for _, pid in out}
        _fresh_module(tmp_path, monkeypatch, "helper_mod_cv")
        helper = fork_helper(lambda payload, progress, inbox: (cv2.getNumThreads(), os.getpid()), ["helper_mod_cv"])
        assert helper is not None
        threads, pid = helper.run(None)
        assert threads == 1 and pid != os.getpid()
        assert cv2.getNumThreads() == 2
    finally:
        cv2.setNumThreads(before)
