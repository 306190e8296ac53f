"""Clocks for the drive loop: real monotonic time, or simulated time that never sleeps."""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    """What the loop needs from a clock: the time now and a way to wait until a deadline."""

    def now(self) -> float:
        """Seconds on a monotonic scale."""
        ...

    def sleep_until(self, deadline: float) -> None:
        """Return at (or just after) ``deadline``; return at once if it has passed."""
        ...


class MonotonicClock:
    """Real time on ``time.perf_counter`` (monotonic, sub-microsecond resolution)."""

    def now(self) -> float:
        """Seconds since an arbitrary start."""
        return time.perf_counter()

    def sleep_until(self, deadline: float) -> None:
        """Sleep until the absolute ``deadline`` (the OS wakes us ~50-100 µs late; never early)."""
        remaining = deadline - time.perf_counter()
        while remaining > 0:
            time.sleep(remaining)
            remaining = deadline - time.perf_counter()


class SimulatedClock:
    """Simulated time: ``sleep_until`` jumps to the deadline, so loops run as fast as the CPU allows.

    Parts that integrate physics use the loop period as their time step, so results do not depend
    on how fast the host is.
    """

    def __init__(self, start: float = 0.0) -> None:
        self.t = start

    def now(self) -> float:
        """The simulated time in seconds."""
        return self.t

    def sleep_until(self, deadline: float) -> None:
        """Advance simulated time to ``deadline`` (never backwards)."""
        self.t = max(self.t, deadline)

    def advance(self, seconds: float) -> None:
        """Let simulated time pass, e.g. to model a part that takes time."""
        self.t += seconds


class RateKeeper:
    """Absolute deadlines at a fixed rate: no cumulative drift and no burst after an overrun.

    After an overrun the next deadline is the next slot of the original grid that is still in the
    future, so the loop stays phase-locked and never runs several catch-up loops back to back.
    """

    def __init__(self, rate_hz: float, clock: Clock) -> None:
        if rate_hz <= 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        self.period = 1.0 / rate_hz
        self.clock = clock
        self.start = clock.now()
        self.slot = 0  # index of the current slot on the grid start + k * period
        self.overruns = 0
        self.skipped_slots = 0

    @property
    def deadline(self) -> float:
        """When the next loop is due."""
        return self.start + (self.slot + 1) * self.period

    def wait(self) -> bool:
        """Wait for the next slot. Returns False (and counts an overrun) if the loop was late."""
        now = self.clock.now()
        next_slot = self.slot + 1
        due = self.start + next_slot * self.period
        late = now > due
        if late:
            self.overruns += 1
            missed = int((now - self.start) / self.period) + 1 - next_slot
            self.skipped_slots += missed
            next_slot += missed
            due = self.start + next_slot * self.period
        self.slot = next_slot
        self.clock.sleep_until(due)
        return not late
