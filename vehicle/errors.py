"""Errors of the core, each with a message that says how to fix the problem.

:class:`VehicleError` is the base of every error whose message is written for the user: one line
that says what was wrong and how to fix it (file, line, setting, valid range). Each library package
has its own subclasses (``ConfigError``, ``WiringError``, ``TubError``, ``ModelFileError``,
``TrackError`` ...); the command line prints any of them as ``error: <message>`` and exits 2,
never with a traceback.
"""

from __future__ import annotations


def error_text(exc: BaseException) -> str:
    """``exc``'s message on one line, an errno pair as OSError writes it: termios.error(5, 'Input/output
    error') reads ``[Errno 5] Input/output error``, not ``(5, 'Input/output error')``."""
    args = exc.args
    if not isinstance(exc, OSError) and len(args) == 2 and isinstance(args[0], int) and isinstance(args[1], str):
        return f"[Errno {args[0]}] {args[1]}"
    return " ".join(str(exc).split()) or type(exc).__name__


class VehicleError(Exception):
    """Base of the errors whose message is meant for the user (one line, says how to fix it)."""


class UserError(VehicleError):
    """Bad input to the application (command-line options, a car folder); raised by ``vehicle.app`` only.

    Library code (``parts/``) raises its own :class:`VehicleError` subclasses instead.
    """


class WiringError(VehicleError, ValueError):
    """The parts of a vehicle do not fit together (unknown input key, bad arguments to add)."""


class PartError(RuntimeError):
    """A part failed while the vehicle ran; names the part and the method that raised."""

    def __init__(self, part_name: str, method: str, cause: BaseException) -> None:
        super().__init__(f"part {part_name!r} failed in {method}(): {type(cause).__name__}: {cause}")
        self.part_name = part_name
        self.method = method
        self.cause = cause


class VehicleStopped(Exception):
    """The loop was stopped by a signal (SIGTERM, SIGHUP); carries the signal number."""

    def __init__(self, signum: int, name: str) -> None:
        super().__init__(f"stopped by {name}")
        self.signum = signum
        self.signal_name = name
