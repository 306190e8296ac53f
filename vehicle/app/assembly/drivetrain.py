"""Assembly helper for the drivetrain: the part DRIVE_TRAIN_TYPE picks in :data:`DRIVETRAINS`.

The hardware (PCA9685 board, GPIO pins, serial port) is opened here, when the car is assembled, so
a wiring problem stops ``manage.py drive`` with a message naming the setting before the loop
starts, not at the first drive command.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from parts.actuators.fake_pca9685 import PCA9685Model
    from parts.actuators.pca9685 import PCA9685, BusFactory
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


#: DRIVE_TRAIN_TYPE -> the drivetrain part, built by its ``from_config`` (DonkeyCar's type names)
DRIVETRAINS: dict[str, str] = {
    "PWM_STEERING_THROTTLE": "parts.actuators.pwm:PWMSteeringThrottle",
    "MOCK": "parts.actuators.pwm:PWMSteeringThrottle",
    "SERVO_HBRIDGE_2PIN": "parts.actuators.motors:ServoHBridge",
    "SERVO_HBRIDGE_3PIN": "parts.actuators.motors:ServoHBridge",
    "DC_STEER_THROTTLE": "parts.actuators.motors:DCSteerThrottle",
    "DC_TWO_WHEEL": "parts.actuators.motors:DifferentialDrive",
    "DC_TWO_WHEEL_L298N": "parts.actuators.motors:DifferentialDrive",
    "VESC": "parts.actuators.vesc:VESC",
    "MM1": "parts.actuators.mm1:RoboHatMM1",
}


def build_drivetrain(cfg: Config, *, clock: Callable[[], float] | None = None, **wiring: Any) -> Any:
    """The drivetrain part DRIVE_TRAIN_TYPE picks, not opened yet (no hardware touched).

    ``wiring`` replaces what the type would open (tests and bench tools): ``bus_factory`` (I2C,
    default smbus2, or the simulated board for "MOCK"), ``gpio_factory`` (a gpiozero pin factory),
    ``serial_factory`` (``factory(port, baudrate)``).

    Raises:
        UserError: a drivetrain setting is invalid (one line naming it).
    """
    import importlib

    from parts.actuators.drivetrain_config import drivetrain_problems
    from vehicle.errors import UserError

    kind = cfg.DRIVE_TRAIN_TYPE
    for problem in drivetrain_problems(cfg):
        raise UserError(f"{_where(cfg, problem.setting)}{problem.message}")
    if kind == "MOCK" and wiring.get("bus_factory") is None:
        wiring["bus_factory"] = mock_board(cfg)[0]
    module, _, name = DRIVETRAINS[kind].partition(":")
    cls = getattr(importlib.import_module(module), name)
    wanted = {k: v for k, v in wiring.items() if v is not None}
    try:
        return cls.from_config(cfg, clock=clock, **wanted)
    except (ValueError, TypeError) as exc:
        raise UserError(f"{_where(cfg, 'DRIVE_TRAIN_TYPE')}{exc}") from exc


def _where(cfg: Config, setting: str) -> str:
    """``"<file>, line <n>: "`` where the car's config sets ``setting``, else ``""``."""
    line = getattr(cfg, "lines", {}).get(setting)
    source = getattr(cfg, "source", None)
    return f"{source}, line {line}: " if source and line else ""


def add_drivetrain(V: Any, cfg: Config, **wiring: Any) -> Any:
    """Add the drivetrain (inputs ``angle``, ``throttle``; a VESC with a gear ratio also outputs
    ``enc/speed``) and open it: the hardware is probed now, before the loop starts.

    Raises:
        UserError: an invalid drivetrain setting.
        VehicleError: the board, pins or serial port cannot be opened (the message names the
            setting and how to check the wiring).
    """
    clock = getattr(getattr(V, "clock", None), "now", None)
    part = build_drivetrain(cfg, clock=clock, **wiring)
    part.open()
    V.add(part)
    return part
