"""The drivetrain family's table: DRIVE_TRAIN_TYPE -> drivetrain part (built by its ``from_config``).

A drivetrain part takes ``angle`` and ``throttle`` in [-1, 1], has ``neutral()`` (every stop path
calls it) and is built by ``from_config(cfg, *, clock=None)``: ``clock`` is the vehicle's clock (a
simulated one in tests; None: ``time.monotonic``). Drivetrains on an I2C board also take
``bus_factory`` (tests pass a register-level fake).
A new drivetrain is a module with such a class and one row below (DonkeyCar's type name).
"""

from __future__ import annotations

from vehicle.registry import Registry

DRIVETRAINS = Registry("DRIVE_TRAIN_TYPE", {
    "PWM_STEERING_THROTTLE": "parts.actuators.pwm:PWMSteeringThrottle",
    "MOCK": "parts.actuators.pwm:MockPWMSteeringThrottle",
})
