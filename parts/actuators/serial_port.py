"""Opening the serial port of a drivetrain (VESC, Robo HAT MM1): pyserial, imported on open."""

from __future__ import annotations

from typing import Any

from parts.actuators.drivetrain import DrivetrainError


def open_serial(port: str, baudrate: int, setting: str) -> Any:
    """Open a serial port for a drivetrain: non-blocking reads, one-line errors naming ``setting``."""
    try:
        import serial  # noqa: PLC0415 - hardware library, imported when the part opens
    except ImportError as exc:
        raise DrivetrainError(f"{setting} = {port!r} needs pyserial: pip install 'vehicle-rc[car]'") from exc
    try:
        return serial.serial_for_url(port, baudrate=baudrate, timeout=0, write_timeout=0.5)
    except serial.SerialException as exc:
        text = str(exc)
        if "Permission denied" in text:
            hint = "add your user to the dialout group (`sudo usermod -aG dialout $USER`) and log in again"
        else:
            hint = "check the cable and set it to the port that appears when you plug the board in (`ls /dev/tty*`)"
        raise DrivetrainError(f"{setting} = {port!r}: cannot open the serial port ({text}); {hint}") from exc
