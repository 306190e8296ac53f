"""Camera watchdog: a pilot never drives blind.

When ``cam/ok`` is False (the camera stopped delivering frames, see parts.cameras.base) while a
pilot mode is asked for, the watchdog forces ``user/mode`` to ``user`` and the user throttle to 0,
and it stays tripped until the driver selects user mode (so the pilot never re-engages by itself
when frames come back).
"""

from __future__ import annotations

import logging
from typing import ClassVar

logger = logging.getLogger(__name__)


class CameraWatchdog:
    """Inputs: ``cam/ok, user/mode, user/throttle``; outputs: ``user/mode, user/throttle``."""

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/ok", "user/mode", "user/throttle")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/mode", "user/throttle")

    def __init__(self) -> None:
        self.tripped = False

    def run(self, cam_ok: bool | None, mode: str | None,
            throttle: float | None) -> tuple[str | None, float | None]:
        """The mode and user throttle to use this loop."""
        autopilot = mode not in (None, "user")
        if not autopilot:
            if self.tripped:
                logger.warning("camera watchdog reset: user mode selected")
            self.tripped = False
            return mode, throttle
        if not cam_ok and not self.tripped:
            logger.error("camera not delivering frames in %s mode: pilot disengaged, throttle 0. "
                         "Select user mode to reset.", mode)
            self.tripped = True
        if self.tripped:
            return "user", 0.0
        return mode, throttle
