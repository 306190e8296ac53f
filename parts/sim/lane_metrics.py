"""Lane metrics of a drive with commanded lane changes (the thesis's lane change on demand).

:func:`lane_metrics` is a pure function over what an evaluation records per step: time, the car's
lateral position, the commanded lane's centre, off-track flags. The parts :class:`CommandedLane`
(behaviour -> the commanded lane's centre) and :class:`LaneMetrics` (records the steps, reports)
put it into an evaluation loop. Definitions (docs/simulator.md repeats them):

- **in the commanded lane**: the car's centre is less than half a lane width from the commanded
  lane's centre and the car is on the road (``in_lane_fraction``);
- **centred** in a lane: the car's centre is less than a quarter lane width from the lane's centre
  (for 0.4 m lanes, 10 cm) and the car is on the road: a car that just crossed the centre line is
  in the new lane but has not changed into it yet;
- a commanded change **succeeds** when, within ``time_limit`` seconds of the command, the car
  becomes centred in the commanded lane and stays centred for ``hold`` seconds without leaving
  the road; its **time to change** is from the command to the start of that stay;
- the **change window** of a command runs from the command to the end of that stay (success) or
  for ``time_limit`` seconds (failure); **lane keeping** |error| (distance of the car's centre to
  the commanded lane's centre) and **wrong-lane time** (the car's centre on the other side of the
  centre line from the commanded lane) are measured outside change windows, on the road;
- a command whose judgement the episode's end cuts short is reported but not judged.

Each command also says where it was given, so a failed one can be understood: the largest
|curvature| of the road over the expert's change distance ahead (``curvature_1pm``), the lane the
car was in (``start_lane``), and whether the expert would have waited there for a straighter
stretch before changing (``expert_would_wait``, :class:`ChangeRule`); a failed one says why
(``failure``: ``off_road`` or ``too_slow``) and when it was judged (``failed_at_s``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from parts.drive.behavior import behavior_lane
from parts.sim.simulator import SimCar

#: seconds a commanded change may take, by default
TIME_LIMIT_S = 6.0
#: seconds the car must stay in the new lane for the change to count
HOLD_S = 1.0
#: why a commanded change failed (a command's ``failure``), in words
FAILURES = {"off_road": "left the road", "too_slow": "not settled in the new lane in time"}


def describe_command(c: dict[str, Any]) -> str:
    """A command's record (:func:`lane_metrics`) in words: where it was given and, if it failed, why."""
    text = f"to {c.get('lane') or '?'} at {c['time_s']:.1f} s"
    if c.get("curvature_1pm") is not None:
        start = "off the road" if c.get("start_lane") == "off road" else f"the {c.get('start_lane')} lane"
        wait = "the expert would have waited" if c.get("expert_would_wait") else "the expert would have changed"
        text += f" from {start}, curvature ahead {c['curvature_1pm']:.2f} 1/m ({wait})"
    if c.get("success") is False:
        text += f"; {FAILURES.get(str(c.get('failure')), 'failed')} at {c.get('failed_at_s') or 0:.1f} s"
    return text


@dataclass(frozen=True)
class LaneCommand:
    """A commanded lane change: when (s), to which lane centre (m left of the road's centre line)."""

    time: float
    offset: float
    lane: str = ""
    pos: tuple[float, float] | None = None  # where the car was (world metres), for the plot
    context: dict[str, Any] | None = None  # where it was given (:meth:`ChangeRule.context`)


@dataclass(frozen=True)
class ChangeRule:
    """The expert's rule for starting a change (parts/sim/expert.py): it waits while the road over
    ``distance`` m ahead curves more than ``max_curvature`` 1/m (SIM_EXPERT_LANE_CHANGE_DISTANCE +
    SIM_EXPERT_LOOKAHEAD, SIM_EXPERT_LANE_CHANGE_MAX_CURVATURE)."""

    distance: float
    max_curvature: float

    def context(self, track: Any, pos: tuple[float, float], lateral: float, off_track: bool) -> dict[str, Any]:
        """Where a command was given: the curvature ahead (1/m), the lane the car was in ("left",
        "right" or "off road") and whether the expert would have waited."""
        curvature = track.curvature_ahead(track.project(pos).s, self.distance)
        lane = "off road" if off_track else ("left" if lateral > 0 else "right")
        return {"curvature_1pm": _r(curvature, 3), "start_lane": lane,
                "expert_would_wait": bool(curvature > self.max_curvature)}


def judge_change(t: np.ndarray, lateral: np.ndarray, off: np.ndarray, offset: float, start: int, deadline: float,
                 centred: float, hold: float) -> tuple[bool | None, int | None, int]:
    """Judge one commanded change from step ``start`` on: ``(outcome, entered, last)``, outcome True
    (centred within ``centred`` m of ``offset`` before ``deadline`` s and for ``hold`` s), False
    (left the road, or too slow) or None (the steps ended first); ``entered`` the step its stay in
    the new lane began, ``last`` the last step looked at."""
    lane_ok = (np.abs(lateral - offset) < centred) & ~off
    entered: int | None = None
    i = start
    for i in range(start, t.size):
        if off[i]:  # left the road during the manoeuvre
            return False, entered, i
        if lane_ok[i]:
            if entered is None:
                if t[i] > deadline:
                    return False, None, i
                entered = i
            if t[i] - t[entered] >= hold - 1e-9:
                return True, entered, i
        else:
            entered = None
            if t[i] > deadline:
                return False, None, i
    return None, entered, i


def _r(x: float | None, nd: int = 4) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else round(float(x), nd)


def lane_metrics(t: Sequence[float], lateral: Sequence[float], commanded: Sequence[float],
                 off_track: Sequence[bool], lane_width: float, commands: Sequence[LaneCommand], *,
                 time_limit: float = TIME_LIMIT_S, hold: float = HOLD_S) -> dict[str, Any]:
    """Lane metrics of one episode (see the module docstring).

    Args:
        t: time of each step, seconds, increasing.
        lateral: the car's lateral position per step, metres left of the centre line (``-sim/cte``).
        commanded: centre of the commanded lane per step, metres left of the centre line.
        off_track: whether the car was off the road, per step.
        lane_width: width of one lane, metres.
        commands: the commanded changes (their ``offset`` is the lane commanded from ``time`` on).
        time_limit: seconds a change may take.
        hold: seconds the car must stay in the new lane.
    """
    t = np.asarray(t, float)
    lat = np.asarray(lateral, float)
    cmd = np.asarray(commanded, float)
    off = np.asarray(off_track, bool)
    if not (t.shape == lat.shape == cmd.shape == off.shape):
        raise ValueError("t, lateral, commanded and off_track must have one value per step")
    if lane_width <= 0 or time_limit <= 0 or hold < 0:
        raise ValueError(f"need lane_width > 0, time_limit > 0, hold >= 0 (got {lane_width}, {time_limit}, {hold})")
    err = lat - cmd
    in_lane = (np.abs(err) < lane_width / 2) & ~off
    centred = lane_width / 4  # how close to the new lane's centre a change must come, and stay
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    window = np.zeros(t.shape, bool)
    results: list[dict[str, Any]] = []
    for c in sorted(commands, key=lambda c: c.time):
        res: dict[str, Any] = {"time_s": _r(c.time, 3), "lane": c.lane, "offset_m": _r(c.offset, 3),
                               "success": None, "time_to_change_s": None,
                               "pos": [_r(c.pos[0], 3), _r(c.pos[1], 3)] if c.pos is not None else None,
                               **(c.context or {})}
        results.append(res)
        start = int(np.searchsorted(t, c.time - 1e-9))
        deadline = c.time + time_limit + 1e-9
        outcome, entered, i = judge_change(t, lat, off, c.offset, start, deadline, centred, hold)
        res["success"] = outcome
        if outcome:
            assert entered is not None
            res["time_to_change_s"] = _r(t[entered] - c.time, 3)
            window[start:i + 1] = True
        elif outcome is False:
            res["failure"] = "off_road" if off[i] else "too_slow"
            res["failed_at_s"] = _r(t[i], 3)
            window[start:max(i + 1, int(np.searchsorted(t, deadline)))] = True
        else:
            window[start:] = True
    keep = ~window & ~off
    abs_err = np.abs(err[keep])
    wrong = keep & (lat * cmd < 0)
    judged_cmds = [r for r in results if r["success"] is not None]
    ok = [r for r in judged_cmds if r["success"]]
    times = [r["time_to_change_s"] for r in ok]
    events = int(np.count_nonzero(off[1:] & ~off[:-1]) + (1 if off.size and off[0] else 0))
    return {
        "lane_changes": len(judged_cmds),
        "lane_changes_ok": len(ok),
        "lane_change_success_rate": _r(len(ok) / len(judged_cmds), 3) if judged_cmds else None,
        "mean_time_to_change_s": _r(float(np.mean(times)), 3) if times else None,
        "max_time_to_change_s": _r(max(times), 3) if times else None,
        "lane_mean_abs_error": _r(float(abs_err.mean())) if abs_err.size else None,
        "lane_p95_abs_error": _r(float(np.percentile(abs_err, 95))) if abs_err.size else None,
        "lane_max_abs_error": _r(float(abs_err.max())) if abs_err.size else None,
        "wrong_lane_s": _r(float(np.count_nonzero(wrong)) * dt, 3),
        "wrong_lane_fraction": _r(float(np.count_nonzero(wrong)) / max(1, int(np.count_nonzero(keep))), 4),
        "in_lane_fraction": _r(float(np.count_nonzero(in_lane & keep)) / max(1, int(np.count_nonzero(keep))), 4),
        "off_track_events": events,
        "commands": results,
        "lane_keeping_frames": int(np.count_nonzero(keep)),
    }


def overall_lane_metrics(tracks: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Lane metrics over several episodes: sums, and means weighted by changes or frames."""
    n = sum(r["lane_changes"] for r in tracks)
    ok = sum(r["lane_changes_ok"] for r in tracks)
    times = [c["time_to_change_s"] for r in tracks for c in r["commands"] if c["success"]]
    frames = sum(r["lane_keeping_frames"] for r in tracks)

    def weighted(key: str) -> float | None:
        pairs = [(r[key], r["lane_keeping_frames"]) for r in tracks if r[key] is not None]
        total = sum(w for _, w in pairs)
        return _r(sum(v * w for v, w in pairs) / total) if total else None

    return {
        "lane_changes": n,
        "lane_changes_ok": ok,
        "lane_change_success_rate": _r(ok / n, 3) if n else None,
        "mean_time_to_change_s": _r(float(np.mean(times)), 3) if times else None,
        "max_time_to_change_s": _r(max(times), 3) if times else None,
        "lane_mean_abs_error": weighted("lane_mean_abs_error"),
        "lane_max_abs_error": _r(max((r["lane_max_abs_error"] for r in tracks
                                      if r["lane_max_abs_error"] is not None), default=None)),
        "wrong_lane_s": _r(sum(r["wrong_lane_s"] for r in tracks), 3),
        "wrong_lane_fraction": weighted("wrong_lane_fraction"),
        "off_track_events": sum(r["off_track_events"] for r in tracks),
        "lane_keeping_frames": frames,
    }


class CommandedLane:
    """Part: the centre of the lane the active behaviour asks for (``behavior/label``, e.g.
    Left_Lane) -> ``sim/lane_center`` (m left of the centre line; None when the label names no lane
    or the track has one lane). The simulator re-centres a car that left the road in that lane.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("behavior/label",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("sim/lane_center",)

    def __init__(self, sim: SimCar) -> None:
        self.sim = sim

    def run(self, label: Any) -> float | None:
        lane = behavior_lane(label) if isinstance(label, str) else None
        if lane is None or self.sim.track.lanes != 2:
            return None
        offset = self.sim.track.lane_offset(lane)
        self.sim.start_offset = offset
        return offset


class LaneMetrics:
    """Part: records one episode's lane keeping and commanded changes; :meth:`result` scores them
    (:func:`lane_metrics`). A change of ``sim/lane_center`` is a commanded change.

    Args:
        dt: seconds per loop.
        lane_width: width of one lane, metres.
        time_limit, hold: see :func:`lane_metrics`.
        rule: the expert's rule for starting a change; with it (and :meth:`on_track`) each command
            says where it was given (:meth:`ChangeRule.context`).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("sim/cte", "sim/off_track", "sim/lane_center", "sim/pos", "behavior/label")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("sim/pos", "behavior/label")
    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, dt: float, lane_width: float, *, time_limit: float = TIME_LIMIT_S, hold: float = HOLD_S,
                 rule: ChangeRule | None = None) -> None:
        self.dt, self.lane_width = float(dt), float(lane_width)
        self.time_limit, self.hold = float(time_limit), float(hold)
        self.rule = rule
        self.track: Any = None
        self.t: list[float] = []
        self.lateral: list[float] = []
        self.commanded: list[float] = []
        self.off: list[bool] = []
        self.commands: list[LaneCommand] = []
        self._time = 0.0
        self._last: float | None = None
        self._pos: tuple[float, float] | None = None

    def run(self, cte: Any, off_track: Any, center: Any, pos: Any, label: Any) -> None:
        self._time += self.dt
        if cte is None or center is None:
            return  # no lane to keep (one-lane track, a behaviour that names no lane)
        c = float(center)
        if self._last is not None and c != self._last:
            here = (float(pos[0]), float(pos[1])) if pos is not None else self._pos
            context = None
            if self.rule is not None and self.track is not None and here is not None:
                context = self.rule.context(self.track, here, -float(cte), bool(off_track))
            self.commands.append(LaneCommand(self._time, c, label if isinstance(label, str) else "", self._pos,
                                             context))
        self._last = c
        self.t.append(self._time)
        self.lateral.append(-float(cte))  # sim/cte is positive to the right
        self.commanded.append(c)
        self.off.append(bool(off_track))
        if pos is not None:
            self._pos = (float(pos[0]), float(pos[1]))

    @classmethod
    def from_config(cls, cfg: Any) -> LaneMetrics:
        """Scored as SIM_EVAL_LANE_CHANGE_* say, on lanes of half SIM_ROAD_WIDTH; each command located
        by the expert's rule (SIM_EXPERT_LANE_CHANGE_DISTANCE + SIM_EXPERT_LOOKAHEAD, _MAX_CURVATURE)."""
        rule = ChangeRule(cfg.SIM_EXPERT_LANE_CHANGE_DISTANCE + cfg.SIM_EXPERT_LOOKAHEAD,
                          cfg.SIM_EXPERT_LANE_CHANGE_MAX_CURVATURE)
        return cls(1.0 / cfg.DRIVE_LOOP_HZ, cfg.SIM_ROAD_WIDTH / 2, time_limit=cfg.SIM_EVAL_LANE_CHANGE_TIME_LIMIT,
                   hold=cfg.SIM_EVAL_LANE_CHANGE_HOLD, rule=rule)

    def on_track(self, track: Any) -> None:
        """The episode's track (:class:`parts.sim.track.Track`), where commands are located."""
        self.track = track

    def result(self) -> dict[str, Any]:
        """The episode's lane metrics (see :func:`lane_metrics`)."""
        return lane_metrics(self.t, self.lateral, self.commanded, self.off, self.lane_width, self.commands,
                            time_limit=self.time_limit, hold=self.hold)
