"""Memory keys of the drive logic that vehicle/keys.py does not list."""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "user/correction": KeyInfo("bool", "the pilot drove and the label (user/angle, user/throttle) is a correction: "
                                       "the simulator's expert (DAgger) or the person's override (CORRECTION_MODE)"),
}
