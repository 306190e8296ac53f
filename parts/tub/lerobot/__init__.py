"""LeRobot datasets (codebase version v3.0): export tubs to them, import them into tubs.

``export_lerobot(tubs, out)`` writes meta/info.json, meta/stats.json, meta/tasks.parquet,
meta/episodes/, data/ and videos/ as LeRobot's own dataset writer does; ``import_lerobot(src,
tub)`` reads such a dataset (ours or anyone's) back into a new tub. The field-by-field mapping is
in docs/data-format.md. pyarrow and PyAV come with the ``datasets`` extra and are imported only
when a function runs. Submodules are imported lazily so that ``import parts.tub.lerobot`` is light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from parts.tub.lerobot.export import ExportReport, export_lerobot
    from parts.tub.lerobot.load import ImportReport, import_lerobot

__all__ = ["export_lerobot", "import_lerobot", "ExportReport", "ImportReport"]

_WHERE = {
    "export_lerobot": "parts.tub.lerobot.export", "ExportReport": "parts.tub.lerobot.export",
    "import_lerobot": "parts.tub.lerobot.load", "ImportReport": "parts.tub.lerobot.load",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'parts.tub.lerobot' has no attribute {name!r}")
