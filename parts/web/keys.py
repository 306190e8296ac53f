"""Memory keys of the web controller: the page's commands before arbitration (``web/*``) and which
controller drives.

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "web/angle": KeyInfo("float in [-1, 1]", "steering from the web page, before arbitration"),
    "web/throttle": KeyInfo("float in [-1, 1]", "throttle from the web page, before arbitration"),
    "web/mode": KeyInfo("str", "drive mode chosen on the web page, before arbitration"),
    "web/recording": KeyInfo("bool", "record toggle of the web page, before arbitration"),
    "web/estop": KeyInfo("bool", "emergency stop latched on the web page"),
    "web/behavior_step": KeyInfo("int", "behaviour steps asked on the web page this loop (change lane)"),
    "controller/active": KeyInfo("str: gamepad | web", "which controller's stick drives (arbitration)"),
    "web/path_command": KeyInfo(
        "str | None", "a path button of the web page, for one loop: record, save, load, clear or "
                      "reset_origin (merged into path/command by the path_follow template)"),
}
