"""Memory keys of the drive logic: the final commands (DonkeyCar's ``angle``, ``throttle``), the
pilot condition, behaviours and the speed step test.

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "angle": KeyInfo("float in [-1, 1]", "steering command sent to the drivetrain"),
    "throttle": KeyInfo("float in [-1, 1]", "throttle command sent to the drivetrain"),
    "run_pilot": KeyInfo("bool", "True when the pilot must run this loop (mode is not user)"),
    # -- behaviours
    "behavior/state": KeyInfo("int", "index of the active behaviour"),
    "behavior/label": KeyInfo("str", "name of the active behaviour, e.g. Left_Lane"),
    "behavior/one_hot_state_array": KeyInfo("list[float]", "one-hot encoding of behavior/state"),
    "behavior/step": KeyInfo("int", "+1 / -1 for one loop: select the next / previous behaviour"),
    "tune/done": KeyInfo("bool", "the speed step test has finished"),
    "user/correction": KeyInfo("bool", "the pilot drove and the label (user/angle, user/throttle) is a correction: "
                                       "the simulator's expert (DAgger) or the person's override (CORRECTION_MODE)"),
    "obstacle/stop": KeyInfo("bool", "the obstacle stop is cutting the throttle this loop"),
    "obstacle/distance": KeyInfo("float, m, or None", "nearest LiDAR return in the cone ahead"),
}
