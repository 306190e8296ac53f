"""Errors of the core, each with a message that says how to fix the problem."""

from __future__ import annotations


class UserError(Exception):
    """Bad input from the user (command line, config, files): the CLI prints it and exits 2."""


class WiringError(ValueError):
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
