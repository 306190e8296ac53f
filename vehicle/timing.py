"""Per-part timing in bounded memory: a ring of recent samples plus all-time count and max."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a single loop longer than this many loop periods is reported as a stall
STALL_PERIODS = 5


class TimingRing:
    """Durations (seconds) of the last ``size`` calls, the all-time maximum and call count.

    A plain list as the ring: on the loop's hot path a list store costs a fraction of a numpy
    scalar store; numpy is used only when a summary is asked for.
    """

    def __init__(self, size: int = 2048) -> None:
        self.size = size
        self.samples: list[float] = [0.0] * size
        self.count = 0
        self.max = 0.0

    def add(self, seconds: float) -> None:
        """Record one duration."""
        self.samples[self.count % self.size] = seconds
        self.count += 1
        if seconds > self.max:
            self.max = seconds

    def recent(self) -> np.ndarray:
        """The samples still in the ring (most recent ``size`` at most)."""
        return np.asarray(self.samples[: min(self.count, self.size)])

    def percentile(self, q: float) -> float:
        """The q-th percentile (0-100) of the recent samples, 0.0 when empty."""
        recent = self.recent()
        return float(np.percentile(recent, q)) if len(recent) else 0.0


@dataclass(frozen=True)
class PartTiming:
    """Summary of one part's run time, in milliseconds."""

    name: str
    calls: int
    p50_ms: float
    p99_ms: float
    max_ms: float


@dataclass(frozen=True)
class LoopSummary:
    """What the vehicle reports when it stops."""

    loops: int
    elapsed_s: float
    target_hz: float
    achieved_hz: float
    overruns: int
    parts: tuple[PartTiming, ...]
    longest_loop_s: float = 0.0  # the longest single loop (its parts' run time), seconds

    @property
    def stalled(self) -> bool:
        """Whether one loop took more than :data:`STALL_PERIODS` loop periods: the car went unsteered."""
        return self.longest_loop_s * self.target_hz > STALL_PERIODS

    def format(self) -> str:
        """A small table for the log."""
        rows = [f"{self.loops} loops in {self.elapsed_s:.2f} s: {self.achieved_hz:.2f} Hz "
                f"(target {self.target_hz:g} Hz), {self.overruns} overruns, longest loop "
                f"{self.longest_loop_s * 1e3:.1f} ms"]
        if self.stalled:
            rows.append(f"STALL: one loop took {self.longest_loop_s:.2f} s, {self.longest_loop_s * self.target_hz:.0f} "
                        "loop periods: nothing was steered meanwhile (see the part with that max ms)")
        rows += [f"{'part':<28}{'calls':>8}{'p50 ms':>10}{'p99 ms':>10}{'max ms':>10}"]
        rows += [f"{p.name:<28}{p.calls:>8}{p.p50_ms:>10.3f}{p.p99_ms:>10.3f}{p.max_ms:>10.3f}"
                 for p in self.parts]
        return "\n".join(rows)
