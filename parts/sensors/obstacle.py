"""Obstacle stop: brake when the LiDAR sees something closer than a set distance ahead, in any mode."""

from __future__ import annotations

import logging
import math
from typing import ClassVar

from parts.sensors.lidar import front_distance

logger = logging.getLogger(__name__)


class ObstacleStop:
    """Part: the final ``throttle`` cut to a brake while an obstacle is near ahead.

    ``run(throttle, dist_array, lidar_ok, speed) -> (throttle, obstacle/stop, obstacle/distance)``.
    Add it after the drive mode and the speed limit, before the drivetrain: it acts on the command
    the car will drive with, whatever mode produced it. A forward throttle is replaced by
    ``-brake`` while the car still rolls forward (``speed`` > ``rolling`` m/s; a hobby ESC brakes
    on a negative command while moving) and by 0 once it stands or its speed is unknown (a negative
    command at rest would reverse). Reverse throttle passes: backing away is allowed.

    Args:
        distance: metres ahead below which the car stops (OBSTACLE_STOP_DISTANCE).
        half_angle_deg: half width of the cone ahead that is watched (OBSTACLE_STOP_ANGLE).
        brake: brake command magnitude in (0, 1] (OBSTACLE_STOP_BRAKE); 0 = coast to neutral.
        stop_when_blind: a stale LiDAR stops the car too (OBSTACLE_STOP_WHEN_BLIND).
        rolling: m/s above which the car counts as rolling forward.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("throttle", "lidar/dist_array", "lidar/ok", "enc/speed")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("enc/speed",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("throttle", "obstacle/stop", "obstacle/distance")

    def __init__(self, distance: float = 0.5, *, half_angle_deg: float = 20.0, brake: float = 0.5,
                 stop_when_blind: bool = True, rolling: float = 0.05) -> None:
        if not distance > 0:
            raise ValueError(f"OBSTACLE_STOP_DISTANCE must be > 0 m, got {distance!r}")
        if not 0 < half_angle_deg <= 180:
            raise ValueError(f"OBSTACLE_STOP_ANGLE must be in (0, 180] degrees, got {half_angle_deg!r}")
        if not 0 <= brake <= 1:
            raise ValueError(f"OBSTACLE_STOP_BRAKE must be in [0, 1], got {brake!r}")
        self.distance, self.half_angle_deg, self.brake = float(distance), float(half_angle_deg), float(brake)
        self.stop_when_blind, self.rolling = bool(stop_when_blind), float(rolling)
        self.stopping = False

    def run(self, throttle: float | None, dist_array: list[float] | None, lidar_ok: bool | None,
            speed: float | None = None) -> tuple[float | None, bool, float | None]:
        """The throttle to drive with, whether the stop acts, the nearest distance ahead (m)."""
        ahead = None if dist_array is None or not lidar_ok else front_distance(dist_array, self.half_angle_deg)
        blocked = (ahead is None and self.stop_when_blind) or (ahead is not None and ahead < self.distance)
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
