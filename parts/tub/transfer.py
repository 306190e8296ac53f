"""Copying a tub from one machine to another, incrementally: the wire format and both ends.

The car (the sender) takes a :class:`Snapshot` of a tub: the records whose catalog lines are whole
at that instant (their images are durable before their lines, so every one is complete), the
deleted indexes of the manifest and the CRC-32 of each image recorded when it was written
(``image_crc32.jsonl``). :func:`stream_records` turns the records from an index on into frames:

    header line   {"tub": NAME, "inputs": [...], "types": [...], "start": S, "end": E, "live": N, ...}
    per record    {"i": INDEX, "rec": {catalog fields}, "img": [[KEY, SIZE, CRC32], ...]}  + the image bytes
                  {"i": INDEX, "skip": "deleted" | "why it was not sent"}                   (no bytes)
    end line      {"done": true, "sent": COUNT}

each a JSON line, the image bytes following their record's line. The laptop (the receiver,
:class:`TubMirror`) keeps the car's indexes: a record the car deleted (or could not send) becomes
a deleted record without values (:meth:`parts.tub.tub.Tub.skip_to`), so "what the laptop has" is
its tub's ``current_index`` and a pull resumes there. Each image is checked against its CRC-32
before its record is written; a wrong one stops the pull (nothing of that record is written).

Born whole: the first pull of a tub grows in a hidden ``.NAME.pull`` folder beside its final place
and is renamed into place once every record of the snapshot is in; an interrupted pull leaves the
hidden folder, and the next pull resumes from it. A later pull appends the car's new records to
the tub in whole, committed records, as recording does.
"""

from __future__ import annotations

import json
import logging
import os
import re
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parts.tub.errors import TubError
from parts.tub.format import IMAGE_CRCS, IMAGE_TYPES, IMAGES, INDEX, MANIFEST, SESSION, TIMESTAMP, fsync_dir

logger = logging.getLogger(__name__)

#: a tub name the car serves: a folder name, no path
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")
#: the longest header line a receiver accepts, bytes (a record's catalog line is far shorter)
MAX_LINE = 1 << 20
#: the largest image a receiver accepts, bytes
MAX_IMAGE = 64 << 20
#: metadata keys a pulled tub carries (manifest line 3): where it came from
SOURCE_KEYS = ("pulled_from", "car_tub", "car_tub_created_at")


class TransferError(TubError):
    """A pull cannot go on; the message says why and what to do (run it again to resume...)."""


# -- the car's side ---------------------------------------------------------------------------------
def tub_folder(data_dir: Path, name: str) -> Path:
    """The tub ``name`` of a car's data folder (TransferError when the name is not a tub there)."""
    if not NAME_RE.match(name or ""):
        raise TransferError(f"{name!r} is not a tub name (letters, digits, '.', '_', '-')")
    path = data_dir / name
    if not (path / MANIFEST).is_file():
        raise TransferError(f"the car has no tub {name!r}; list its tubs first")
    return path


def list_tubs(data_dir: Path, sizes: dict[Path, tuple[tuple[int, int], int]] | None = None) -> list[dict[str, Any]]:
    """The tubs directly in ``data_dir`` (hidden ones, still being born, left out): name, records
    (live), next index, deleted, bytes on disk, creation time; sorted by name. Counts come from
    manifest.json, which may lag the catalogs of a tub being recorded by up to a second. ``sizes``
    keeps each tub's byte count until its manifest or images folder changes (a status page asks
    every few seconds; summing the sizes of ten thousand images each time would cost the car)."""
    from parts.tub.manifest import parse_manifest
    from parts.tub.tools import disk_size

    out: list[dict[str, Any]] = []
    if not data_dir.is_dir():
        return out
    for path in sorted(data_dir.iterdir()):
        if path.name.startswith(".") or not NAME_RE.match(path.name) or not (path / MANIFEST).is_file():
            continue
        m = parse_manifest(path / MANIFEST).manifest
        try:
            stamp = ((path / MANIFEST).stat().st_mtime_ns, (path / IMAGES).stat().st_mtime_ns)
        except OSError:
            stamp = (0, 0)
        known = sizes.get(path) if sizes is not None else None
        size = known[1] if known is not None and known[0] == stamp and stamp != (0, 0) else disk_size(path)
        if sizes is not None:
            sizes[path] = (stamp, size)
        out.append({"name": path.name, "records": m.current_index - len(m.deleted_indexes),
                    "current_index": m.current_index, "deleted": len(m.deleted_indexes),
                    "bytes": size, "created_at": m.manifest_metadata.get("created_at")})
    return out


@dataclass(frozen=True)
class Snapshot:
    """A tub's records as they were at one instant (see the module docstring)."""

    path: Path
    inputs: list[str]
    types: list[str]
    metadata: dict[str, Any]
    created_at: float | None
    end: int  # records [0, end) belong to the snapshot
    deleted: frozenset[int]
    max_len: int
    catalogs: list[Path] = field(default_factory=list)

    def header(self, start: int) -> dict[str, Any]:
        """The stream's first line for the records from ``start``."""
        live = sum(1 for i in range(start, self.end) if i not in self.deleted)
        return {"tub": self.path.name, "inputs": self.inputs, "types": self.types, "metadata": self.metadata,
                "created_at": self.created_at, "start": start, "end": self.end, "live": live,
                "max_len": self.max_len}


def snapshot(path: Path) -> Snapshot:
    """Take a snapshot of the tub ``path`` (read-only: a tub being recorded is not disturbed)."""
    from parts.tub.tub import Tub

    tub = Tub(path, read_only=True, log_problems=False)  # a recording tub's manifest lags: no warning
    try:
        m = tub.manifest
        return Snapshot(path, list(m.inputs), list(m.types), dict(m.metadata), m.manifest_metadata.get("created_at"),
                        tub.current_index, frozenset(m.deleted_indexes), tub.max_len, tub.catalog_paths)
    finally:
        tub.close()


def _stored_crcs(path: Path, start: int, end: int) -> dict[int, tuple[str | None, dict[str, int]]]:
    """index -> (session, {key: CRC-32}) from the tub's image_crc32.jsonl, for [start, end)."""
    out: dict[int, tuple[str | None, dict[str, int]]] = {}
    try:
        with open(path / IMAGE_CRCS, "rb") as f:
            for line in f:
                try:
                    entry = json.loads(line)
                    index = int(entry[INDEX])
                except (ValueError, KeyError, TypeError):
                    continue  # a torn last line (crash) or a damaged one: that record is checked as read
                if start <= index < end and isinstance(entry.get("crc32"), dict):
                    out[index] = (entry.get(SESSION), entry["crc32"])
    except FileNotFoundError:
        pass
    return out


def _records_from(snap: Snapshot, start: int) -> Iterator[tuple[int, dict[str, Any] | None]]:
    """(index, record or None when unparsable) of the snapshot's records from ``start``."""
    from parts.tub.catalog import parse_line, record_index, scan_catalog

    first = min(start // snap.max_len, max(0, len(snap.catalogs) - 1))
    position = 0
    for i, catalog in enumerate(snap.catalogs[first:], first):
        position = max(position, i * snap.max_len)
        if position >= snap.end:
            return
        for line in scan_catalog(catalog).lines:
            rec, _salvaged = parse_line(line)
            index = record_index(rec, position) if rec is not None else position
            position = index + 1
            if index >= snap.end:
                return
            if index >= start:
                yield index, rec


def stream_records(snap: Snapshot, start: int) -> Iterator[bytes]:
    """The frames of the snapshot's records from ``start`` (header, records, end line)."""
    if start < 0:
        raise TransferError(f"start must be >= 0, got {start}")
    yield _line(snap.header(start))
    crcs = _stored_crcs(snap.path, start, snap.end)
    image_keys = [k for k, t in zip(snap.inputs, snap.types, strict=True) if t in IMAGE_TYPES]
    expected, sent = start, 0
    for index, rec in _records_from(snap, start):
        for missing in range(expected, index):  # lines a crash lost: never records
            yield _line({"i": missing, "skip": "no catalog line"})
        expected = index + 1
        if index in snap.deleted:
            yield _line({"i": index, "skip": "deleted"})
            continue
        if rec is None:
            yield _line({"i": index, "skip": "its catalog line is damaged on the car"})
            continue
        frame = _record_frame(snap.path, index, rec, image_keys, crcs.get(index))
        sent += 1
        yield frame
    for missing in range(expected, snap.end):
        yield _line({"i": missing, "skip": "no catalog line"})
    yield _line({"done": True, "sent": sent})


def _record_frame(path: Path, index: int, rec: dict[str, Any], image_keys: list[str],
                  stored: tuple[str | None, dict[str, int]] | None) -> bytes:
    """One record's line and image bytes, or a skip line when an image is missing or damaged."""
    images: list[list[Any]] = []
    blobs: list[bytes] = []
    known = stored[1] if stored is not None and stored[0] in (None, rec.get(SESSION)) else {}
    for key in image_keys:
        name = rec.get(key)
        if not isinstance(name, str):
            continue
        try:
            data = (path / IMAGES / Path(name).name).read_bytes()
        except OSError:
            return _line({"i": index, "skip": f"its image {name} is missing on the car"})
        crc = zlib.crc32(data)
        if key in known and known[key] != crc:
            return _line({"i": index, "skip": f"its image {name} fails its CRC-32 on the car (damaged)"})
        images.append([key, len(data), crc])
        blobs.append(data)
    return b"".join([_line({"i": index, "rec": rec, "img": images}), *blobs])


def _line(obj: dict[str, Any]) -> bytes:
    return json.dumps(obj, sort_keys=True, allow_nan=False).encode() + b"\n"


# -- the laptop's side ------------------------------------------------------------------------------
@dataclass
class PullReport:
    """What a pull did."""

    tub: Path
    start: int
    end: int
    received: int = 0  # records written by this pull
    skipped: dict[str, int] = field(default_factory=dict)  # reason -> records kept as deleted
    complete: bool = False
    created: bool = False  # the tub appeared with this pull


class FrameReader:
    """Reads frames from a binary stream (``read(n)`` and ``readline(limit)``, e.g. an HTTP response)."""

    def __init__(self, stream: Any) -> None:
        self.stream = stream

    def line(self) -> dict[str, Any] | None:
        """The next JSON line, None at the end of the stream (TransferError when cut or malformed)."""
        raw = self.stream.readline(MAX_LINE + 1)
        if not raw:
            return None
        if not raw.endswith(b"\n"):
            raise TransferError("the car's answer was cut in the middle of a line")
        try:
            obj = json.loads(raw)
        except ValueError as exc:
            raise TransferError(f"the car sent a malformed line ({exc})") from exc
        if not isinstance(obj, dict):
            raise TransferError("the car sent a malformed line (not an object)")
        return obj

    def exactly(self, n: int) -> bytes:
        """``n`` bytes (TransferError when the stream ends before)."""
        chunks, left = [], n
        while left:
            chunk = self.stream.read(left)
            if not chunk:
                raise TransferError("the car's answer was cut in the middle of an image")
            chunks.append(chunk)
            left -= len(chunk)
        return b"".join(chunks)


def staging_folder(target: Path) -> Path:
    """Where the first pull of ``target`` grows until it is complete."""
    return target.parent / f".{target.name}.pull"


def resume_index(target: Path) -> int:
    """The index a pull into ``target`` starts at: the next index of the tub or of its
    interrupted first pull (0 when neither exists)."""
    from parts.tub.tub import Tub

    for folder in (target, staging_folder(target)):
        if (folder / MANIFEST).is_file():
            tub = Tub(folder, read_only=True)
            try:
                return tub.current_index
            finally:
                tub.close()
    return 0


class TubMirror:
    """Writes the frames of :func:`stream_records` into the laptop's copy of a car's tub.

    Args:
        target: the tub folder on the laptop (a new one appears there whole, at the end).
        source: where the tub comes from (the car's name or address), kept in its metadata.
        fsync: make each commit durable against power loss.
    """

    def __init__(self, target: Path, source: str, fsync: bool = True) -> None:
        self.target, self.source, self.fsync = target, source, fsync
        self.staging = staging_folder(target)

    def _open(self, header: dict[str, Any]) -> tuple[Any, bool]:
        """The writable tub for the stream ``header`` describes, and whether it is the staging one."""
        from parts.tub.tub import Tub

        staged = not (self.target / MANIFEST).is_file()
        folder = self.staging if staged else self.target
        identity = {"pulled_from": self.source, "car_tub": header["tub"],
                    "car_tub_created_at": header.get("created_at")}
        if (folder / MANIFEST).is_file():
            tub = Tub(folder, fsync=self.fsync, fsync_records=200, fsync_ms=5000.0)
            theirs = (tub.metadata.get("car_tub"), tub.metadata.get("car_tub_created_at"))
            if theirs != (identity["car_tub"], identity["car_tub_created_at"]) or \
                    (tub.inputs, tub.types) != (header["inputs"], header["types"]):
                tub.close()
                raise TransferError(f"{folder} holds another tub than the car's {header['tub']} (a car tub of "
                                    "the same name made anew?): pull into another folder, or move that one away")
        else:
            if folder.exists() and any(folder.iterdir()):
                raise TransferError(f"{folder} exists and is not a tub: move it away or pull into another folder")
            meta = {k: v for k, v in (header.get("metadata") or {}).items() if k not in SOURCE_KEYS}
            meta.update(identity)
            tub = Tub(folder, list(header["inputs"]), list(header["types"]), metadata=meta,
                      max_catalog_len=int(header.get("max_len") or 1000), fsync=self.fsync,
                      fsync_records=200, fsync_ms=5000.0)
        return tub, staged

    def receive(self, reader: FrameReader, progress: Callable[[int, int], None] | None = None) -> PullReport:
        """Read every frame and write the records; ``progress(done, total)`` after each record.

        Raises:
            TransferError: the stream was cut, a record is malformed or an image fails its CRC-32
                (the records before it are kept: run the pull again to resume).
        """
        header = reader.line()
        if header is None or not isinstance(header.get("inputs"), list) or not isinstance(header.get("end"), int):
            raise TransferError("the car sent no tub header (not a car of this software, or an older version?)")
        tub, staged = self._open(header)
        start, end = int(header["start"]), int(header["end"])
        report = PullReport(self.target, start, end)
        total = max(0, end - start)
        try:
            if tub.current_index != start:
                raise TransferError(f"the car sent records from {start}, but {tub.path} continues at "
                                    f"{tub.current_index}: run the pull again")
            types = dict(zip(header["inputs"], header["types"], strict=True))
            while True:
                frame = reader.line()
                if frame is None:
                    raise TransferError(f"the car closed the connection after {report.received} records "
                                        f"(of {header.get('live')}): run the pull again to resume")
                if frame.get("done"):
                    break
                self._one(tub, reader, frame, types, report)
                if progress is not None:
                    progress(tub.current_index - start, total)
            if tub.current_index < end:
                tub.skip_to(end, None)  # the car's snapshot ends with deleted records
            accounted = report.received + sum(n for why, n in report.skipped.items() if why != "deleted")
            if accounted != header.get("live"):
                raise TransferError(f"the car announced {header.get('live')} records and sent {report.received}: "
                                    "run the pull again")
            report.complete = True
        finally:
            tub.close()
        if staged and report.complete:
            os.replace(self.staging, self.target)
            if self.fsync:
                fsync_dir(self.target.parent)
            report.created = True
        return report

    @staticmethod
    def _one(tub: Any, reader: FrameReader, frame: dict[str, Any], types: dict[str, str],
             report: PullReport) -> None:
        """Write one record frame (or keep a skipped index as a deleted record)."""
        index = frame.get("i")
        if not isinstance(index, int) or index < tub.current_index:
            raise TransferError(f"the car sent record {index!r} out of order (next is {tub.current_index})")
        if "skip" in frame:
            why = str(frame["skip"])[:200]
            tub.skip_to(index + 1, None if why in ("deleted", "no catalog line") else f"not pulled: {why}")
            report.skipped[why] = report.skipped.get(why, 0) + 1
            return
        rec, images = frame.get("rec"), frame.get("img")
        if not isinstance(rec, dict) or not isinstance(images, list):
            raise TransferError(f"record {index}: malformed frame from the car")
        values = {k: v for k, v in rec.items() if k in types and types[k] not in IMAGE_TYPES}
        for item in images:
            if not (isinstance(item, list) and len(item) == 3 and item[0] in types
                    and isinstance(item[1], int) and 0 <= item[1] <= MAX_IMAGE and isinstance(item[2], int)):
                raise TransferError(f"record {index}: malformed image entry from the car")
            key, size, crc = item
            data = reader.exactly(size)
            if zlib.crc32(data) != crc:
                raise TransferError(f"record {index}: image {key} arrived damaged (CRC-32 mismatch): run the "
                                    "pull again to resume")
            values[key] = data
        stamp = rec.get(TIMESTAMP)
        tub.write_record(values, timestamp_ms=stamp if isinstance(stamp, int) else None, index=index)
        report.received += 1
