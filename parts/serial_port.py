"""The serial ports of parts (VESC, Robo HAT MM1, encoder counter, GPS, LiDAR): pyserial, imported
only when a part opens its port; opening, a failing link and closing as one-line errors naming
the setting."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from vehicle.errors import VehicleError, error_text


def pyserial_port(port: str, baudrate: int, timeout: float) -> Any:
    """``serial.serial_for_url(port, baudrate, timeout)``: a device path, or a pyserial URL such as
    ``loop://`` or ``socket://host:port``. The parts take another factory of this signature in tests."""
    import serial  # noqa: PLC0415 - hardware library, imported only when a part starts

    return serial.serial_for_url(port, baudrate=baudrate, timeout=timeout)


def open_serial(port: str, baudrate: int, setting: str, error: type[VehicleError] = VehicleError) -> Any:
    """Open a serial port for a part that writes commands (a drivetrain): non-blocking reads, a
    0.5 s write timeout, one-line ``error`` naming ``setting``."""
    try:
        import serial  # noqa: PLC0415 - hardware library, imported when the part opens
    except ImportError as exc:
        raise error(f"{setting} = {port!r} needs pyserial: pip install 'vehicle-rc[car]'") from exc
    try:
        port_ = pyserial_port(port, baudrate, 0)
        port_.write_timeout = 0.5
        return port_
    except serial.SerialException as exc:
        text = str(exc)
        if "Permission denied" in text:
            hint = "add your user to the dialout group (`sudo usermod -aG dialout $USER`) and log in again"
        else:
            hint = "check the cable and set it to the port that appears when you plug the board in (`ls /dev/tty*`)"
        raise error(f"{setting} = {port!r}: cannot open the serial port ({text}); {hint}") from exc


def _link_errors() -> tuple[type[BaseException], ...]:
    """What a serial port raises when its device is gone: pyserial's SerialException (an OSError)
    from read/write, termios.error from flush (tcdrain) on POSIX."""
    try:
        import termios  # noqa: PLC0415 - POSIX only
    except ImportError:
        return (OSError,)
    return (OSError, termios.error)


@contextmanager
def serial_link(setting: str, port: str, fallback: str, error: type[VehicleError] = VehicleError) -> Iterator[None]:
    """Turn a failed read, write or flush of an open port (cable pulled, board reset) into one
    ``error`` naming ``setting``; ``fallback`` says what happens now (what stops the motor)."""
    try:
        yield
    except _link_errors() as exc:
        reason = error_text(exc)  # termios.error's tuple would read ((5, 'Input/output error'))
        raise error(f"{setting} = {port!r}: the serial link failed ({reason}); check the cable and "
                              f"the board's power; {fallback}") from exc


def close_serial(port: Any, setting: str, name: str, fallback: str, error: type[VehicleError] = VehicleError) -> None:
    """Send what is still buffered (the last neutral command), then close ``port`` even when that
    fails (one ``error``, see :func:`serial_link`); None does nothing."""
    if port is None:
        return
    try:
        with serial_link(setting, name, fallback, error):
            port.flush()
    finally:
        port.close()
