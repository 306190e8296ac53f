"""Fixtures for the drivetrain tests: a simulated PCA9685 board and drivers on it."""

from __future__ import annotations

import pytest

from parts.actuators.fake_pca9685 import FakeI2C, PCA9685Model
from parts.actuators.pca9685 import PCA9685
from parts.actuators.pins import PinSet
from parts.actuators.pwm import PWMSteeringThrottle, SteeringCalibration, ThrottleCalibration

STEERING_CH, THROTTLE_CH = 1, 0


class FakeClock:
    """A clock the test moves by hand."""

    def __init__(self, t: float = 100.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t

    def advance(self, dt: float) -> None:
        self.t += dt


@pytest.fixture
def i2c() -> FakeI2C:
    return FakeI2C()


@pytest.fixture
def board(i2c: FakeI2C) -> PCA9685Model:
    return i2c.add_board(bus=1, address=0x40)


@pytest.fixture
def driver(i2c: FakeI2C, board: PCA9685Model) -> PCA9685:
    pca = PCA9685(1, 0x40, 60, bus_factory=i2c.smbus)
    yield pca.open()
    pca.close()


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()


@pytest.fixture
def make_drivetrain(i2c, board, clock):
    """Build a drivetrain on the board; keyword arguments go to PWMSteeringThrottle."""
    made = []

    def make(**kwargs) -> PWMSteeringThrottle:
        kwargs.setdefault("arm_s", 0.0)
        kwargs.setdefault("watchdog_s", None)
        kwargs.setdefault("clock", clock)
        kwargs.setdefault("sleep", lambda s: None)
        part = PWMSteeringThrottle(PinSet(60, bus_factory=i2c.smbus), f"PCA9685.1:40.{STEERING_CH}",
                                   f"PCA9685.1:40.{THROTTLE_CH}", kwargs.pop("steering", SteeringCalibration()),
                                   kwargs.pop("throttle", ThrottleCalibration()), **kwargs)
        made.append(part)
        return part

    yield make
    for part in made:
        part.shutdown()
