"""The path follower: pure pursuit towards a point ahead on the path plus a PID on the cross-track
error for the steering, the recorded speed (or a constant throttle) for the throttle.

It writes ``pilot/angle`` and ``pilot/throttle`` exactly like a learned pilot, so drive mode, the
e-stop, the speed limit, obstacle stop and neutral on exit act on it unchanged.
"""

from __future__ import annotations

import logging
import math
from typing import Any, ClassVar

import numpy as np

from parts.drive.speed import PIController
from parts.path.geometry import cross_track_error, nearest_index, point_ahead, pure_pursuit
from vehicle.keys import Mode, parse_mode

logger = logging.getLogger(__name__)


class PID:
    """A PID controller on an error: ``kp e + ki integral(e) + kd de/dt``, the integral clamped to
    ``±integral_limit`` (no wind-up)."""

    def __init__(self, kp: float, ki: float = 0.0, kd: float = 0.0, integral_limit: float = 1.0) -> None:
        self.kp, self.ki, self.kd, self.integral_limit = float(kp), float(ki), float(kd), float(integral_limit)
        self.reset()

    def reset(self) -> None:
        """Forget the integral and the last error."""
        self.integral = 0.0
        self.last: float | None = None

    def update(self, error: float, dt: float) -> float:
        """The output for ``error`` after ``dt`` seconds."""
        derivative = 0.0 if self.last is None or dt <= 0 else (error - self.last) / dt
        self.last = error
        if self.ki > 0:
            lim = self.integral_limit / self.ki
            self.integral = min(lim, max(-lim, self.integral + error * dt))
        return self.kp * error + self.ki * self.integral + self.kd * derivative


class PathFollower:
    """Part: follows ``path/xy`` from the localiser's pose while a pilot mode is engaged.

    ``run(x, y, heading, ok, xy, speeds, version, recording, mode, measured_speed)``; outputs
    ``pilot/angle, pilot/throttle, path/target_x, path/target_y, path/cte, path/state``.

    Steering: pure pursuit on the point ``look_ahead_dist`` metres along the path after the nearest
    point (when the heading is known and ``look_ahead_dist`` > 0) plus ``pid`` on the signed
    cross-track error to the line through the points ``look_behind`` before and ``look_ahead``
    after the nearest one (DonkeyCar's CTE). Throttle: ``constant_throttle`` when given, else a PI
    controller (``speed_pi``) holding the recorded speed at the nearest point, times
    ``speed_scale``, between ``min_speed`` and ``max_speed``. An open path ends with throttle 0
    (state "done"); a closed one (``loop``, or None: its end near its start) goes round again.
    A pose that is not trustworthy (``loc/ok`` False) gives state "lost" and throttle 0.

    Args:
        dt: seconds per loop (1 / DRIVE_LOOP_HZ).
        wheel_base, max_steering_angle: the car's geometry for pure pursuit (WHEEL_BASE,
            MAX_STEERING_ANGLE).
    """

    #: the measured speed is ``enc/speed``; a car measuring it elsewhere renames it at ``V.add``
    INPUTS: ClassVar[tuple[str, ...]] = ("loc/x", "loc/y", "loc/angle", "loc/ok", "path/xy", "path/speed",
                                         "path/version", "path/recording", "user/mode", "enc/speed")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("enc/speed",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("pilot/angle", "pilot/throttle", "path/target_x", "path/target_y",
                                          "path/cte", "path/state")

    def __init__(self, dt: float, *, pid: PID | None = None, look_ahead_dist: float = 0.5, look_ahead: int = 1,
                 look_behind: int = 1, search_length: int | None = None, wheel_base: float = 0.26,
                 max_steering_angle: float = 0.436, constant_throttle: float | None = None,
                 speed_pi: PIController | None = None, speed_scale: float = 1.0, min_speed: float = 0.3,
                 max_speed: float | None = None, loop: bool | None = None, close_dist: float = 1.0) -> None:
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s, got {dt!r}")
        self.dt = float(dt)
        self.pid = pid or PID(0.5, 0.0, 0.2)
        self.look_ahead_dist = float(look_ahead_dist)
        self.look_ahead, self.look_behind = int(look_ahead), int(look_behind)
        self.search_length = search_length
        self.wheel_base, self.max_steering_angle = float(wheel_base), float(max_steering_angle)
        self.constant_throttle = constant_throttle
        self.speed_pi = speed_pi or PIController(0.3, 0.6)
        self.speed_scale, self.min_speed, self.max_speed = float(speed_scale), float(min_speed), max_speed
        self.loop, self.close_dist = loop, float(close_dist)
        self._version: Any = object()
        self.index: int | None = None
        self.closed = False
        self.done = False
        self._following = False
        self._no_speed_warned = False

    @classmethod
    def from_config(cls, cfg: Any) -> PathFollower:
        """PATH_*, PID_*, USE_CONSTANT_THROTTLE, PID_THROTTLE, PILOT_SPEED_KP/KI/MAX_THROTTLE,
        WHEEL_BASE, MAX_STEERING_ANGLE and DRIVE_LOOP_HZ."""
        return cls(1.0 / cfg.DRIVE_LOOP_HZ, pid=PID(cfg.PID_P, cfg.PID_I, cfg.PID_D),
                   look_ahead_dist=cfg.PATH_LOOK_AHEAD_DIST, look_ahead=cfg.PATH_LOOK_AHEAD,
                   look_behind=cfg.PATH_LOOK_BEHIND, search_length=cfg.PATH_SEARCH_LENGTH,
                   wheel_base=cfg.WHEEL_BASE, max_steering_angle=cfg.MAX_STEERING_ANGLE,
                   constant_throttle=cfg.PID_THROTTLE if cfg.USE_CONSTANT_THROTTLE else None,
                   speed_pi=PIController(cfg.PILOT_SPEED_KP, cfg.PILOT_SPEED_KI, 0.0, cfg.PILOT_SPEED_MAX_THROTTLE),
                   speed_scale=cfg.PATH_SPEED_SCALE, min_speed=cfg.PATH_MIN_SPEED, max_speed=cfg.PATH_MAX_SPEED,
                   loop=cfg.PATH_LOOP, close_dist=cfg.PATH_LOOP_CLOSE_DIST)

    def _new_path(self, xy: np.ndarray) -> None:
        self.index = None
        self.done = False
        self.closed = self.loop if self.loop is not None else (
            len(xy) > 2 and float(np.linalg.norm(xy[-1] - xy[0])) <= self.close_dist)
        self.pid.reset()
        self.speed_pi.reset()

    def _stop_following(self) -> None:
        self._following = False
        self.pid.reset()
        self.speed_pi.reset()

    def run(self, x: float | None, y: float | None, heading: float | None, ok: bool | None, xy: np.ndarray | None,
            speeds: np.ndarray | None, version: Any, recording: bool | None, mode: Any,
            measured_speed: float | None) -> tuple[Any, ...]:
        """This loop's (pilot/angle, pilot/throttle, path/target_x, path/target_y, path/cte, path/state)."""
        if version != self._version:
            self._version = version
            self._new_path(xy if xy is not None else np.zeros((0, 2)))
        following = parse_mode(mode) is not Mode.USER
        if following and not self._following:
            self.done = False  # engaging again restarts a finished path
        if not following:
            self._stop_following()
        self._following = following
        if recording:
            return 0.0, 0.0, None, None, None, "recording"
        if xy is None or len(xy) < 2:
            return 0.0, 0.0, None, None, None, "empty"
        if not ok or x is None or y is None:
            self._stop_following()
            self._following = following
            return 0.0, 0.0, None, None, None, "lost"
        n = len(xy)
        start = None if self.index is None else self.index - (self.look_behind if self.closed else 0)
        self.index = nearest_index(xy, x, y, start, self.search_length, self.closed)
        i = self.index
        cte = cross_track_error(xy, x, y, i, self.look_behind, self.look_ahead, self.closed)
        if not following:
            return 0.0, 0.0, None, None, cte, "ready"
        if not self.closed and i == n - 1:
            prev, last = xy[-2], xy[-1]
            if (x - last[0]) * (last[0] - prev[0]) + (y - last[1]) * (last[1] - prev[1]) >= 0:
                if not self.done:
                    logger.info("path: end reached, stopping")
                self.done = True
        if self.done:
            return 0.0, 0.0, None, None, cte, "done"
        tx, ty, _ = point_ahead(xy, i, max(self.look_ahead_dist, 1e-3), self.closed)
        steer = self.pid.update(cte, self.dt)
        if self.look_ahead_dist > 0 and heading is not None:
            steer += pure_pursuit(x, y, heading, tx, ty, self.wheel_base, self.max_steering_angle)
        angle = max(-1.0, min(1.0, steer))
        return angle, self._throttle(speeds, i, measured_speed), tx, ty, cte, "following"

    def _throttle(self, speeds: np.ndarray | None, i: int, measured: float | None) -> float:
        if self.constant_throttle is not None:
            return float(self.constant_throttle)
        recorded = float(speeds[i]) if speeds is not None and len(speeds) > i else 0.0
        target = max(self.min_speed, recorded * self.speed_scale)
        if self.max_speed is not None:
            target = min(target, self.max_speed)
        if measured is None or not math.isfinite(measured):
            if not self._no_speed_warned:
                logger.warning("path follow: no measured speed (enc/speed): throttle 0; fit an encoder or GPS, or "
                               "set USE_CONSTANT_THROTTLE = True")
                self._no_speed_warned = True
            self.speed_pi.reset()
            return 0.0
        self.speed_pi.set_desired(target)
        return self.speed_pi.update(float(measured), self.dt)
