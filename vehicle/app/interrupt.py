"""Ctrl-C during a long training: end it after the current step and keep what it learnt.

``manage.py train``, ``vehicle train`` and both demos train this way, so a Ctrl-C leaves the best
model so far with its metrics, loss plot and database entry, as a finished run does.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
from collections.abc import Iterator
from typing import Any

logger = logging.getLogger(__name__)


@contextlib.contextmanager
def ctrl_c_stops_training() -> Iterator[threading.Event | None]:
    """The first Ctrl-C ends the training after the current step, keeping the best model so far
    (its metrics, plot and database entry written as for a finished run); a second one stops at
    once. Yields the event ``fit`` polls, or None where a handler cannot be set (another thread,
    several processes: torchrun stops its workers itself)."""
    if threading.current_thread() is not threading.main_thread() or int(os.environ.get("WORLD_SIZE", "1")) > 1:
        yield None
        return
    interrupted = threading.Event()
    owner = os.getpid()

    def on_sigint(signum: int, frame: Any) -> None:
        if os.getpid() != owner:  # a forked DataLoader worker got the terminal's Ctrl-C: the trainer stops it
            return
        if interrupted.is_set():
            raise KeyboardInterrupt
        interrupted.set()
        logger.warning("Ctrl-C: training stops after this step and keeps its best model so far "
                       "(Ctrl-C again to stop at once)")

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield interrupted
    finally:
        signal.signal(signal.SIGINT, previous)
