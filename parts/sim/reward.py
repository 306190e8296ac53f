"""Reward functions in AWS DeepRacer's style for the simulator's Gymnasium environment.

A reward file is plain Python that defines ``reward_function(params) -> float``; ``params`` holds
DeepRacer's documented input parameters, computed from the simulator's own telemetry
(:func:`reward_params`), plus a few of ours (``laps``, ``lap_time``, ``cte``, ``heading_error``,
``throttle``, ``dt``). docs/rl.md is the reference. :func:`default_reward` is used when no file is
given; :func:`speed_reward` (``--reward speed``) also pays for speed itself, for a policy that
drives the throttle. :func:`load_reward_function` reads a user's file (or a built-in's name); what it returns raises
:class:`RewardError` (one line naming the file and line) when the function raises or returns
something that is not a finite number.
"""

from __future__ import annotations

import contextlib
import copy
import math
import signal
import sys
import threading
import traceback
import types
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from parts.sim.telemetry import TelemetryFrame
from parts.sim.track import Track
from vehicle.errors import VehicleError, VehicleStopped

#: half the width of a 1:10 car between its wheels' outer edges, metres (all_wheels_on_track)
CAR_HALF_WIDTH = 0.1
#: spacing of the waypoints handed to reward functions, metres (DeepRacer's are ~0.3-0.6 m apart)
WAYPOINT_SPACING = 0.2
#: speed at which :func:`speed_reward` pays what :func:`default_reward` does, m/s
SPEED_REWARD_REF = 1.0

RewardFn = Callable[[dict[str, Any]], float]


class RewardError(VehicleError, ValueError):
    """A reward file is missing, does not define reward_function, or the function failed."""


class TrackWaypoints:
    """A track's waypoints in DeepRacer's form, computed once per track."""

    def __init__(self, track: Track) -> None:
        stride = max(1, round(WAYPOINT_SPACING / (track.length / track.n)))
        pts = track.points[::stride]
        self.track = track
        self.spacing = track.length / len(pts)
        # points as tuples: a reward function gets a fresh list of them each call (reward_params)
        # and cannot edit one in place for the next call
        self.waypoints: tuple[tuple[float, float], ...] = tuple((round(float(x), 4), round(float(y), 4))
                                                                for x, y in pts)
        x, y = track.points[:, 0], track.points[:, 1]
        area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
        self.is_reversed = area < 0  # DeepRacer: True when the car drives clockwise

    def closest(self, s: float) -> list[int]:
        """Indices of the waypoints behind and ahead of arc length ``s`` (metres)."""
        n = len(self.waypoints)
        i = int(s / self.spacing) % n
        return [i, (i + 1) % n]


def reward_params(frame: TelemetryFrame, wp: TrackWaypoints, *, steer_rad: float, heading_rad: float,
                  steps: int, best_distance: float, throttle: float, dt: float) -> dict[str, Any]:
    """DeepRacer's ``params`` for one step (docs/rl.md lists every key, its unit and range).

    Args:
        frame: the simulator's telemetry after the step.
        wp: the track's waypoints.
        steer_rad: front wheel angle, radians, positive = left.
        heading_rad: the car's yaw, radians counter-clockwise from +x.
        steps: steps taken in this episode.
        best_distance: most forward progress along the centre line since the episode began, metres.
        throttle: the throttle applied this step.
        dt: simulated seconds per step.
    """
    track = wp.track
    dist = abs(frame.cte)
    return {
        "all_wheels_on_track": dist + CAR_HALF_WIDTH <= track.width / 2,
        "x": float(frame.pos[0]),
        "y": float(frame.pos[1]),
        "closest_objects": [],
        "closest_waypoints": wp.closest(frame.s),
        "distance_from_center": float(dist),
        "heading": math.degrees(math.atan2(math.sin(heading_rad), math.cos(heading_rad))),
        "is_crashed": False,
        "is_left_of_center": frame.cte < 0,
        "is_offtrack": bool(frame.off_track),
        "is_reversed": wp.is_reversed,
        "objects_distance": [],
        "objects_heading": [],
        "objects_left_of_center": [],
        "objects_location": [],
        "objects_speed": [],
        "progress": 100.0 * max(0.0, best_distance) / track.length,
        "speed": float(frame.speed),
        "steering_angle": math.degrees(steer_rad),
        "steps": int(steps),
        "track_length": float(track.length),
        "track_width": float(track.width),
        "waypoints": list(wp.waypoints),  # its own list each call (a shallow copy: ~1 µs)
        # ours, beyond DeepRacer's
        "laps": int(frame.lap),
        "lap_time": frame.lap_time,
        "cte": float(frame.cte),
        "heading_error": math.degrees(frame.heading_error),
        "throttle": float(throttle),
        "dt": float(dt),
    }


def default_reward(params: dict[str, Any]) -> float:
    """Speed along the track, weighted by closeness to the centre line (0 off the road).

    Rewards driving, not standing still: per step it is the metres gained along the track times
    ``1 - (distance from centre / half the width)^2``, so a lap's total is about the track's length
    when the car keeps to the centre.
    """
    if params["is_offtrack"]:
        return 0.0
    half = params["track_width"] / 2
    centre = max(0.0, 1.0 - (params["distance_from_center"] / half) ** 2)
    along = params["speed"] * math.cos(math.radians(params["heading_error"]))
    return centre * max(0.0, along) * params["dt"]


def speed_reward(params: dict[str, Any]) -> float:
    """:func:`default_reward` times the speed along the track over SPEED_REWARD_REF (1 m/s).

    A lap's total is then about the track's length times the mean speed in m/s: a lap driven
    twice as fast earns twice as much, while leaving the road forfeits the rest of the lap (0
    off the road, and the episode ends). With :func:`default_reward` a lap earns about the same
    at any speed, so only the discount favours the faster one.
    """
    along = params["speed"] * math.cos(math.radians(params["heading_error"]))
    return default_reward(params) * max(0.0, along) / SPEED_REWARD_REF


#: reward functions chosen by name (``--reward speed``) instead of a file
BUILTIN_REWARDS: dict[str, RewardFn] = {"default": default_reward, "speed": speed_reward}


def load_reward_function(path: str | Path | None, time_limit: float | None = None) -> RewardFn:
    """The reward function of a user's file (None: :func:`default_reward`; a name of
    BUILTIN_REWARDS that is not a file: that function), wrapped so that an exception, a call that
    takes longer than ``time_limit`` seconds (RL_REWARD_TIME_LIMIT_S; None: no limit) or a value
    that is not a finite number raises :class:`RewardError` naming the line.

    Raises:
        RewardError: the file is missing, does not compile, or defines no ``reward_function``.
    """
    if path is None:
        return default_reward
    file = Path(path).expanduser().resolve()
    if not file.is_file():
        if str(path) in BUILTIN_REWARDS:
            return BUILTIN_REWARDS[str(path)]
        raise RewardError(f"{path}: no such reward file; give a Python file that defines reward_function(params), "
                          f"or one of the built-in rewards {', '.join(BUILTIN_REWARDS)}")
    source = file.read_text()
    try:
        code = compile(source, str(file), "exec")
    except SyntaxError as exc:
        raise RewardError(f"{file}:{exc.lineno}: syntax error in the reward file: {exc.msg}") from None
    namespace: dict[str, Any] = {"__name__": "reward_file", "__file__": str(file)}
    try:
        exec(code, namespace)  # the user's own file, like myconfig.py
    except Exception as exc:
        raise RewardError(f"{_where(file, exc)}: the reward file failed while loading: "
                          f"{type(exc).__name__}: {exc}") from None
    fn = namespace.get("reward_function")
    if not callable(fn):
        raise RewardError(f"{file}: defines no reward_function(params); add `def reward_function(params): ... "
                          "return float(reward)`")
    return _Checked(fn, file, time_limit)


class _TimeUp(BaseException):
    """Raised into a reward function that ran out of time (a BaseException: the function's own
    ``except Exception`` cannot swallow it)."""


@contextlib.contextmanager
def _time_limit(seconds: float | None) -> Iterator[None]:
    """Raise :class:`_TimeUp` in this block after ``seconds`` (SIGALRM). Only where a signal can
    be delivered: in the main thread of a process on a POSIX system; elsewhere no limit."""
    if seconds is None or threading.current_thread() is not threading.main_thread() \
            or not hasattr(signal, "setitimer"):
        yield
        return

    def time_up(_signum: int, _frame: Any) -> None:
        raise _TimeUp

    old = signal.signal(signal.SIGALRM, time_up)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


class _Checked:
    """A user's reward_function that fails with a one-line RewardError instead of a traceback."""

    def __init__(self, fn: Callable[[dict[str, Any]], Any], file: Path, time_limit: float | None = None) -> None:
        self.fn, self.file, self.time_limit = fn, file, time_limit
        self.line = getattr(getattr(fn, "__code__", None), "co_firstlineno", 0)

    def __call__(self, params: dict[str, Any]) -> float:
        try:
            with _time_limit(self.time_limit):
                value = self.fn(params)
        except _TimeUp:
            raise RewardError(f"{self.file}:{self.line}: reward_function did not return within {self.time_limit:g} s "
                              "(RL_REWARD_TIME_LIMIT_S): look for a loop that never ends, or raise the limit in "
                              "myconfig.py") from None
        except VehicleStopped:  # a stop signal arrived during the call: not the function's fault
            raise
        except Exception as exc:
            raise RewardError(f"{_where(self.file, exc, self.line)}: reward_function raised "
                              f"{type(exc).__name__}: {exc}") from None
        if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating) \
                or not math.isfinite(float(value)):
            raise RewardError(f"{self.file}:{_return_line(self.fn, params, self.line)}: reward_function returned "
                              f"{value!r} ({type(value).__name__}); it must return a finite number, e.g. float(reward)")
        return float(value)

    def __reduce__(self) -> tuple[Any, ...]:  # vectorised environments send it to worker processes
        return (load_reward_function, (str(self.file), self.time_limit))


def _return_line(fn: Callable[[dict[str, Any]], Any], params: dict[str, Any], default: int) -> int:
    """The line of ``fn``'s ``return`` statement for ``params``: the call is run again under a
    tracer (only on this error path, so a normal call costs nothing)."""
    code = getattr(fn, "__code__", None)
    line = default

    def tracer(frame: types.FrameType, event: str, _arg: Any) -> Any:
        nonlocal line
        if frame.f_code is not code:
            return None
        if event == "return" and frame.f_lineno is not None:
            line = frame.f_lineno
        return tracer

    old = sys.gettrace()
    sys.settrace(tracer)
    try:
        with _time_limit(1.0):
            fn(copy.deepcopy(params))
    except (Exception, _TimeUp):  # only looking for the line; the caller reports the value
        pass
    finally:
        sys.settrace(old)
    return line


def _where(file: Path, exc: BaseException, default_line: int = 0) -> str:
    """``file:line`` of the innermost frame of ``exc`` in the user's file."""
    line = default_line
    for frame in traceback.extract_tb(exc.__traceback__):
        if frame.filename == str(file):
            line = frame.lineno or line
    return f"{file}:{line}"
