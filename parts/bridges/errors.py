"""The bridges' own error type: a one-line message for the user that says what to fix."""

from __future__ import annotations

from vehicle.errors import VehicleError


class BridgeError(VehicleError):
    """A simulator bridge cannot work as configured (port taken, unsupported library, bad scene)."""
