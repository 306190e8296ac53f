"""Catalog files: append-only JSON lines plus their ``.catalog_manifest`` (line lengths).

Only whole lines count: bytes after the last newline are a torn write and are cut on a writable
open (``CatalogFile.open_append``) and ignored when reading. A line that is not a JSON object is
reported; when it is two records run together (DonkeyCar appending after a torn line) the whole
second record is salvaged.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parts.tub.format import INDEX, O_BINARY, atomic_write, catalog_manifest_name, write_all

_RECORD_START = b'{"_index": '
_decode_str = json.JSONDecoder().decode


def _loads_utf8(line: bytes) -> Any:
    """json.loads for the usual line (plain UTF-8) without json's encoding sniffing."""
    return _decode_str(line.decode())


@dataclass
class CatalogScan:
    """The whole lines of one catalog file and its torn tail."""

    path: Path
    lines: list[bytes]            # complete lines without the newline
    line_lengths: list[int]       # characters per line incl. newline (DonkeyCar's Seekable unit)
    valid_bytes: int              # length of the file up to and including the last newline
    torn_bytes: int               # bytes after the last newline (a torn write)


def scan_catalog(path: Path) -> CatalogScan:
    """Read a catalog file; a missing file reads as empty."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        data = b""
    end = data.rfind(b"\n") + 1
    body = data[:end]
    lines = body.split(b"\n")[:-1] if body else []
    if body.isascii():  # what json.dumps writes: a character per byte
        lengths = [len(ln) + 1 for ln in lines]
    else:
        lengths = [len(ln.decode("utf-8", errors="replace")) + 1 for ln in lines]
    return CatalogScan(path, lines, lengths, end, len(data) - end)


def parse_line(line: bytes) -> tuple[dict[str, Any] | None, bool]:
    """Parse one catalog line -> (record or None, salvaged).

    A line holding a torn record followed by a whole one (what DonkeyCar writes after a power loss)
    gives the whole second record with ``salvaged=True``.
    """
    for decode in (_loads_utf8, json.loads):  # the fast path, then json's own reading of bytes
        try:
            rec = decode(line)
            if isinstance(rec, dict):
                return rec, False
        except ValueError:
            pass
    at = line.rfind(_RECORD_START)
    if at > 0:
        try:
            rec = json.loads(line[at:])
            if isinstance(rec, dict):
                return rec, True
        except ValueError:
            pass
    return None, False


def record_index(rec: dict[str, Any], fallback: int) -> int:
    """The record's ``_index`` when it is an int, else its position in the tub."""
    idx = rec.get(INDEX)
    return idx if isinstance(idx, int) and not isinstance(idx, bool) and idx >= 0 else fallback


def read_catalog_manifest(catalog: Path) -> dict[str, Any] | None:
    """The ``.catalog_manifest`` next to ``catalog``, or None when missing/unreadable."""
    try:
        value = json.loads(catalog.with_name(catalog_manifest_name(catalog.name)).read_bytes())
    except (OSError, ValueError):
        return None
    return value if isinstance(value, dict) else None


def write_catalog_manifest(catalog: Path, start_index: int, line_lengths: list[int],
                           created_at: float | None = None, *, durable: bool = False) -> None:
    """Replace the catalog's ``.catalog_manifest`` atomically (DonkeyCar's one-line format).

    Not durable by default: recovery recomputes line lengths from the catalog itself.
    """
    name = catalog_manifest_name(catalog.name)
    content = {"created_at": time.time() if created_at is None else created_at,
               "line_lengths": line_lengths, "path": name, "start_index": start_index}
    atomic_write(catalog.with_name(name), json.dumps(content, allow_nan=False, sort_keys=True) + "\n",
                 durable=durable)


@dataclass
class CatalogFile:
    """The catalog being appended to: an O_APPEND descriptor and its line lengths."""

    path: Path
    start_index: int
    line_lengths: list[int] = field(default_factory=list)
    created_at: float = field(default_factory=time.time)
    fd: int = -1
    size: int = 0          # bytes of whole, committed lines: where the next line starts
    _torn: bool = False    # a failed append may have left bytes past ``size``

    @classmethod
    def open_append(cls, path: Path, start_index: int, *, durable: bool) -> CatalogFile:
        """Open (create) a catalog for appending, cutting a torn last line first."""
        scan = scan_catalog(path)
        existed = path.exists()
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND | O_BINARY, 0o644)
        if scan.torn_bytes:
            os.ftruncate(fd, scan.valid_bytes)
            if durable:
                os.fsync(fd)
        meta = read_catalog_manifest(path) or {}
        created = meta.get("created_at")
        cat = cls(path, start_index, list(scan.line_lengths),
                  created if isinstance(created, int | float) else time.time(), fd, scan.valid_bytes)
        if not existed or meta.get("line_lengths") != cat.line_lengths \
                or meta.get("start_index") != start_index:
            cat.save_manifest(durable=durable)
        return cat

    def append(self, lines: list[str], *, durable: bool) -> None:
        """Append whole lines (each ending in a newline) in one write, then fsync when durable.

        When the write or the fsync fails, the file is cut back to its committed lines, so that
        retrying the same lines never writes them twice or glues them to a torn one.
        """
        if self._torn:  # the cut after an earlier failure failed too: cut before going on
            os.ftruncate(self.fd, self.size)
            self._torn = False
        data = "".join(lines).encode()
        try:
            write_all(self.fd, data)
            if durable:
                os.fsync(self.fd)
        except BaseException:
            self._torn = True
            try:
                os.ftruncate(self.fd, self.size)
                self._torn = False
            except OSError:
                pass  # retried before the next append
            raise
        self.size += len(data)
        self.line_lengths.extend(len(ln) for ln in lines)

    def cut_back(self, size: int, lines: int) -> None:
        """Remove the last ``lines`` lines, which start at byte ``size`` (to append them again)."""
        del self.line_lengths[len(self.line_lengths) - lines:]
        self.size = size
        self._torn = True  # cut now, or before the next append if this fails
        try:
            os.ftruncate(self.fd, size)
            self._torn = False
        except OSError:
            pass

    def save_manifest(self, *, durable: bool = False) -> None:
        write_catalog_manifest(self.path, self.start_index, self.line_lengths, self.created_at,
                               durable=durable)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

