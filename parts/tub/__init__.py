"""Tubs: the DonkeyCar tub v2 data store, written crash-safe.

``Tub`` opens, writes and edits one tub; ``TubWriter`` is the drive-loop part that records off the
loop thread; ``parts.tub.reader`` reads many tubs for training; ``parts.tub.udacity`` and
``parts.tub.lerobot`` convert to and from Udacity recordings and LeRobot v3.0 datasets. See
docs/data-format.md.
Submodules are imported lazily so that ``import parts.tub`` stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from parts.tub.errors import CorruptRecord, TubError
    from parts.tub.reader import TubRecord, iter_records, load_records
    from parts.tub.tub import Tub
    from parts.tub.writer import TubWiper, TubWriter

__all__ = ["Tub", "TubWriter", "TubWiper", "TubRecord", "iter_records", "load_records", "TubError",
           "CorruptRecord"]

_WHERE = {
    "Tub": "parts.tub.tub", "TubWriter": "parts.tub.writer", "TubWiper": "parts.tub.writer",
    "TubRecord": "parts.tub.reader", "iter_records": "parts.tub.reader", "load_records": "parts.tub.reader",
    "TubError": "parts.tub.errors", "CorruptRecord": "parts.tub.errors",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'parts.tub' has no attribute {name!r}")
