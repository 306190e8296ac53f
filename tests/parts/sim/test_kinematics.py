from __future__ import annotations

import math

import pytest

from parts.sim.kinematics import Car, CarParams, CarState


def drive(car: Car, angle: float, throttle: float, seconds: float, dt: float = 0.05) -> CarState:
    for _ in range(round(seconds / dt)):
        car.step(angle, throttle, dt)
    return car.state


def test_throttle_accelerates_to_drag_limited_speed():
    p = CarParams(max_speed=10.0)
    car = Car(p)
    drive(car, 0.0, 0.5, 15.0)
    # terminal speed where throttle * max_accel = drag * v + rolling
    assert car.state.speed == pytest.approx((0.5 * p.max_accel - p.rolling) / p.drag, rel=1e-3)
    assert car.state.y == pytest.approx(0.0, abs=1e-9)  # straight ahead along +x
    assert car.state.x > 20.0


def test_speed_limit_brake_reverse_and_coast():
    car = Car(CarParams(max_speed=3.0, max_reverse_speed=1.0))
    assert drive(car, 0, 1.0, 5.0).speed == pytest.approx(3.0)
    # full brake from 3 m/s stops within about 3 / brake seconds and never rolls backwards
    car.step(0, -1.0, 0.05)
    assert 0 < car.state.speed < 3.0
    speeds = [car.step(0, -1.0, 0.05).speed for _ in range(10)]
    assert speeds[-1] < 0  # then reverses (ESC brake -> reverse)
    assert min(speeds) >= -1.0
    assert drive(car, 0, -1.0, 5.0).speed == pytest.approx(-1.0)
    # coasting stops the car and it stays stopped
    assert drive(car, 0, 0.0, 10.0).speed == 0.0
    assert drive(car, 0, 0.05, 1.0).speed == 0.0  # too weak to overcome rolling resistance


def test_turning_circle_matches_the_bicycle_model():
    p = CarParams()
    car = Car(p)
    drive(car, -1.0, 0.3, 12.0)  # full left, steady speed
    v = car.state.speed
    h0 = car.state.heading
    drive(car, -1.0, 0.3, 1.0)
    yaw_rate = ((car.state.heading - h0 + math.pi) % (2 * math.pi) - math.pi) / 1.0
    assert yaw_rate > 0  # left turn = counter-clockwise
    assert yaw_rate == pytest.approx(v * math.tan(p.max_steer) / p.wheelbase, rel=0.02)


def test_steering_servo_is_rate_limited_and_commands_clipped():
    p = CarParams(steer_rate=math.radians(100))
    car = Car(p)
    car.step(5.0, 0.0, 0.05)  # clipped to full right
    assert car.state.steer == pytest.approx(-math.radians(5.0))  # 100 deg/s * 0.05 s
    drive(car, 5.0, 0.0, 1.0)
    assert car.state.steer == pytest.approx(-p.max_steer)


def test_deterministic_for_a_command_sequence():
    def run() -> tuple:
        car = Car()
        for i in range(300):
            car.step(math.sin(i / 10), 0.6 if i < 200 else -0.4, 0.05)
        s = car.state
        return s.x, s.y, s.heading, s.speed

    assert run() == run()


def test_bad_parameters():
    with pytest.raises(ValueError, match="wheelbase"):
        CarParams(wheelbase=0)
    with pytest.raises(ValueError, match="time step"):
        Car().step(0, 0, 0.0)
