"""Memory keys the web controller adds (collected with every package's ``keys.py``)."""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "web/path_command": KeyInfo(
        "str | None", "a path button of the web page, for one loop: record, save, load, clear or "
                      "reset_origin (merged into path/command by the path_follow template)"),
}
