"""Memory keys of the sonar."""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "sonar/distance": KeyInfo("float, m", "distance to the nearest object ahead; None when stale"),
    "sonar/ok": KeyInfo("bool", "False while the sonar has not reported within its max age"),
}
