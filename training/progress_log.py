"""Training progress as log lines, for output that is not a terminal (a file, a pipe, a service).

A terminal gets fit's progress bar; elsewhere the bar is left out, and without this the log would
be silent between two epoch lines, minutes apart on a slow CPU.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

logger = logging.getLogger(__name__)

#: seconds between two progress lines within an epoch
PROGRESS_LOG_S = 30.0


class ProgressLog:
    """An event sink for :func:`training.fit.fit`: logs ``epoch E/N: batch B of M, loss L,
    S samples/s`` from the batch events, at most once every ``every_s`` seconds (counted again
    from each epoch's end, when fit logs its own line), and hands every event on to ``forward``.

    ``every_s`` defaults to :data:`PROGRESS_LOG_S`; ``clock`` (seconds) is for tests.
    """

    def __init__(self, forward: Callable[[dict[str, Any]], None] | None = None, every_s: float | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.forward = forward
        self.every_s = PROGRESS_LOG_S if every_s is None else every_s
        self.clock = clock
        self._last = clock()

    def __call__(self, event: dict[str, Any]) -> None:
        if self.forward is not None:
            self.forward(event)
        kind = event.get("event")
        if kind == "epoch":
            self._last = self.clock()
        elif kind == "batch":
            now = self.clock()
            if now - self._last >= self.every_s:
                self._last = now
                logger.info("epoch %d/%d: batch %d of %d, loss %.5f, %.0f samples/s", event["epoch"],
                            event["epochs"], event["batch"], event["batches"], event["loss"],
                            event["samples_per_s"])
