"""DonkeyCar's ThrottleFilter: the reverse "double tap" done on the command stream.

Car ESCs (forward/brake/reverse) brake on the first reverse pulse and only back up after a return
to neutral. This filter turns a run of negative commands ``neg, neg, neg, ...`` into
``neg, 0, neg, ...``: the second negative command becomes 0 once, so holding the stick back
brakes, then reverses. Any command >= 0 re-arms it. Use it, or the drivetrain's
``ESC_REVERSE_MODE = "double_tap"`` (time based), not both.
"""

from __future__ import annotations

from typing import ClassVar


class ThrottleFilter:
    """Input: ``throttle``; output: ``throttle``."""

    INPUTS: ClassVar[tuple[str, ...]] = ("throttle",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("throttle",)

    def __init__(self) -> None:
        self.reverse_triggered = False
        self.last_throttle = 0.0

    def run(self, throttle: float | None) -> float | None:
        """The filtered throttle (None passes through)."""
        if throttle is None:
            return None
        out = float(throttle)
        if out < 0.0:
            if not self.reverse_triggered and self.last_throttle < 0.0:
                out = 0.0
                self.reverse_triggered = True
        else:
            self.reverse_triggered = False
        self.last_throttle = out
        return out
