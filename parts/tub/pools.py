"""Thread pools that keep working while the interpreter exits.

``TubWriter.shutdown`` runs from ``atexit`` when a program ends without calling it, to write the
records still queued. By then Python has shut its thread pools down (``concurrent.futures``
refuses new tasks once the interpreter is finalizing), so a task handed to a pool would raise
and the records waiting for it would be lost. :func:`submit_or_run` runs such a task in the
calling thread instead.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor, Future
from typing import Any, TypeVar

T = TypeVar("T")


def submit_or_run(pool: Executor, fn: Callable[..., T], *args: Any) -> Future[T]:
    """``pool.submit(fn, *args)``, or ``fn(*args)`` run now when the pool takes no more tasks
    (the interpreter is exiting, or the pool was shut down); a future either way."""
    try:
        return pool.submit(fn, *args)
    except RuntimeError:  # "cannot schedule new futures after (interpreter) shutdown"
        done: Future[T] = Future()
        try:
            done.set_result(fn(*args))
        except Exception as exc:
            done.set_exception(exc)
        return done
