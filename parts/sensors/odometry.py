"""Odometry: encoder ticks -> distance and speed, and distance + steering -> pose.

- :class:`Odometer`: cumulative ticks -> ``enc/distance`` (m) and ``enc/speed`` (m/s) over the
  last ``smoothing`` readings (DonkeyCar's ODOM_SMOOTHING), from MM_PER_TICK.
- :class:`BicyclePose`: a car (front steering, WHEEL_BASE, MAX_STEERING_ANGLE): the distance
  driven since the last loop and the steering command give the pose ``pos/x, pos/y, pos/angle``
  and velocities ``vel/x, vel/y, vel/angle`` (world frame, metres, radians, counter-clockwise).
- :class:`UnicyclePose`: a differential drive (AXLE_LENGTH): left and right wheel distances give
  the same keys.

Both integrate each loop's step as a circular arc, so a constant-curvature drive is followed exactly.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import Any, ClassVar

from vehicle.config import check_settings

Pose = tuple[float, float, float]


def wrap_angle(a: float) -> float:
    """``a`` in [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def arc_step(x: float, y: float, heading: float, distance: float, turn: float) -> Pose:
    """The pose after driving ``distance`` metres along a circular arc (or a line) while the heading
    changes by ``turn`` radians: the chord of the arc points along the midpoint heading."""
    half = 0.5 * turn
    chord = distance if abs(half) < 1e-9 else distance * math.sin(half) / half
    mid = heading + half
    return x + chord * math.cos(mid), y + chord * math.sin(mid), wrap_angle(heading + turn)


class Odometer:
    """Part: ticks and their time -> distance (m) and speed (m/s).

    ``run(ticks, timestamp) -> (distance, speed)``; None in (a stale encoder) gives None out, and
    the speed history restarts, so a speed is never computed across a gap.

    Args:
        m_per_tick: metres per tick (MM_PER_TICK / 1000).
        smoothing: readings over which the speed is averaged (ODOM_SMOOTHING, >= 1): the speed is
            the distance between the newest and the ``smoothing``-th previous reading over their time.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("enc/ticks", "enc/timestamp")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("enc/distance", "enc/speed")
    RECORDED: ClassVar[Mapping[str, str]] = {"enc/speed": "float", "enc/distance": "float"}

    def __init__(self, m_per_tick: float, smoothing: int = 1) -> None:
        check_settings(MM_PER_TICK=m_per_tick * 1000.0, ODOM_SMOOTHING=smoothing)
        self.m_per_tick = float(m_per_tick)
        self.smoothing = int(smoothing)
        self._history: deque[tuple[float, int]] = deque(maxlen=self.smoothing + 1)
        self.speed = 0.0

    @classmethod
    def from_config(cls, cfg: Any) -> Odometer:
        """MM_PER_TICK and ODOM_SMOOTHING."""
        return cls(cfg.MM_PER_TICK / 1000.0, cfg.ODOM_SMOOTHING)

    def run(self, ticks: int | None, timestamp: float | None) -> tuple[float | None, float | None]:
        """(distance, speed) for this reading; (None, None) without one."""
        if ticks is None or timestamp is None:
            self._history.clear()
            return None, None
        if self._history and timestamp <= self._history[-1][0]:
            if ticks == self._history[-1][1]:  # the same reading again: keep the speed
                return ticks * self.m_per_tick, self.speed
        else:
            self._history.append((float(timestamp), int(ticks)))
        if len(self._history) >= 2:
            (t0, n0), (t1, n1) = self._history[0], self._history[-1]
            if t1 > t0:
                self.speed = (n1 - n0) * self.m_per_tick / (t1 - t0)
        else:
            self.speed = 0.0
        return ticks * self.m_per_tick, self.speed


class _PoseBase:
    OUTPUTS: ClassVar[tuple[str, ...]] = ("pos/x", "pos/y", "pos/angle", "vel/x", "vel/y", "vel/angle")
    RECORDED: ClassVar[Mapping[str, str]] = dict.fromkeys(OUTPUTS, "float")

    def __init__(self, x: float = 0.0, y: float = 0.0, heading: float = 0.0) -> None:
        self.x, self.y, self.heading = float(x), float(y), float(heading)
        self._last: tuple[float, ...] | None = None  # previous distances
        self._t: float | None = None

    def reset(self, x: float = 0.0, y: float = 0.0, heading: float = 0.0) -> None:
        """Set the pose (the path follower's 'reset origin')."""
        self.x, self.y, self.heading = float(x), float(y), float(heading)

    def _advance(self, distance: float, turn: float, timestamp: float | None) -> tuple[float, ...]:
        x0, y0, h0 = self.x, self.y, self.heading
        self.x, self.y, self.heading = arc_step(x0, y0, h0, distance, turn)
        dt = None if timestamp is None or self._t is None else timestamp - self._t
        self._t = timestamp
        if dt is None or dt <= 0:
            vel = (0.0, 0.0, 0.0)
        else:
            vel = ((self.x - x0) / dt, (self.y - y0) / dt, turn / dt)
        return (self.x, self.y, self.heading, *vel)

    def _stale(self) -> tuple[None, ...]:
        self._last = None
        self._t = None
        return (None,) * 6


class BicyclePose(_PoseBase):
    """Part: pose of a car from the distance driven and the steering command (bicycle model).

    ``run(distance, timestamp, angle)``; ``angle`` is the steering command in [-1, 1] (-1 = full
    left, DonkeyCar's convention: the wheels then turn MAX_STEERING_ANGLE to the left). Add it
    right after the encoder/odometer: it reads the ``angle`` of the previous loop, the command that
    was acting while the wheels turned.

    Args:
        wheel_base: metres between the axles (WHEEL_BASE).
        max_steering_angle: front wheel angle at full steering, radians (MAX_STEERING_ANGLE).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("enc/distance", "enc/timestamp", "angle")
    FEEDBACK: ClassVar[tuple[str, ...]] = ("angle",)

    def __init__(self, wheel_base: float, max_steering_angle: float, **pose: float) -> None:
        check_settings(WHEEL_BASE=wheel_base, MAX_STEERING_ANGLE=max_steering_angle)
        super().__init__(**pose)
        self.wheel_base, self.max_steering_angle = float(wheel_base), float(max_steering_angle)

    @classmethod
    def from_config(cls, cfg: Any) -> BicyclePose:
        """WHEEL_BASE and MAX_STEERING_ANGLE."""
        return cls(cfg.WHEEL_BASE, cfg.MAX_STEERING_ANGLE)

    def run(self, distance: float | None, timestamp: float | None, angle: float | None) -> tuple[float | None, ...]:
        """(pos/x, pos/y, pos/angle, vel/x, vel/y, vel/angle); all None while the distance is unknown."""
        if distance is None:
            return self._stale()
        last = self._last
        self._last = (float(distance),)
        if last is None:
            return self._advance(0.0, 0.0, timestamp)
        ds = float(distance) - last[0]
        steer = -max(-1.0, min(1.0, float(angle or 0.0))) * self.max_steering_angle
        return self._advance(ds, ds * math.tan(steer) / self.wheel_base, timestamp)


class UnicyclePose(_PoseBase):
    """Part: pose of a differential drive from its left and right wheel distances (unicycle model).

    ``run(left_distance, right_distance, timestamp)``.

    Args:
        axle_length: metres between the left and right wheels (AXLE_LENGTH).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("enc/left/distance", "enc/right/distance", "enc/timestamp")

    def __init__(self, axle_length: float, **pose: float) -> None:
        check_settings(AXLE_LENGTH=axle_length)
        super().__init__(**pose)
        self.axle_length = float(axle_length)

    @classmethod
    def from_config(cls, cfg: Any) -> UnicyclePose:
        """AXLE_LENGTH."""
        return cls(cfg.AXLE_LENGTH)

    def run(self, left: float | None, right: float | None, timestamp: float | None) -> tuple[float | None, ...]:
        """(pos/x, pos/y, pos/angle, vel/x, vel/y, vel/angle); all None while a distance is unknown."""
        if left is None or right is None:
            return self._stale()
        last = self._last
        self._last = (float(left), float(right))
        if last is None:
            return self._advance(0.0, 0.0, timestamp)
        dl, dr = float(left) - last[0], float(right) - last[1]
        return self._advance(0.5 * (dl + dr), (dr - dl) / self.axle_length, timestamp)


class DifferentialOdometer:
    """Part: left and right ticks of a differential drive -> each wheel's distance, and the car's
    distance and speed (their means). ``run(left, right, timestamp)``; None in gives None out."""

    INPUTS: ClassVar[tuple[str, ...]] = ("enc/left/ticks", "enc/right/ticks", "enc/timestamp")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("enc/left/distance", "enc/right/distance", "enc/distance", "enc/speed")
    RECORDED: ClassVar[Mapping[str, str]] = Odometer.RECORDED

    def __init__(self, m_per_tick: float, smoothing: int = 1) -> None:
        self.left, self.right = Odometer(m_per_tick, smoothing), Odometer(m_per_tick, smoothing)

    @classmethod
    def from_config(cls, cfg: Any) -> DifferentialOdometer:
        """MM_PER_TICK and ODOM_SMOOTHING."""
        return cls(cfg.MM_PER_TICK / 1000.0, cfg.ODOM_SMOOTHING)

    def run(self, left: int | None, right: int | None, timestamp: float | None) -> tuple[float | None, ...]:
        """(left distance, right distance, distance, speed)."""
        dl, vl = self.left.run(left, timestamp)
        dr, vr = self.right.run(right, timestamp)
        if dl is None or dr is None or vl is None or vr is None:
            return None, None, None, None
        return dl, dr, 0.5 * (dl + dr), 0.5 * (vl + vr)
