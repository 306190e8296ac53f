"""Memory keys of recording.

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "tub/num_records": KeyInfo("int", "records in the current tub"),
    "tub/erase": KeyInfo("bool", "rising edge: delete the last ERASE_LAST_N_RECORDS records"),
}
