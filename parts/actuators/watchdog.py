"""Command watchdog (dead-man): no fresh command within a timeout -> a callback puts the car in neutral.

It runs in its own thread (a :class:`vehicle.part.ThreadedPart`), so it still fires when the drive
loop itself is stuck and no longer calls the actuator.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable

from vehicle.part import ThreadedPart

logger = logging.getLogger(__name__)


class CommandWatchdog(ThreadedPart):
    """Calls ``on_timeout()`` once when ``feed()`` has not been called for ``timeout_s`` seconds.

    The watch starts with the first ``feed()`` (before it there is nothing to protect) and re-arms
    with the next ``feed()`` after a trip. ``check()`` does one check inline (tests, simulated time).

    Args:
        timeout_s: seconds without a command before ``on_timeout`` runs.
        on_timeout: what to do (called from the watchdog thread, or from ``check()``'s caller).
        clock: time source in seconds (the vehicle's clock, so simulated time works too).
    """

    def __init__(self, timeout_s: float, on_timeout: Callable[[], None],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        if isinstance(timeout_s, bool) or not isinstance(timeout_s, int | float) \
                or not math.isfinite(timeout_s) or timeout_s <= 0:
            raise ValueError(f"ACTUATOR_WATCHDOG_S must be > 0 seconds (or None to disable), "
                             f"got {timeout_s!r}")
        self.timeout_s = float(timeout_s)
        self.on_timeout = on_timeout
        self.clock = clock
        # check a few times per timeout, but never spin
        self.period = min(0.05, self.timeout_s / 4)
        self._state_lock = threading.Lock()
        self._last_feed: float | None = None
        self.tripped = False
        self.trips = 0

    def feed(self) -> None:
        """A fresh command arrived."""
        with self._state_lock:
            self._last_feed = self.clock()
            self.tripped = False

    def check(self) -> bool:
        """Trip if the last command is too old; True when this call tripped."""
        with self._state_lock:
            if self.tripped or self._last_feed is None:
                return False
            age = self.clock() - self._last_feed
            if age <= self.timeout_s:
                return False
            self.tripped = True
            self.trips += 1
        logger.warning("no drive command for %.2f s (watchdog %.2f s): going neutral", age, self.timeout_s)
        self.on_timeout()
        return True

    def poll(self) -> object:
        self.check()
        return ThreadedPart.NOTHING
