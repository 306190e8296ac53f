"""Assembly helper for the drivetrain: the part DRIVE_TRAIN_TYPE picks in the drivetrain table
(:data:`parts.actuators.registry.DRIVETRAINS`).

The board is probed and initialised here, when the car is assembled, so a wiring problem stops
``manage.py drive`` with a message naming bus and address before the loop starts, not at the
first drive command.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from parts.actuators.pca9685 import BusFactory
    from vehicle.config import Config

logger = logging.getLogger(__name__)


def build_drivetrain(cfg: Config, *, bus_factory: BusFactory | None = None,
                     clock: Callable[[], float] | None = None) -> Any:
    """The drivetrain part DRIVE_TRAIN_TYPE picks in the drivetrain table, not opened yet (no
    hardware touched). ``bus_factory``, when given, replaces the bus its type selects (smbus2, or
    the simulated board for "MOCK"); ``clock`` is the vehicle's clock."""
    from parts.actuators.registry import DRIVETRAINS

    wiring: dict[str, Any] = {"clock": clock}
    if bus_factory is not None:
        wiring["bus_factory"] = bus_factory
    return DRIVETRAINS.from_config(cfg, **wiring)


def add_drivetrain(V: Any, cfg: Config, *, bus_factory: BusFactory | None = None) -> Any:
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
