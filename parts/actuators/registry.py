"""The drivetrain family's table: DRIVE_TRAIN_TYPE -> drivetrain part (built by its ``from_config``).

A drivetrain part takes ``angle`` and ``throttle`` in [-1, 1], has ``neutral()`` (every stop path
calls it) and is built by ``from_config(cfg, *, clock=None)``: ``clock`` is the vehicle's clock (a
simulated one in tests; None: ``time.monotonic``). Tests and bench tools may also pass
``bus_factory`` (I2C, a register-level fake), ``gpio_factory`` (a gpiozero pin factory) or
``serial_factory`` (``factory(port, baudrate)``); each drivetrain takes those it uses.
A new drivetrain is a module with such a class and one row below (DonkeyCar's type name).
"""

from __future__ import annotations

from vehicle.registry import Registry

DRIVETRAINS = Registry("DRIVE_TRAIN_TYPE", {
    "PWM_STEERING_THROTTLE": "parts.actuators.pwm:PWMSteeringThrottle",
    "MOCK": "parts.actuators.pwm:MockPWMSteeringThrottle",
    "SERVO_HBRIDGE_2PIN": "parts.actuators.motors:ServoHBridge",
    "SERVO_HBRIDGE_3PIN": "parts.actuators.motors:ServoHBridge",
    "DC_STEER_THROTTLE": "parts.actuators.motors:DCSteerThrottle",
    "DC_TWO_WHEEL": "parts.actuators.motors:DifferentialDrive",
    "DC_TWO_WHEEL_L298N": "parts.actuators.motors:DifferentialDrive",
    "VESC": "parts.actuators.vesc:VESC",
    "MM1": "parts.actuators.mm1:RoboHatMM1",
})
