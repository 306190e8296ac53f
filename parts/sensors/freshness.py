"""Staleness of a sensor's readings (when did it last report, is that recent enough) and the base
class of sensor parts that turns a stale reading into None values and ``ok`` False."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import ClassVar

from vehicle.part import ThreadedPart

logger = logging.getLogger(__name__)


class Freshness:
    """Tracks the time of a sensor's latest reading on ``clock`` (seconds).

    Args:
        max_age: seconds after the latest reading at which the sensor counts as stale.
        clock: time source (default ``time.monotonic``; tests and the simulator pass their own).
    """

    def __init__(self, max_age: float, clock: Callable[[], float] = time.monotonic) -> None:
        if not max_age > 0:
            raise ValueError(f"max_age must be > 0 seconds, got {max_age!r}")
        self.max_age = float(max_age)
        self.clock = clock
        self.last: float | None = None  # clock time of the latest reading

    def mark(self) -> None:
        """A reading arrived now."""
        self.last = self.clock()

    @property
    def age(self) -> float | None:
        """Seconds since the latest reading (None: never)."""
        return None if self.last is None else self.clock() - self.last

    @property
    def ok(self) -> bool:
        """Whether the latest reading is at most ``max_age`` seconds old."""
        age = self.age
        return age is not None and age <= self.max_age


class SensorPart(ThreadedPart):
    """Base of a sensor part: :meth:`read` one reading (a tuple of values, None = nothing new);
    :meth:`run_threaded` / :meth:`run` return the latest values followed by the ``ok`` flag, and
    all-None values with ``ok`` False once the latest reading is older than ``max_age`` seconds.

    Subclasses set ``OUTPUTS`` (the values' keys, then the ok key) and implement :meth:`read`;
    ``open`` / ``close`` acquire and release the device; ``RECORDED`` says which values a drive
    records, :meth:`where` and :meth:`describe` what ``vehicle hw check`` prints.
    """

    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, max_age: float, clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        self.freshness = Freshness(max_age, clock)
        self._was_ok = False

    def probe(self) -> SensorPart:
        """Open the device now (in the caller's thread), so that a missing device stops the car's
        assembly with a message naming it, before the loop starts; the thread then reads it."""
        self._ensure_open()
        return self

    def read(self) -> tuple[object, ...] | None:
        """One reading: the values of ``OUTPUTS`` but the last (block at most briefly)."""
        raise NotImplementedError(f"{type(self).__name__} must implement read()")

    def poll(self) -> object:
        value = self.read()
        if value is None:
            return self.NOTHING
        self.freshness.mark()
        return value

    def run_threaded(self, *inputs: object) -> tuple[object, ...]:
        """The latest values and True, or all None and False when stale (logged once per change)."""
        value = super().run_threaded(*inputs)
        ok = value is not None and self.freshness.ok
        if ok != self._was_ok:
            self._was_ok = ok
            age = self.freshness.age
            if ok:
                logger.info("%s: reporting", type(self).__name__)
            else:
                logger.warning("%s: stale (no reading for %s%s): its values read None",
                               type(self).__name__, "ever" if age is None else f"{age:.2f} s",
                               f"; its thread failed: {self.error}" if self.error is not None else "")
        if not ok:
            return (None,) * (len(self.OUTPUTS) - 1) + (False,)
        return (*value, True)  # type: ignore[misc]

    def where(self) -> str:
        """Where the device is, for messages: ``"on /dev/ttyUSB0"`` (its ``port``) by default."""
        return f"on {getattr(self, 'port', '?')}"

    def describe(self, values: tuple[object, ...]) -> tuple[bool, str]:
        """(whether ``values``, this part's latest outputs, hold a fresh reading, one line saying
        what they show) for ``vehicle hw check``; by default each value beside its key."""
        if not values or values[-1] is not True:
            return False, f"{self.where()}: no reading within the timeout: check the wiring and the settings above"
        shown = ", ".join(f"{key} {_short(value)}" for key, value in zip(self.OUTPUTS, values[:-1], strict=False))
        return True, f"{self.where()}: {shown}"

    def run(self, *inputs: object) -> tuple[object, ...]:
        """Non-threaded use: one read inline with this loop's inputs (ThreadedPart.run stores them
        before the read, so a read sees this loop's throttle, not the previous one's), then as
        :meth:`run_threaded`."""
        super().run(*inputs)
        return self.run_threaded(*inputs)


def _short(value: object) -> str:
    """A reading in a few characters: floats to 3 significant digits, long sequences by length."""
    if isinstance(value, float):
        return f"{value:.3g}"
    if isinstance(value, list | tuple) and len(value) > 4:
        return f"[{len(value)} values]"
    return str(value)
