"""Opening the serial port of a drivetrain (VESC, Robo HAT MM1): pyserial, imported on open."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from parts.actuators.drivetrain import DrivetrainError
from parts.serial_port import pyserial_port


def open_serial(port: str, baudrate: int, setting: str) -> Any:
    """Open a serial port for a drivetrain: non-blocking reads, one-line errors naming ``setting``."""
    try:
        import serial  # noqa: PLC0415 - hardware library, imported when the part opens
    except ImportError as exc:
        raise DrivetrainError(f"{setting} = {port!r} needs pyserial: pip install 'vehicle-rc[car]'") from exc
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
        raise DrivetrainError(f"{setting} = {port!r}: cannot open the serial port ({text}); {hint}") from exc


def _link_errors() -> tuple[type[BaseException], ...]:
    """What a serial port raises when its device is gone: pyserial's SerialException (an OSError)
    from read/write, termios.error from flush (tcdrain) on POSIX."""
    try:
        import termios  # noqa: PLC0415 - POSIX only
    except ImportError:
        return (OSError,)
    return (OSError, termios.error)


@contextmanager
def serial_link(setting: str, port: str, fallback: str) -> Iterator[None]:
    """Turn a failed read, write or flush of an open port (cable pulled, board reset) into one
    DrivetrainError naming ``setting``; ``fallback`` says what stops the motor now."""
    try:
        yield
    except _link_errors() as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise DrivetrainError(f"{setting} = {port!r}: the serial link failed ({reason}); check the cable and "
                              f"the board's power; {fallback}") from exc


def close_serial(port: Any, setting: str, name: str, fallback: str) -> None:
    """Send what is still buffered (the last neutral command), then close ``port`` even when that
    fails (one DrivetrainError, see :func:`serial_link`); None does nothing."""
    if port is None:
        return
    try:
        with serial_link(setting, name, fallback):
            port.flush()
    finally:
        port.close()
