"""Drive modes: who steers and who sets the throttle (DonkeyCar's user / local_angle / local)."""

from __future__ import annotations

import math
from typing import ClassVar

from vehicle.keys import Mode, parse_mode


def _finite(value: object) -> float:
    """A command as a float in [-1, 1]; None, NaN and inf become 0 (stop, centre)."""
    if value is None:
        return 0.0
    x = float(value)  # type: ignore[arg-type]
    if not math.isfinite(x):
        return 0.0
    return max(-1.0, min(1.0, x))


class DriveMode:
    """Choose the final steering and throttle from the user's and the pilot's commands.

    Inputs: ``user/mode, user/angle, user/throttle, pilot/angle, pilot/throttle[, estop]``.
    Outputs: ``angle, throttle``. An emergency stop (``estop`` truthy) forces throttle 0 in
    every mode. A missing pilot value (pilot not loaded yet) means centre steering and zero
    throttle, never the last human command.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("user/mode", "user/angle", "user/throttle", "pilot/angle",
                                         "pilot/throttle", "estop")
    #: a car may have no pilot (None: centre, no throttle) and no emergency stop button
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("pilot/angle", "pilot/throttle", "estop")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle")

    def __init__(self, ai_throttle_mult: float = 1.0) -> None:
        if not math.isfinite(ai_throttle_mult) or ai_throttle_mult < 0:
            raise ValueError(f"ai_throttle_mult must be a finite number >= 0, got {ai_throttle_mult}")
        self.ai_throttle_mult = ai_throttle_mult

    def run(self, mode: object, user_angle: object, user_throttle: object, pilot_angle: object,
            pilot_throttle: object, estop: object = None) -> tuple[float, float]:
        """Return ``(angle, throttle)`` for this loop."""
        m = parse_mode(mode)
        if m is Mode.USER:
            angle, throttle = _finite(user_angle), _finite(user_throttle)
        elif m is Mode.LOCAL_ANGLE:
            angle, throttle = _finite(pilot_angle), _finite(user_throttle)
        else:
            angle = _finite(pilot_angle)
            throttle = _finite(_finite(pilot_throttle) * self.ai_throttle_mult)
        if estop:
            throttle = 0.0
        return angle, throttle


class PilotCondition:
    """``run_pilot`` is True when the pilot must run: any mode but user."""

    INPUTS: ClassVar[tuple[str, ...]] = ("user/mode",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("run_pilot",)

    def run(self, mode: object) -> bool:
        """Whether the pilot runs this loop."""
        return parse_mode(mode) is not Mode.USER
