"""Memory keys of the Pilot part: its commands and the model it drives with.

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "pilot/model_request": KeyInfo("str path or None", "model file the web picker asks the pilot to load"),
    "pilot/angle": KeyInfo("float in [-1, 1]", "steering from the pilot"),
    "pilot/throttle": KeyInfo("float in [-1, 1]", "throttle from the pilot"),
    "pilot/model": KeyInfo("str", "file name of the model driving now (after a hot switch: the new one)"),
    "pilot/load_error": KeyInfo("str or None", "why the last model asked for was not loaded (None after a success)"),
}
