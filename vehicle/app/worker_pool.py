"""A pool of worker processes that maps a function over items, results in order, and can be stopped
at once.

Why not ``concurrent.futures.ProcessPoolExecutor``: it cannot be stopped in the middle of a task.
Killing its workers (a Ctrl-C during ``vehicle sim eval --workers N``) could leave its manager
thread blocked reading the result pipe, which the parent also holds open, and the interpreter waited
for that thread at exit: the command hung. Here each worker has a pipe of its own whose other end
only the worker holds, so a worker's death is an end of file, never a wait; and stopping the pool
kills and reaps its workers, leaving no thread behind.

A worker ends when the pool sends it ``None``, when its pipe closes, or, in the middle of a task,
when its parent has died (killed: nobody wants the result, and an orphan would run on for minutes).
"""

from __future__ import annotations

import collections
import contextlib
import logging
import os
import pickle
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from multiprocessing.connection import Connection, wait
from typing import Any

logger = logging.getLogger(__name__)

#: seconds a worker has to exit after the pool asked it to, before it is killed
EXIT_GRACE_S = 5.0
#: seconds between a worker's checks that its parent is alive
PARENT_CHECK_S = 0.5


class WorkerDied(RuntimeError):
    """A worker process ended in the middle of a task (killed, out of memory, a crash in C code)."""


def _sendable(exc: BaseException) -> BaseException:
    """``exc`` if it survives the trip through a pipe (some exceptions pickle but cannot be rebuilt),
    else a RuntimeError with its type and message; either way with the worker's traceback as a note."""
    text = "".join(traceback.format_exception(exc))
    try:
        out = pickle.loads(pickle.dumps(exc))
    except Exception:  # noqa: BLE001 - whatever stops it from travelling
        out = RuntimeError(f"{type(exc).__name__}: {exc}")
    out.add_note(f"in the worker process:\n{text.rstrip()}")
    return out


def _exit_with(parent: int) -> None:
    """End this process as soon as ``parent`` is no longer its parent (it died and we were adopted)."""
    while os.getppid() == parent:
        time.sleep(PARENT_CHECK_S)
    os._exit(1)  # no clean-up to wait for: the pool's tasks have nothing to bring to a safe state


def _serve(conn: Connection, parent: int, fn: Callable[..., Any], initializer: Callable[..., Any] | None,
           initargs: tuple[Any, ...]) -> None:
    """A worker's life: initialise, then answer ``(index, args)`` with ``(index, ok, value)``."""
    threading.Thread(target=_exit_with, args=(parent,), name="parent-watch", daemon=True).start()
    try:
        if initializer is not None:
            initializer(*initargs)
    except Exception as exc:  # noqa: BLE001 - the parent reports it
        conn.send((-1, False, _sendable(exc)))
        return
    while True:
        try:
            job = conn.recv()
        except EOFError:  # the parent is gone: nobody wants the result
            return
        if job is None:
            return
        index, args = job
        try:
            value = fn(*args)
            conn.send((index, True, value))  # pickles before writing: an unsendable value fails whole
        except Exception as exc:  # noqa: BLE001 - the parent raises it
            conn.send((index, False, _sendable(exc)))


class WorkerPool:
    """``processes`` worker processes running ``fn``; use as a context manager around :meth:`start`
    and :meth:`map`. Leaving the block normally lets the workers exit; leaving it by an exception
    (a failed task, Ctrl-C) kills them at once, without waiting for their tasks."""

    def __init__(self, fn: Callable[..., Any], processes: int, initializer: Callable[..., Any] | None = None,
                 initargs: tuple[Any, ...] = (), context: str = "spawn") -> None:
        if processes < 1:
            raise ValueError(f"a pool needs at least one process, not {processes}")
        self._fn, self._size = fn, processes
        self._initializer, self._initargs = initializer, initargs
        self._context = context
        self._workers: list[tuple[Any, Connection]] = []

    def start(self) -> None:
        """Start the worker processes (they initialise while the first tasks wait in their pipes)."""
        import multiprocessing

        ctx = multiprocessing.get_context(self._context)
        for _ in range(self._size):
            ours, theirs = ctx.Pipe(duplex=True)
            args = (theirs, os.getpid(), self._fn, self._initializer, self._initargs)
            process = ctx.Process(target=_serve, args=args, daemon=True, name="pool-worker")
            self._workers.append((process, ours))
            process.start()
            theirs.close()  # only the worker holds its end: its death reads as end of file here

    def map(self, items: Sequence[tuple[Any, ...]]) -> Iterator[Any]:
        """``fn(*args)`` for each ``args`` of ``items``, yielded in the order of ``items``; a task's
        exception is raised here, as is :class:`WorkerDied`."""
        if not self._workers:
            raise RuntimeError("start() the pool before map()")
        pending = collections.deque(enumerate(items))
        busy: dict[Connection, tuple[Any, int]] = {}
        done: dict[int, Any] = {}

        def feed(process: Any, conn: Connection) -> None:
            if pending:
                index, args = pending.popleft()
                try:
                    conn.send((index, tuple(args)))
                except OSError:
                    raise WorkerDied(f"a worker process ended before task {index} (exit code "
                                     f"{process.exitcode})") from None
                busy[conn] = (process, index)

        for process, conn in self._workers:
            feed(process, conn)
        for next_index in range(len(items)):
            while next_index not in done:
                sentinels = {process.sentinel: conn for conn, (process, _) in busy.items()}
                for ready in wait([*busy, *sentinels]):
                    conn = sentinels.get(ready, ready)
                    if conn not in busy:
                        continue  # its answer was read through the other handle of this round
                    process, index = busy.pop(conn)
                    try:
                        answer, ok, value = conn.recv()
                    except (EOFError, OSError):
                        process.join(1.0)
                        raise WorkerDied(f"a worker process ended during task {index} (exit code "
                                         f"{process.exitcode}): out of memory, or killed?") from None
                    if not ok:
                        raise value
                    done[answer] = value
                    feed(process, conn)
            yield done.pop(next_index)

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        self.close(kill=exc_type is not None)

    def close(self, kill: bool = False) -> None:
        """Stop the workers: ask them to exit (kill after :data:`EXIT_GRACE_S`), or kill them now."""
        if not kill:
            for _, conn in self._workers:
                with contextlib.suppress(OSError):  # already gone
                    conn.send(None)
        for process, conn in self._workers:
            if not kill:
                process.join(EXIT_GRACE_S)
            if process.is_alive():
                process.kill()  # SIGKILL: no handler runs, nothing half-stopped is waited for
            process.join()
            conn.close()
        self._workers.clear()
