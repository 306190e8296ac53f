"""Errors of the tub data store; each message names the tub and says what to do."""

from __future__ import annotations

from pathlib import Path

from vehicle.errors import VehicleError


class TubError(VehicleError):
    """A tub cannot be opened or changed as asked (not a tub, schema mismatch, closed ...)."""


class TubSchemaError(TubError, ValueError):
    """Inputs/types given to a tub do not fit (unknown type, lengths differ, differ from the tub's)."""


class CorruptRecord(TubError):
    """A record cannot be read: unparsable catalog line, missing, empty or undecodable image.

    Attributes ``tub`` (path), ``index`` (record index or None when unknown) and ``file`` (the file
    that is bad) say exactly where; ``vehicle tub check --repair`` marks such records deleted.
    """

    def __init__(self, tub: str | Path, index: int | None, file: str | Path, reason: str) -> None:
        where = f"record {index}" if index is not None else "a record"
        super().__init__(f"{tub}: {where}: {file}: {reason}. "
                         f"Run `vehicle tub check --repair {tub}` to mark bad records deleted.")
        self.tub = Path(tub)
        self.index = index
        self.file = Path(file)
        self.reason = reason
