"""Memory keys of the built-in simulator: telemetry of the simulated car (``sim/*``).

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "sim/cte": KeyInfo("float, m", "signed cross-track error, positive = right of the centre line (the simulator's "
                                   "own units from the Donkey simulator and Udacity forks)"),
    "sim/heading_error": KeyInfo("float, rad", "car heading minus track heading"),
    "sim/speed": KeyInfo("float, m/s", "speed of the simulated car"),
    "sim/progress": KeyInfo("float in [0, 1)", "fraction of the current lap driven"),
    "sim/lap": KeyInfo("int", "laps completed"),
    "sim/lap_time": KeyInfo("float, s", "duration of the last completed lap"),
    "sim/off_track": KeyInfo("bool", "True while the car is off the road"),
    "sim/pos": KeyInfo("tuple[float, float], m", "car position in track coordinates"),
    "sim/track": KeyInfo("int", "seed of the track the simulated car is on"),
    "sim/reset": KeyInfo("bool", "rising edge puts the simulated car back on its start line"),
}
