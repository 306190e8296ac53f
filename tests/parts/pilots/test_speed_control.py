"""Speed controllers of the seeds: PI to a target speed, and throttle = 1 - speed/limit."""

from __future__ import annotations

import math

import pytest

from parts.drive.speed import PIController, SpeedControl, limit_throttle


def simulate(control: SpeedControl, limit: float, steps: int, dt: float = 0.05) -> list[float]:
    """A first-order car: acceleration = 4 * throttle - 1 * speed (m/s^2); top speed 4 m/s."""
    speed, speeds = 0.0, []
    for _ in range(steps):
        throttle = control.run(0.9, speed, limit)
        speed += (4.0 * throttle - speed) * dt
        speeds.append(speed)
    return speeds


def test_limit_throttle_follows_the_seed_formula():
    assert limit_throttle(0.0, 2.0) == 1.0
    assert limit_throttle(0.5, 2.0) == pytest.approx(0.75)
    assert limit_throttle(2.0, 2.0) == 0.0
    assert limit_throttle(3.0, 2.0) == 0.0  # over the limit: no throttle, never negative
    assert limit_throttle(1.0, 2.0, max_throttle=0.6) == pytest.approx(0.3)
    with pytest.raises(ValueError, match="speed limit must be > 0"):
        limit_throttle(1.0, 0.0)


def test_pi_controller_reaches_the_target_without_steady_error():
    speeds = simulate(SpeedControl("pi", dt=0.05, kp=0.3, ki=0.6), limit=2.0, steps=400)
    assert speeds[-1] == pytest.approx(2.0, abs=0.02)
    assert max(speeds) < 2.5  # modest overshoot


def test_limit_mode_settles_below_the_limit():
    speeds = simulate(SpeedControl("limit"), limit=2.0, steps=400)
    # steady state of v' = 4(1 - v/2) - v: v = 4/3 m/s, under the limit (the seed's known droop)
    assert speeds[-1] == pytest.approx(4 / 3, abs=0.02)


def test_pi_anti_windup_after_a_long_stall():
    pi = PIController(kp=0.3, ki=0.6)
    pi.set_desired(2.0)
    outputs = [pi.update(0.0, 0.05) for _ in range(1000)]  # wheels blocked: speed stays 0
    assert outputs[0] == pytest.approx(0.3 * 2.0 + 0.6 * 2.0 * 0.05)
    assert outputs[-1] == 1.0  # saturated
    # integral stopped growing at saturation, so the output drops as soon as the car is too fast
    assert pi.update(2.5, 0.05) < 1.0
    assert pi.integral * pi.ki <= 1.0 + 1e-9


def test_no_limit_passes_the_pilot_throttle_and_zero_limit_stops():
    control = SpeedControl("pi")
    assert control.run(0.42, 1.0, None) == 0.42
    assert control.run(0.42, 1.0, 0.0) == 0.0
    assert SpeedControl("off").run(0.42, 1.0, 3.0) == 0.42


def test_default_limit_applies_while_the_input_is_none():
    control = SpeedControl("limit", default_limit=4.0)
    assert control.run(0.42, 1.0, None) == pytest.approx(0.75)  # 1 - 1/4
    assert control.run(0.42, 1.0, 2.0) == pytest.approx(0.5)  # the input wins while set


def test_missing_speed_gives_zero_throttle_and_one_warning(caplog):
    control = SpeedControl("pi")
    with caplog.at_level("WARNING"):
        for bad in (None, math.nan, math.inf):
            assert control.run(0.5, bad, 2.0) == 0.0
    assert sum("no valid speed" in r.message for r in caplog.records) == 1  # rate-limited


@pytest.mark.parametrize("kwargs, message", [
    ({"mode": "fast"}, "mode must be one of"),
    ({"dt": 0.0}, "dt must be a positive"),
    ({"max_throttle": 1.5}, "max_throttle must be in"),
    ({"kp": -1.0}, "gains must be >= 0"),
    ({"default_limit": -2.0}, "default_limit must be > 0"),
])
def test_bad_settings_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SpeedControl(**kwargs)
