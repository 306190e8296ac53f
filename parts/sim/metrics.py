"""Closed-loop driving metrics of one episode, as a part that reads a simulator's telemetry.

:class:`EpisodeMetrics` runs last in an evaluation loop: it reads the executed command (``angle``,
DriveMode's output) and the telemetry keys every simulator part writes (``sim/cte``,
``sim/off_track``, ``sim/speed``, ``sim/pos``, ``sim/lap``, ``sim/lap_time``, ``sim/progress``),
and asks the loop to stop once the episode has driven its laps or used its time. Definitions
follow docs/simulator.md and protocols.md §4 (DAVE-2 autonomy, |CTE| over autonomous frames, ...).
A simulator that does not report a signal (stock Udacity: no CTE, laps, progress or position) gives
None for the metrics that need it, never zeros, and the result names them (``unavailable``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

#: most trajectory points kept per episode (for the PNG; positions are subsampled beyond this)
MAX_TRAJECTORY_POINTS = 3000


@dataclass
class _Trace:
    """What one episode records, step by step."""

    cte: list[float] = field(default_factory=list)  # NaN where the simulator reports none
    off: list[bool] = field(default_factory=list)
    speed: list[float] = field(default_factory=list)
    angle: list[float] = field(default_factory=list)
    pos: list[tuple[float, float]] = field(default_factory=list)
    events: list[tuple[float, float]] = field(default_factory=list)  # where the car left the road
    lap_times: list[float] = field(default_factory=list)
    distance: float = 0.0  # odometer, m
    laps: int = 0
    laps_driven: float = 0.0  # most forward progress reached, in laps
    progress: float = 0.0
    reported: set[str] = field(default_factory=set)  # signals the simulator gave at least once


#: signal -> (what it is, the metrics that need it); a simulator that never reports a signal gets
#: None for those metrics and the report names them, instead of zeros
SIGNALS: dict[str, tuple[str, tuple[str, ...]]] = {
    "cte": ("cross-track error", ("mean_abs_cte", "rms_cte", "p95_abs_cte", "max_abs_cte")),
    "lap": ("laps", ("laps_completed", "success", "timed_out", "lap_times_s", "best_lap_s", "mean_lap_s",
                     "std_lap_s")),
    "progress": ("progress along the track", ("laps_driven", "progress", "off_track_per_lap", "completion",
                                              "score")),
    "speed": ("speed", ("mean_speed", "distance_m", "off_track_per_km", "mean_distance_between_interventions_m")),
    "pos": ("position", ("trajectory", "off_track_at")),
}


class EpisodeMetrics:
    """Part: scores one episode and stops the loop when it is over.

    Args:
        dt: seconds per loop (1 / DRIVE_LOOP_HZ).
        laps: laps to drive; the episode ends when they are completed ...
        max_time: ... or after this many seconds.
        penalty_s: seconds charged per intervention (DAVE-2: 6).
        stop: called once when the episode is over (``Vehicle.stop``).
        seed, track_length: the track, for the report.
        on_step: called after every recorded step (e.g. to show frames).
        details: more about the episode for the report (e.g. the track's theme and conditions).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "sim/cte", "sim/off_track", "sim/speed", "sim/pos", "sim/lap",
                                         "sim/lap_time", "sim/progress")
    #: simulators differ in what they report (stock Udacity: no CTE, position or laps)
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = INPUTS[1:]
    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, dt: float, laps: int, max_time: float, penalty_s: float, *,
                 stop: Callable[[], None] | None = None, seed: int | None = None,
                 track_length: float | None = None, on_step: Callable[[], None] | None = None,
                 details: dict[str, Any] | None = None) -> None:
        self.dt, self.laps, self.max_time, self.penalty = float(dt), int(laps), float(max_time), float(penalty_s)
        self.stop, self.seed, self.track_length, self.on_step = stop, seed, track_length, on_step
        self.details = dict(details or {})
        self.trace = _Trace()
        self.time = 0.0
        self.done = False
        self._was_off = False
        self._last_pos: tuple[float, float] | None = None
        self._progress: float | None = None
        self._last_lap: int | None = None
        self._reset_pending = False
        self._unwrapped = 0.0  # laps of forward progress since the first step

    def run(self, angle: Any, cte: Any, off_track: Any, speed: Any, pos: Any, lap: Any, lap_time: Any,
            progress: Any) -> None:
        """Record this loop's step; ask the loop to stop when the episode is over."""
        if self.done:
            return
        tr = self.trace
        self.time += self.dt
        for name, value in (("cte", cte), ("lap", lap), ("progress", progress), ("speed", speed), ("pos", pos)):
            if value is not None:
                tr.reported.add(name)
        off = bool(off_track)
        self._reset_pending = self._was_off  # the simulator re-centred the car after the last frame
        if off and not self._was_off:  # off-track event: the rising edge (the simulator re-centres)
            tr.events.append(self._last_pos if self._last_pos is not None else _pair(pos))
        self._was_off = off
        v = float(speed) if speed is not None else math.nan
        tr.distance += abs(v) * self.dt if math.isfinite(v) else 0.0
        tr.cte.append(float(cte) if cte is not None else math.nan)
        tr.off.append(off)
        tr.speed.append(v)
        tr.angle.append(float(angle) if angle is not None else 0.0)
        if pos is not None:
            tr.pos.append(_pair(pos))
            self._last_pos = tr.pos[-1]
        restarted = False  # the simulator moved the car (a reset) or restarted its lap count
        if lap is not None:
            n = int(lap)
            if self._last_lap is not None and n > self._last_lap:  # laps are counted as increments, so
                tr.laps += n - self._last_lap  # a counter that restarts (a new scene) loses none
                if lap_time is not None:
                    tr.lap_times.append(float(lap_time))
            restarted = self._last_lap is not None and n < self._last_lap
            self._last_lap = n
        if progress is not None:
            # unwrap the lap fraction (it jumps 0.99 -> 0 at the start line, and reads ~1.0 or ~0.0
            # for a car standing on it) into forward progress; the best of it counts. The step after
            # a reset is a jump, not driving: it does not count.
            p = float(progress)
            if self._progress is not None and not restarted and not self._reset_pending:
                delta = p - self._progress
                self._unwrapped += delta - round(delta)
            self._progress = p
            tr.progress = p
            tr.laps_driven = max(tr.laps_driven, self._unwrapped)
        if self.on_step is not None:
            self.on_step()
        if tr.laps >= self.laps or self.time >= self.max_time - 1e-9:
            self.done = True
            if self.stop is not None:
                self.stop()

    # -- results ----------------------------------------------------------------------------------
    def autonomous_abs_cte(self) -> np.ndarray:
        """|CTE| of the frames on the road (NaN-free), for percentiles over several episodes."""
        cte = np.asarray(self.trace.cte, float)
        keep = ~np.asarray(self.trace.off, bool) & np.isfinite(cte)
        return np.abs(cte[keep])

    def unavailable(self) -> dict[str, str]:
        """Signals the simulator never reported -> what they are (e.g. the stock Udacity simulator:
        ``{"cte": "cross-track error", "lap": "laps", ...}``)."""
        return {name: what for name, (what, _) in SIGNALS.items() if name not in self.trace.reported}

    def result(self) -> dict[str, Any]:
        """Per-track metrics (docs/simulator.md gives the definitions); metrics that need a signal
        the simulator never reported are None, and ``unavailable`` names them."""
        out = self._result()
        missing = self.unavailable()
        for name in missing:
            for key in SIGNALS[name][1]:
                out[key] = None
        out["unavailable"] = {name: {"signal": SIGNALS[name][0], "metrics": list(SIGNALS[name][1])}
                              for name in missing}
        out.update(self.details)
        return out

    def _result(self) -> dict[str, Any]:
        tr, t = self.trace, self.time
        n_int = len(tr.events)
        off = np.asarray(tr.off, bool)
        speed = np.asarray(tr.speed, float)
        auto = ~off  # autonomous frames: the car is on the road under the pilot's control
        cte = np.asarray(tr.cte, float)
        steer = np.asarray(tr.angle, float)
        km = tr.distance / 1000.0
        step = max(1, math.ceil(len(tr.pos) / MAX_TRAJECTORY_POINTS))
        auto_speed = speed[auto & np.isfinite(speed)]
        lap_times = tr.lap_times
        autonomy = max(0.0, 1.0 - n_int * self.penalty / t) * 100.0 if t > 0 else 0.0
        return {
            "seed": self.seed,
            "track_length_m": _r(self.track_length, 2),
            "elapsed_s": _r(t, 3),
            "interventions": n_int,
            "autonomy": _r(autonomy, 2),
            "laps_completed": tr.laps,
            "laps_driven": _r(tr.laps_driven, 3),
            # a car that stands still has no intervention: autonomy means something only beside the
            # share of the asked laps it drove, and the score (what pilots are ranked by) is both
            "completion": _r(completion(tr.laps_driven, self.laps), 3),
            "score": _r(score(autonomy, completion(tr.laps_driven, self.laps)), 2),
            "success": tr.laps >= self.laps and n_int == 0,
            "timed_out": tr.laps < self.laps,
            **cte_stats(cte[auto]),
            "off_track_per_lap": _r(n_int / tr.laps_driven, 3) if tr.laps_driven > 0.01 else None,
            "off_track_per_km": _r(n_int / km, 3) if km > 0 else None,
            "distance_m": _r(tr.distance, 2),
            "mean_distance_between_interventions_m": _r(tr.distance / n_int, 2) if n_int else None,
            "lap_times_s": [_r(x, 3) for x in lap_times],
            "best_lap_s": _r(min(lap_times), 3) if lap_times else None,
            "mean_lap_s": _r(float(np.mean(lap_times)), 3) if lap_times else None,
            "std_lap_s": _r(float(np.std(lap_times)), 3) if lap_times else None,
            "mean_speed": _r(float(auto_speed.mean()), 3) if auto_speed.size else None,
            "steering_smoothness": _r(float(np.abs(np.diff(steer)).mean() / self.dt), 4) if steer.size > 1 else None,
            "progress": _r(tr.progress, 3),
            "frames": int(off.size),
            "autonomous_frames": int(auto.sum()),
            "trajectory": [[_r(x, 3), _r(y, 3)] for x, y in tr.pos[::step]],
            "off_track_at": [[_r(x, 3), _r(y, 3)] for x, y in tr.events],
        }


def completion(laps_driven: float | None, laps: int) -> float:
    """The share of ``laps`` asked that the car drove (0..1): its forward progress, capped at 1."""
    return min(1.0, max(0.0, float(laps_driven or 0.0)) / laps) if laps > 0 else 0.0


def score(autonomy: float | None, share: float | None) -> float:
    """What pilots are ranked by: autonomy % times the share of the asked laps driven.

    DAVE-2's autonomy counts interventions per time, so a car that stands still scores 100 %;
    weighed by the laps it drove it scores 0.
    """
    return float(autonomy or 0.0) * float(share or 0.0)


def rank_key(o: dict[str, Any]) -> tuple[float, float, float, float]:
    """Sort key of an evaluation's overall (or one track's) result, best first: score, then laps
    completed, then mean |CTE| (lower first), then mean speed. Results written before the score
    existed rank by autonomy."""
    cte = o.get("mean_abs_cte")
    ranked = o.get("score")
    if ranked is None:  # no progress signal (the Udacity simulator), or written before the score
        ranked = o.get("autonomy")
    return (-(ranked or 0.0), -(o.get("laps_completed") or 0), cte if cte is not None else math.inf,
            -(o.get("mean_speed") or 0.0))


def cte_stats(values: np.ndarray) -> dict[str, float | None]:
    """Mean/RMS/p95/max |CTE| of signed CTE values (None where there are none, e.g. no CTE reported)."""
    values = values[np.isfinite(values)]
    if values.size == 0:
        return {"mean_abs_cte": None, "rms_cte": None, "p95_abs_cte": None, "max_abs_cte": None}
    a = np.abs(values)
    return {"mean_abs_cte": _r(a.mean()), "rms_cte": _r(np.sqrt((values**2).mean())),
            "p95_abs_cte": _r(np.percentile(a, 95)), "max_abs_cte": _r(a.max())}


def overall(results: Sequence[dict[str, Any]], penalty: float, abs_cte: np.ndarray) -> dict[str, Any]:
    """Aggregate over tracks: sums, and means weighted by frames / time / distance."""
    t = sum(r["elapsed_s"] for r in results)
    n_int = sum(r["interventions"] for r in results)
    laps_driven = sum(r["laps_driven"] or 0.0 for r in results)
    dist = sum(r["distance_m"] or 0.0 for r in results)
    with_laps = [r for r in results if r["laps_completed"] is not None]
    auto_frames = sum(r["autonomous_frames"] for r in results if r["rms_cte"] is not None)
    frames = sum(r["frames"] for r in results)

    def weighted(key: str, weight: str) -> float | None:
        pairs = [(r[key], r[weight]) for r in results if r[key] is not None and r[weight]]
        total = sum(w for _, w in pairs)
        return _r(sum(v * w for v, w in pairs) / total) if total else None

    lap_times = [x for r in results for x in r["lap_times_s"] or []]
    autonomy = max(0.0, 1.0 - n_int * penalty / t) * 100.0 if t > 0 else 0.0
    shares = [r["completion"] for r in results if r.get("completion") is not None]
    share = float(np.mean(shares)) if shares else None  # each track counts alike
    return {
        "tracks": len(results),
        "elapsed_s": _r(t, 3),
        "interventions": n_int,
        "autonomy": _r(autonomy, 2),
        "laps_completed": sum(r["laps_completed"] for r in with_laps) if with_laps else None,
        "completion": _r(share, 3),
        "score": _r(score(autonomy, share), 2) if share is not None else None,
        "success_rate": _r(sum(bool(r["success"]) for r in with_laps) / len(with_laps), 3) if with_laps else None,
        "mean_abs_cte": weighted("mean_abs_cte", "autonomous_frames"),
        "rms_cte": _r(math.sqrt(sum((r["rms_cte"] or 0) ** 2 * r["autonomous_frames"] for r in results)
                                / auto_frames)) if auto_frames else None,
        "p95_abs_cte": _r(np.percentile(abs_cte, 95)) if abs_cte.size else None,
        "max_abs_cte": _r(max((r["max_abs_cte"] for r in results if r["max_abs_cte"] is not None),
                              default=None)),
        "off_track_per_lap": _r(n_int / laps_driven, 3) if laps_driven > 0.01 else None,
        "off_track_per_km": _r(n_int / (dist / 1000.0), 3) if dist > 0 else None,
        "distance_m": _r(dist, 2),
        "mean_distance_between_interventions_m": _r(dist / n_int, 2) if n_int else None,
        "mean_lap_s": _r(float(np.mean(lap_times)), 3) if lap_times else None,
        "best_lap_s": _r(min(lap_times), 3) if lap_times else None,
        "mean_speed": weighted("mean_speed", "autonomous_frames"),
        "steering_smoothness": weighted("steering_smoothness", "frames"),
        "frames": frames,
        # a signal missing on every track: its metrics are None above, named here
        "unavailable": {k: v for k, v in results[0].get("unavailable", {}).items()
                        if all(k in r.get("unavailable", {}) for r in results)},
    }


def _pair(pos: Any) -> tuple[float, float]:
    return (float(pos[0]), float(pos[1])) if pos is not None else (math.nan, math.nan)


def _r(x: float | None, nd: int = 4) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else round(float(x), nd)
