"""Memory keys of the human controllers: the driver's commands (DonkeyCar's ``user/*``, ``recording``,
``estop``) and the gamepad's own (``js/*``) before arbitration with the web page.

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "user/angle": KeyInfo("float in [-1, 1]", "steering from the human controller, -1 = full left"),
    "user/throttle": KeyInfo("float in [-1, 1]", "throttle from the human controller, negative = reverse"),
    "user/mode": KeyInfo("str: user | local_angle | local", "who drives: human, pilot steers, pilot drives"),
    "recording": KeyInfo("bool", "whether the tub writer records this loop"),
    "estop": KeyInfo("bool", "emergency stop latched: throttle forced to 0"),
    "user/speed_limit": KeyInfo("float, m/s, or None", "web page's speed limit: caps the speed in every mode"),
    # -- the gamepad, before arbitration with the web page
    "js/angle": KeyInfo("float in [-1, 1]", "gamepad steering, before arbitration with the web page"),
    "js/throttle": KeyInfo("float in [-1, 1]", "gamepad throttle, before arbitration"),
    "js/mode": KeyInfo("str", "gamepad drive mode, before arbitration"),
    "js/recording": KeyInfo("bool", "gamepad record toggle, before arbitration"),
    "js/estop": KeyInfo("bool", "emergency stop latched on the gamepad"),
    "js/status": KeyInfo("str: connected | silent | lost", "the car's gamepad link (shown on the web page)"),
}
