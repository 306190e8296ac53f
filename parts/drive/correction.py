"""Correction mode: the pilot drives, the person's stick overrides while moved, and those frames
are recorded as corrections (DAgger with a human expert on the real car).

Where it sits: right after the drive mode (:func:`vehicle.app.assembly.drive.add_drive_mode`
adds it with CORRECTION_MODE), before the speed limit and the obstacle stop, so those still act
on whatever it decides. In "user" mode it changes nothing. In "local" (the pilot drives) and
"local_angle" (the pilot steers) mode:

- steering: the person's ``user/angle`` replaces the pilot's while the stick is off centre by more
  than ``deadzone``;
- throttle ("local" only): the person's ``user/throttle`` replaces the pilot's while off zero by
  more than ``deadzone`` (in "local_angle" the person sets the throttle anyway);
- a frame where either was overridden is a correction: ``user/correction`` True, ``recording``
  True, and the labels ``user/angle`` / ``user/throttle`` are what the car executed (the person's
  value where they overrode, the pilot's where they let it be); every other frame is not recorded.

So a person watches the pilot, steers only where it goes wrong, and the tub holds exactly those
frames, labelled with what the person did. Training keeps correction records whatever TRAIN_MODES
says (docs/dagger.md).
"""

from __future__ import annotations

from typing import Any, ClassVar

from vehicle.config import check_settings
from vehicle.keys import Mode, parse_mode


def _moved(value: Any, deadzone: float) -> bool:
    try:
        return value is not None and abs(float(value)) > deadzone
    except (TypeError, ValueError):
        return False


class Correction:
    """Part: in: ``user/mode, user/angle, user/throttle, angle, throttle, recording[, estop]``; out:
    ``angle, throttle`` (executed), ``user/angle, user/throttle`` (labels), ``user/correction,
    recording``. An emergency stop keeps the throttle at 0 whoever overrides."""

    INPUTS: ClassVar[tuple[str, ...]] = ("user/mode", "user/angle", "user/throttle", "angle", "throttle",
                                         "recording", "estop")
    #: a car without a record button (no controller writes ``recording``) or an e-stop button
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("recording", "estop")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle", "user/angle", "user/throttle", "user/correction",
                                          "recording")

    def __init__(self, deadzone: float = 0.05) -> None:
        check_settings(CORRECTION_DEADZONE=deadzone)
        self.deadzone = float(deadzone)
        self.corrections = 0  # frames overridden so far

    def run(self, mode: Any, user_angle: Any, user_throttle: Any, angle: float, throttle: float,
            recording: Any = None, estop: Any = None) -> tuple[float, float, Any, Any, bool, Any]:
        """This loop's executed command, labels, correction flag and recording decision."""
        m = parse_mode(mode)
        if m is Mode.USER:
            return angle, throttle, user_angle, user_throttle, False, recording
        steer = _moved(user_angle, self.deadzone)
        drive = m is Mode.LOCAL and _moved(user_throttle, self.deadzone)
        if steer:
            angle = max(-1.0, min(1.0, float(user_angle)))
        if drive and not estop:
            throttle = max(-1.0, min(1.0, float(user_throttle)))
        corrected = steer or drive
        self.corrections += corrected
        return angle, throttle, angle, throttle, corrected, corrected
