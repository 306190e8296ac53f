"""Assembly helper for the drivetrain: steering servo + ESC on a PCA9685 (real or simulated).

The board is probed and initialised here, when the car is assembled, so a wiring problem stops
``manage.py drive`` with a message naming bus and address before the loop starts, not at the
first drive command.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from parts.actuators.fake_pca9685 import PCA9685Model
    from parts.actuators.pca9685 import PCA9685, BusFactory
    from parts.actuators.pwm import PWMSteeringThrottle
    from vehicle.config import Config

logger = logging.getLogger(__name__)

#: default bus when PCA9685_I2C_BUSNUM is None: header pins 3/5 on a Raspberry Pi and a Jetson Nano
DEFAULT_BUS = 1


def busnum(cfg: Config) -> int:
    """PCA9685_I2C_BUSNUM, with None meaning bus 1."""
    return DEFAULT_BUS if cfg.PCA9685_I2C_BUSNUM is None else cfg.PCA9685_I2C_BUSNUM


def mock_board(cfg: Config) -> tuple[BusFactory, PCA9685Model]:
    """A simulated PCA9685 at the configured bus and address: (bus factory, register model).

    The model keeps real (monotonic) time, also under a simulated vehicle clock: it checks the
    driver's real delays (oscillator start-up) against the datasheet.
    """
    from parts.actuators.fake_pca9685 import FakeI2C

    trace = str(cfg.path("PCA9685_MOCK_TRACE")) if cfg.PCA9685_MOCK_TRACE else None
    i2c = FakeI2C()
    model = i2c.add_board(busnum(cfg), cfg.PCA9685_I2C_ADDR, trace_path=trace)
    return i2c.smbus, model


def make_driver(cfg: Config, bus_factory: BusFactory | None = None) -> PCA9685:
    """The PCA9685 driver for the car's settings (not opened yet)."""
    from parts.actuators.pca9685 import PCA9685

    return PCA9685(busnum(cfg), cfg.PCA9685_I2C_ADDR, cfg.PWM_FREQ, osc_hz=cfg.PCA9685_OSC_HZ,
                   bus_factory=bus_factory)


def build_drivetrain(cfg: Config, *, bus_factory: BusFactory | None = None,
                     clock: Callable[[], float] | None = None) -> PWMSteeringThrottle:
    """The drivetrain part for the car's settings, not opened yet (no hardware touched).

    ``bus_factory`` replaces the one DRIVE_TRAIN_TYPE selects (smbus2, or the simulated board for
    "MOCK").
    """
    import time

    from parts.actuators.esc import ReverseStateMachine
    from parts.actuators.pins import PinSet
    from parts.actuators.pwm import PWMSteeringThrottle, SteeringCalibration, ThrottleCalibration
    from vehicle.errors import UserError

    kind = cfg.DRIVE_TRAIN_TYPE
    if kind not in ("PWM_STEERING_THROTTLE", "MOCK"):
        raise UserError(f"DRIVE_TRAIN_TYPE = {kind!r} is not supported: set it to 'PWM_STEERING_THROTTLE' "
                        "or 'MOCK' in myconfig.py")
    clock = clock or time.monotonic
    if bus_factory is None and kind == "MOCK":
        bus_factory, _ = mock_board(cfg)
    steering = SteeringCalibration(cfg.STEERING_LEFT_PWM, cfg.STEERING_RIGHT_PWM, cfg.STEERING_TRIM,
                                   cfg.STEERING_INVERT)
    throttle = ThrottleCalibration(cfg.THROTTLE_FORWARD_PWM, cfg.THROTTLE_STOPPED_PWM,
                                   cfg.THROTTLE_REVERSE_PWM, cfg.THROTTLE_FORWARD_LIMIT,
                                   cfg.THROTTLE_REVERSE_LIMIT, cfg.THROTTLE_INVERT)
    reverse = ReverseStateMachine(cfg.ESC_REVERSE_MODE, cfg.ESC_REVERSE_BRAKE_S, cfg.ESC_REVERSE_NEUTRAL_S)
    board = f"PCA9685.{busnum(cfg)}:{cfg.PCA9685_I2C_ADDR:02X}"
    pins = PinSet(cfg.PWM_FREQ, osc_hz=cfg.PCA9685_OSC_HZ, bus_factory=bus_factory)
    return PWMSteeringThrottle(
        pins, f"{board}.{cfg.STEERING_CHANNEL}", f"{board}.{cfg.THROTTLE_CHANNEL}", steering, throttle,
        slew_rate=cfg.THROTTLE_SLEW_RATE, reverse=reverse, arm_s=cfg.ESC_ARM_TIME_S,
        watchdog_s=cfg.ACTUATOR_WATCHDOG_S, hold_s=cfg.PWM_SHUTDOWN_HOLD_S,
        full_off_on_shutdown=cfg.PWM_FULL_OFF_ON_SHUTDOWN, clock=clock)


def add_drivetrain(V: Any, cfg: Config, *, bus_factory: BusFactory | None = None) -> PWMSteeringThrottle:
    """Add the drivetrain (inputs ``angle``, ``throttle``) and open it: the board is probed now.

    Raises:
        PCA9685Error: the board is missing or does not answer (the message names bus and address
            and how to check the wiring).
        ValueError: inconsistent calibration settings.
    """
    clock = getattr(getattr(V, "clock", None), "now", None)
    part = build_drivetrain(cfg, bus_factory=bus_factory, clock=clock)
    part.open()
    V.add(part)
    return part
