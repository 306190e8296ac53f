"""Assembly helper for the drivetrain: the part DRIVE_TRAIN_TYPE picks in the drivetrain table
(:data:`parts.actuators.registry.DRIVETRAINS`).

The hardware (PCA9685 board, GPIO pins, serial port) is opened here, when the car is assembled,
so a wiring problem stops ``manage.py drive`` with a message naming the setting before the loop
starts, not at the first drive command.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from vehicle.config import Config

logger = logging.getLogger(__name__)


def build_drivetrain(cfg: Config, *, clock: Callable[[], float] | None = None, **wiring: Any) -> Any:
    """The drivetrain part DRIVE_TRAIN_TYPE picks in the drivetrain table, not opened yet (no
    hardware touched); ``clock`` is the vehicle's clock. ``wiring``, for tests and bench tools,
    replaces what the type would open: ``bus_factory`` (I2C: smbus2, or the simulated board for
    "MOCK"), ``gpio_factory`` (a gpiozero pin factory), ``serial_factory``."""
    from parts.actuators.registry import DRIVETRAINS

    given = {name: value for name, value in wiring.items() if value is not None}
    return DRIVETRAINS.from_config(cfg, clock=clock, **given)


def add_drivetrain(V: Any, cfg: Config, **wiring: Any) -> Any:
    """Add the drivetrain (inputs ``angle``, ``throttle``; a VESC with VESC_GEAR_RATIO also outputs
    ``enc/speed``) and open it: the board, pins or serial port are opened now, before the loop.

    Raises:
        PCA9685Error: the board is missing or does not answer (the message names bus and address
            and how to check the wiring).
        DrivetrainError: GPIO pins or a serial port cannot be opened (names the setting).
    """
    clock = getattr(getattr(V, "clock", None), "now", None)
    part = build_drivetrain(cfg, clock=clock, **wiring)
    part.open()
    V.add(part)
    return part
