"""Telemetry of the simulated car on its track: CTE, heading error, progress, laps, off-track.

Laps are counted on the distance driven along the centre line (unwrapped arc length): a lap is
completed when the car has gained one more track length of forward progress than ever before, so
wiggling back and forth over the start line, reversing or cutting across never counts a lap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from parts.sim.kinematics import CarState
from parts.sim.track import Track


@dataclass
class TelemetryFrame:
    """One step's telemetry (what the sim part writes to memory as sim/...)."""

    cte: float  # m, positive = right of the centre line
    heading_error: float  # rad, car heading minus track heading, in (-pi, pi]
    speed: float  # m/s
    progress: float  # fraction of the current lap in [0, 1)
    lap: int  # laps completed
    lap_time: float | None  # s, duration of the last completed lap (None before the first)
    off_track: bool
    pos: tuple[float, float]  # m
    s: float  # arc length of the nearest centre-line point, m
    lap_completed: bool = False  # True on the step a lap was completed
    off_track_event: bool = False  # True on the step the car left the road (rising edge)


@dataclass
class LapTracker:
    """Follows a car along a track: progress, laps and lap times, off-track events.

    Args:
        track: the track.
        off_track_cte: |CTE| in metres beyond which the car is off the road.
        start_s: arc length of the start line (where the car is placed), m.
    """

    track: Track
    off_track_cte: float
    start_s: float = 0.0
    distance: float = 0.0  # unwrapped forward progress since the start, m
    best: float = 0.0  # most forward progress reached, m
    laps: int = 0
    lap_times: list[float] = field(default_factory=list)
    off_track_events: int = 0
    _last_s: float | None = None
    _lap_start: float = 0.0
    _was_off: bool = False

    def __post_init__(self) -> None:
        if self.off_track_cte <= 0:
            raise ValueError(f"off-track CTE must be > 0 m, got {self.off_track_cte}")

    def restart(self, t: float) -> None:
        """Forget progress: a new run from the start line at time ``t``."""
        self.distance = self.best = 0.0
        self.laps = 0
        self.lap_times = []
        self._last_s = None
        self._lap_start = t
        self._was_off = False

    def relocate(self) -> None:
        """The car was moved (a reset): the next update must not count the jump as driving."""
        self._last_s = None
        self._was_off = False

    def update(self, state: CarState, t: float) -> TelemetryFrame:
        """Telemetry for the car's state at simulated time ``t`` (seconds)."""
        tr = self.track
        proj = tr.project((state.x, state.y))
        if self._last_s is not None:
            ds = proj.s - self._last_s
            ds -= tr.length * round(ds / tr.length)  # shortest way round the loop
            self.distance += ds
        self._last_s = proj.s
        lap_completed = False
        if self.distance > self.best:
            self.best = self.distance
            if self.best >= (self.laps + 1) * tr.length:
                self.laps += 1
                self.lap_times.append(t - self._lap_start)
                self._lap_start = t
                lap_completed = True
        off = abs(proj.cte) > self.off_track_cte
        event = off and not self._was_off
        if event:
            self.off_track_events += 1
        self._was_off = off
        heading_error = (state.heading - proj.heading + math.pi) % (2 * math.pi) - math.pi
        progress = ((proj.s - self.start_s) % tr.length) / tr.length
        return TelemetryFrame(
            cte=proj.cte, heading_error=heading_error, speed=state.speed, progress=progress,
            lap=self.laps, lap_time=self.lap_times[-1] if self.lap_times else None, off_track=off,
            pos=(state.x, state.y), s=proj.s, lap_completed=lap_completed, off_track_event=event)
