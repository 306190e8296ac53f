"""Drive modes: who steers and who sets the throttle (DonkeyCar's user / local_angle / local)."""

from __future__ import annotations

import logging
import math
from enum import StrEnum

logger = logging.getLogger(__name__)


class Mode(StrEnum):
    """The three drive modes; values are DonkeyCar's strings, as recorded in tubs."""

    USER = "user"  # the human steers and sets the throttle
    LOCAL_ANGLE = "local_angle"  # the pilot steers, the human sets the throttle
    LOCAL = "local"  # the pilot steers and sets the throttle

    def next(self) -> Mode:
        """The mode after this one, cycling user -> local_angle -> local -> user."""
        order = list(Mode)
        return order[(order.index(self) + 1) % len(order)]


def parse_mode(value: object) -> Mode:
    """Mode from a stored string; unknown or missing values mean user mode (the safe choice)."""
    try:
        return Mode(value)
    except ValueError:
        if value is not None:
            logger.warning("unknown drive mode %r: using user mode", value)
        return Mode.USER


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

    def run(self, mode: object) -> bool:
        """Whether the pilot runs this loop."""
        return parse_mode(mode) is not Mode.USER
