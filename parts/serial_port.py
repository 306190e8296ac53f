"""The serial ports of parts (VESC, Robo HAT MM1, encoder counter, GPS, LiDAR): pyserial, imported
only when a part opens its port."""

from __future__ import annotations

from typing import Any


def pyserial_port(port: str, baudrate: int, timeout: float) -> Any:
    """``serial.serial_for_url(port, baudrate, timeout)``: a device path, or a pyserial URL such as
    ``loop://`` or ``socket://host:port``. The parts take another factory of this signature in tests."""
    import serial  # noqa: PLC0415 - hardware library, imported only when a part starts

    return serial.serial_for_url(port, baudrate=baudrate, timeout=timeout)
