"""Memory keys the simulator bridges add to the simulator's ``sim/*`` telemetry (Udacity and Donkey
simulators).

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "sim/steering_deg": KeyInfo("float, degrees", "steering the Udacity simulator reports, positive = right"),
    "sim/throttle": KeyInfo("float in [-1, 1]", "throttle the Udacity simulator reports"),
    "sim/manual": KeyInfo("bool", "the user overrides the pilot in the simulator (Udacity: W/S held)"),
    "sim/hit": KeyInfo("str", "what the simulated car hit this loop, or 'none' (Donkey simulator)"),
    "sim/time": KeyInfo("float, s", "the simulator's clock (Donkey simulator: time since the scene loaded)"),
    "sim/extra": KeyInfo("dict", "other telemetry fields of a simulator (Donkey IMU, Udacity fork keys)"),
}
