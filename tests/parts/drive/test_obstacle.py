"""The obstacle stop: a drive decision on the LiDAR's distances (its LiDAR side is in
tests/parts/sensors/test_lidar.py)."""

from __future__ import annotations

import pytest

from parts.drive.obstacle import ObstacleStop


def test_obstacle_stop_brakes_then_holds_neutral() -> None:
    stop = ObstacleStop(0.5, half_angle_deg=20, brake=0.6, decel=2.0, latency=0.1, rolling=0.05)
    assert stop.trigger(None) == 0.5 and stop.trigger(2.0) == pytest.approx(0.5 + 0.2 + 1.0)
    clear = [0.0] * 36
    near = [0.0] * 36
    near[35] = 0.4  # 350-360 degrees: just right of straight ahead
    assert stop.run(0.7, clear, True, 1.0) == (0.7, False, None)
    assert stop.run(0.7, near, True, 1.0) == (-0.6, True, 0.4)  # rolling: brake
    far = [0.0] * 36
    far[0] = 1.5
    assert stop.run(0.7, far, True, 0.5)[:2] == (0.7, False)  # 1.5 m is room enough at 0.5 m/s
    assert stop.run(0.7, far, True, 2.0)[:2] == (-0.6, True)  # ... not at 2 m/s
    assert stop.run(0.7, near, True, 0.0) == (0.0, True, 0.4)  # standing: neutral, never reverse
    assert stop.run(0.7, near, True, None) == (0.0, True, 0.4)  # speed unknown: neutral
    assert stop.run(-0.5, near, True, 0.0) == (-0.5, False, 0.4)  # backing away is allowed
    side = [0.0] * 36
    side[9] = 0.2  # at the left: not in the way
    assert stop.run(0.7, side, True, 1.0) == (0.7, False, None)
    assert stop.run(0.7, None, False, 1.0) == (-0.6, True, None)  # blind: stop
    assert ObstacleStop(0.5, stop_when_blind=False).run(0.7, None, False, 1.0)[0] == 0.7
