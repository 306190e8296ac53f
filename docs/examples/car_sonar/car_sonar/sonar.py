"""MaxBotix HRLV-MaxSonar over serial: each reading is "R", four ASCII digits (millimetres,
300 = nearer than 30 cm, 5000 = nothing within 5 m) and a carriage return, about 10 per second."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

from parts.sensors.freshness import SensorPart
from parts.serial_port import pyserial_port
from vehicle.config import check_value
from vehicle.errors import VehicleError

MAX_RANGE_MM = 5000  # the sensor's "no target" reading


class SonarError(VehicleError):
    """The sonar's port cannot be opened."""


class MaxSonar(SensorPart):
    """Part: ``sonar/distance`` (metres; inf: nothing within range) and ``sonar/ok``.
    Add it threaded: it blocks on the serial line."""

    OUTPUTS: ClassVar[tuple[str, ...]] = ("sonar/distance", "sonar/ok")
    RECORDED: ClassVar[Mapping[str, str]] = {"sonar/distance": "float"}

    def __init__(self, port: str, *, max_age: float = 0.5, clock: Callable[[], float] = time.monotonic,
                 serial_factory: Callable[..., Any] | None = None) -> None:
        check_value("SONAR_MAX_AGE_S", max_age)  # the settings' own range: one source for the bound
        super().__init__(max_age, clock)
        self.port = port
        self._factory = serial_factory or pyserial_port
        self._serial: Any = None

    @classmethod
    def from_config(cls, cfg: Any, clock: Callable[[], float] | None = None) -> MaxSonar:
        """SONAR_SERIAL, SONAR_MAX_AGE_S."""
        return cls(cfg.SONAR_SERIAL, max_age=cfg.SONAR_MAX_AGE_S, clock=clock or time.monotonic)

    def open(self) -> None:
        try:
            self._serial = self._factory(self.port, 9600, 0.2)
        except (OSError, ValueError) as exc:
            raise SonarError(f"sonar serial port {self.port}: {exc} (check SONAR_SERIAL)") from exc

    def read(self) -> tuple[object, ...] | None:
        """One reading, or None for a partial or garbled line."""
        line = self._serial.read_until(b"\r").strip()
        if len(line) != 5 or line[:1] != b"R" or not line[1:].isdigit():
            return None
        mm = int(line[1:])
        return (float("inf") if mm >= MAX_RANGE_MM else mm / 1000.0,)

    def close(self) -> None:
        if self._serial is not None:
            self._serial.close()
            self._serial = None

    def describe(self, values: tuple[object, ...]) -> tuple[bool, str]:
        """The distance ahead, for `vehicle hw check`."""
        ok, text = super().describe(values)
        if ok:
            text = f"{self.where()}: nearest object {values[0]:.2f} m ahead"
        return ok, text
