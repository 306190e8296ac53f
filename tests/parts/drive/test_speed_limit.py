"""The page's speed limit: a cap on the car's speed in every drive mode, never a target."""

from __future__ import annotations

import logging

import pytest

from parts.drive.speed import SpeedLimit


def drive(limiter: SpeedLimit, request, limit, steps: int, dt: float = 0.05, speed: float = 0.0):
    """A first-order car (acceleration = 4 * throttle - speed, m/s^2) driven through the limiter;
    ``request`` and ``limit`` may be functions of the step. Returns speeds and throttles."""
    speeds, throttles = [], []
    for i in range(steps):
        r = request(i) if callable(request) else request
        lim = limit(i) if callable(limit) else limit
        throttle = limiter.run(r, speed, lim)
        speed += (4.0 * throttle - speed) * dt
        speeds.append(speed)
        throttles.append(throttle)
    return speeds, throttles


def test_full_throttle_is_held_at_the_limit():
    speeds, _ = drive(SpeedLimit(dt=0.05), 1.0, 1.5, 400)
    assert speeds[-1] == pytest.approx(1.5, abs=0.03)
    assert max(speeds) < 1.5 * 1.1


def test_a_limit_above_the_cars_own_speed_never_makes_it_faster():
    # issue 21: with PI speed control, a "limit" above the pilot's own speed was a target
    _, throttles = drive(SpeedLimit(dt=0.05), 0.3, 3.5, 400)  # 0.3 settles at 1.2 m/s
    assert throttles == [0.3] * 400


def test_lowering_the_limit_slows_the_car_and_raising_it_gives_the_request_back():
    speeds, throttles = drive(SpeedLimit(dt=0.05), 0.8, lambda i: 2.5 if i < 200 else 1.0, 600)
    assert speeds[199] == pytest.approx(2.5, abs=0.05)  # 0.8 alone would reach 3.2 m/s
    assert speeds[-1] == pytest.approx(1.0, abs=0.03)
    speeds, throttles = drive(SpeedLimit(dt=0.05), 0.5, lambda i: 1.0 if i < 200 else None, 400)
    assert throttles[-1] == 0.5 and speeds[-1] == pytest.approx(2.0, abs=0.05)


def test_braking_and_reverse_are_limited_the_same_way_and_none_passes():
    limiter = SpeedLimit(dt=0.05)
    assert limiter.run(-1.0, 2.0, 1.0) == -1.0  # braking while too fast: never cut
    speeds, _ = drive(SpeedLimit(dt=0.05), -1.0, 1.0, 400)
    assert speeds[-1] == pytest.approx(-1.0, abs=0.03)
    assert limiter.run(None, 0.0, 1.0) is None


def test_no_speed_measurement_means_no_forward_throttle(caplog):
    limiter = SpeedLimit(dt=0.05)
    with caplog.at_level(logging.WARNING):
        assert limiter.run(0.7, None, 1.0) == 0.0
        assert limiter.run(0.7, float("nan"), 1.0) == 0.0
    assert caplog.text.count("no valid speed measurement") == 1
    assert limiter.run(0.7, None, None) == 0.7  # no limit: nothing to hold
