"""The worker pool behind `sim eval --workers`: ordered results, errors and deaths reported, and a
stop that kills its workers at once and leaves nothing to wait for."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from vehicle.app.worker_pool import WorkerDied, WorkerPool

_STATE: dict[str, int] = {}


def _init(offset: int) -> None:
    _STATE["offset"] = offset


def _add(a: int, b: int) -> tuple[int, int]:
    time.sleep(0.05 * (a % 3))  # finish out of order
    return a + b + _STATE.get("offset", 0), os.getpid()


class _Unpicklable(Exception):
    def __init__(self, a: int, b: int) -> None:  # rebuilding from args=(message,) fails
        super().__init__(f"{a}-{b}")


def _fail(kind: str) -> None:
    if kind == "value":
        raise ValueError("bad value 7")
    if kind == "odd":
        raise _Unpicklable(1, 2)
    if kind == "die":
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(3600)


def _bad_init() -> None:
    raise OSError("no such model file: x.pt")


def test_results_come_in_item_order_from_several_workers():
    with WorkerPool(_add, 2, _init, (100,)) as pool:
        pool.start()
        out = list(pool.map([(i, 1) for i in range(7)]))
    assert [v for v, _ in out] == [101 + i for i in range(7)]
    assert len({pid for _, pid in out}) == 2  # both workers took tasks
    assert pool._workers == []  # closed: every worker reaped


def test_a_task_error_is_raised_with_the_workers_traceback_and_the_others_are_killed():
    start = time.monotonic()
    with pytest.raises(ValueError, match="bad value 7") as info, WorkerPool(_fail, 2) as pool:
        pool.start()
        list(pool.map([("sleep",), ("value",)]))
    assert time.monotonic() - start < 60  # the sleeping task (an hour) was not waited for
    assert any("in the worker process" in n and "_fail" in n for n in info.value.__notes__)


def test_an_exception_that_cannot_travel_arrives_as_its_type_and_message():
    with pytest.raises(RuntimeError, match="_Unpicklable: 1-2"), WorkerPool(_fail, 1) as pool:
        pool.start()
        list(pool.map([("odd",)]))


def test_a_worker_that_dies_mid_task_is_an_error_not_a_wait():
    with pytest.raises(WorkerDied, match=r"ended during task 1 \(exit code -9\)"), WorkerPool(_fail, 2) as pool:
        pool.start()
        list(pool.map([("sleep",), ("die",)]))


def test_an_initializer_error_is_raised():
    with pytest.raises(OSError, match="no such model file"), WorkerPool(_add, 1, _bad_init) as pool:
        pool.start()
        list(pool.map([(1, 2)]))


def test_a_pool_needs_a_process_and_a_start():
    with pytest.raises(ValueError, match="at least one process"):
        WorkerPool(_add, 0)
    with pytest.raises(RuntimeError, match=r"start\(\) the pool"):
        list(WorkerPool(_add, 1).map([(1, 2)]))


_INTERRUPTED = """
import os, signal, sys, threading
sys.path.insert(0, {root!r})
from tests.vehicle.app.test_worker_pool import _fail
from vehicle.app.worker_pool import WorkerPool
threading.Timer(3.0, os.kill, (os.getpid(), signal.SIGINT)).start()
with WorkerPool(_fail, 2) as pool:
    pool.start()
    try:
        list(pool.map([("sleep",), ("sleep",), ("sleep",)]))
    except KeyboardInterrupt:
        print("interrupted", flush=True)
        raise SystemExit(130)
"""


def test_ctrl_c_in_the_parent_kills_the_workers_and_the_parent_exits():
    """The defect ProcessPoolExecutor had: after a Ctrl-C killed the workers, the interpreter waited
    at exit for a thread blocked on the result pipe. Here the parent exits, every worker gone."""
    root = str(Path(__file__).resolve().parents[3])
    proc = subprocess.run([sys.executable, "-c", _INTERRUPTED.format(root=root)], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 130, proc.stderr[-2000:]
    assert proc.stdout.strip() == "interrupted"
