"""Recording rules: when the tub writer records (DonkeyCar's ToggleRecording semantics).

- With ``auto_record_on_throttle`` the car records while the throttle is off zero (beyond the
  dead zone) and stops when it is released: no standing-still records.
- Outside user mode nothing is recorded unless ``record_during_ai`` (RECORD_DURING_AI): records
  of a pilot driving would teach the next pilot its own mistakes.
- A correction (``user/correction``, correction mode) is recorded whatever the mode.
- An emergency stop stops recording.
"""

from __future__ import annotations

import logging
from typing import ClassVar

logger = logging.getLogger(__name__)


class RecordingRules:
    """Inputs: ``user/mode, recording, throttle[, estop, user/correction]``; output: ``recording``."""

    INPUTS: ClassVar[tuple[str, ...]] = ("user/mode", "recording", "throttle", "estop", "user/correction")
    #: a car may have no e-stop button, and only correction mode writes user/correction
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("estop", "user/correction")
    #: without a record button (no controller writes ``recording``) it reads its own last decision
    FEEDBACK: ClassVar[tuple[str, ...]] = ("recording",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("recording",)

    def __init__(self, auto_record_on_throttle: bool = True, record_during_ai: bool = False,
                 deadzone: float = 0.01) -> None:
        if not 0.0 <= deadzone < 1.0:
            raise ValueError(f"deadzone {deadzone} must be in [0, 1)")
        self.auto_record_on_throttle = auto_record_on_throttle
        self.record_during_ai = record_during_ai
        self.deadzone = deadzone
        self.last: bool | None = None

    def run(self, mode: str | None, recording: bool | None, throttle: float | None,
            estop: bool | None = None, correction: bool | None = None) -> bool:
        """Whether to record this loop."""
        wanted = bool(recording)
        if self.auto_record_on_throttle:
            wanted = throttle is not None and abs(throttle) > self.deadzone
        in_user_mode = mode in (None, "user")
        if not in_user_mode and not self.record_during_ai:
            wanted = False
        if correction:  # the person overrode the pilot: the frame is what correction mode records
            wanted = True
        if estop:
            wanted = False
        if wanted != self.last:
            logger.info("recording %s", "on" if wanted else "off")
            self.last = wanted
        return wanted
