"""Obstacle stop: brake when the LiDAR sees something closer than a set distance ahead, in any mode."""

from __future__ import annotations

import logging
import math
from typing import Any, ClassVar

from parts.sensors.lidar import front_distance
from vehicle.config import check_settings

logger = logging.getLogger(__name__)


class ObstacleStop:
    """Part: the final ``throttle`` cut to a brake while an obstacle is near ahead.

    ``run(throttle, dist_array, lidar_ok, speed) -> (throttle, obstacle/stop, obstacle/distance)``.
    Add it after the drive mode and the speed limit, before the drivetrain: it acts on the command
    the car will drive with, whatever mode produced it.

    The stop acts when the nearest return ahead is closer than ``distance`` plus the distance the
    car needs to stop from its measured speed v: ``v * latency + v^2 / (2 * decel)``, so a fast car
    starts braking early enough to stand still ``distance`` metres before the obstacle. A forward
    throttle is then replaced by ``-brake`` while the car still rolls forward faster than
    ``rolling`` m/s (a hobby ESC brakes on a negative command while moving) and by 0 below that or
    when the speed is unknown (a negative command at rest would make a car reverse; drag stops it
    from a walking pace). Reverse throttle passes: backing away is allowed.

    Args:
        distance: metres ahead at which the car should stand (OBSTACLE_STOP_DISTANCE).
        half_angle_deg: half width of the cone ahead that is watched (OBSTACLE_STOP_ANGLE).
        brake: brake command magnitude in [0, 1] (OBSTACLE_STOP_BRAKE); 0 = coast to neutral.
        decel: m/s^2 the car decelerates at under that brake (OBSTACLE_STOP_DECEL; be modest).
        latency: seconds from a return to the brake acting (a LiDAR turn plus a loop).
        stop_when_blind: a stale LiDAR, or an unknown bin (no fresh reading) in the cone ahead,
            stops the car too (OBSTACLE_STOP_WHEN_BLIND).
        rolling: m/s above which the brake is held; below it the throttle is neutral.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("throttle", "lidar/dist_array", "lidar/ok", "enc/speed")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("enc/speed",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("throttle", "obstacle/stop", "obstacle/distance")

    def __init__(self, distance: float = 0.5, *, half_angle_deg: float = 20.0, brake: float = 0.5,
                 decel: float = 3.0, latency: float = 0.15, stop_when_blind: bool = True,
                 rolling: float = 0.3) -> None:
        check_settings(OBSTACLE_STOP_DISTANCE=distance, OBSTACLE_STOP_ANGLE=half_angle_deg, OBSTACLE_STOP_BRAKE=brake,
                       OBSTACLE_STOP_DECEL=decel)
        if not latency >= 0:
            raise ValueError(f"ObstacleStop: latency must be >= 0 s, got {latency!r}")
        self.distance, self.half_angle_deg, self.brake = float(distance), float(half_angle_deg), float(brake)
        self.decel, self.latency = float(decel), float(latency)
        self.stop_when_blind, self.rolling = bool(stop_when_blind), float(rolling)
        self.stopping = False

    @classmethod
    def from_config(cls, cfg: Any) -> ObstacleStop:
        """OBSTACLE_STOP_DISTANCE, _ANGLE, _BRAKE, _DECEL, _WHEN_BLIND."""
        return cls(cfg.OBSTACLE_STOP_DISTANCE, half_angle_deg=cfg.OBSTACLE_STOP_ANGLE, brake=cfg.OBSTACLE_STOP_BRAKE,
                   decel=cfg.OBSTACLE_STOP_DECEL, stop_when_blind=cfg.OBSTACLE_STOP_WHEN_BLIND)

    def trigger(self, speed: float | None) -> float:
        """Distance ahead (m) below which the stop acts at ``speed`` (m/s; None = unknown)."""
        v = max(0.0, speed) if speed is not None and math.isfinite(speed) else 0.0
        return self.distance + v * self.latency + v * v / (2.0 * self.decel)

    def run(self, throttle: float | None, dist_array: list[float] | None, lidar_ok: bool | None,
            speed: float | None = None) -> tuple[float | None, bool, float | None]:
        """The throttle to drive with, whether the stop acts, the nearest distance ahead (m)."""
        ahead = None if dist_array is None or not lidar_ok else front_distance(dist_array, self.half_angle_deg)
        if ahead is not None and math.isnan(ahead):  # a bin ahead without a fresh reading: blind there
            ahead = None
        blocked = (ahead is None and self.stop_when_blind) or (ahead is not None and ahead < self.trigger(speed))
        if blocked != self.stopping:
            self.stopping = blocked
            if blocked:
                logger.warning("obstacle stop: %s", "LiDAR blind" if ahead is None else f"{ahead:.2f} m ahead")
            else:
                logger.info("obstacle stop released")
        near = None if ahead is None or math.isinf(ahead) else ahead
        if not blocked or throttle is None or throttle <= 0:
            return throttle, False, near
        rolling = speed is not None and speed > self.rolling
        return (-self.brake if rolling else 0.0), True, near
