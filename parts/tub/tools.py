"""Tub inspection helpers behind ``vehicle tub info|ls|delete|restore``."""

from __future__ import annotations

import contextlib
import os
import time
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parts.tub.errors import TubError
from parts.tub.format import INDEX, SESSION, TIMESTAMP
from parts.tub.tub import Tub


def parse_ranges(spec: str, end: int) -> list[int]:
    """Index ranges like ``"3,10:20,95:"`` -> sorted indexes (``a:b`` excludes b, as in Python).

    ``end`` is the tub's current_index (used for open ranges). ValueError says what is wrong.
    """
    out: set[int] = set()
    for part in spec.replace(" ", "").split(","):
        if not part:
            continue
        try:
            if ":" in part:
                a, _, b = part.partition(":")
                lo = int(a) if a else 0
                hi = int(b) if b else end
                if lo > hi:
                    raise ValueError
                out.update(range(lo, hi))
            else:
                out.add(int(part))
        except ValueError:
            raise ValueError(f"bad index range {part!r}: use N, A:B (A..B-1), A: or :B, "
                             "separated by commas, e.g. 3,10:20,95:") from None
    bad = sorted(i for i in out if not 0 <= i < end)
    if bad:
        raise ValueError(f"indexes {bad[:5]} are outside the tub's records 0..{end - 1}")
    return sorted(out)


def format_ranges(indexes: list[int]) -> str:
    """Sorted indexes -> a spec :func:`parse_ranges` reads back: ``[1, 2, 3, 7]`` -> ``"1:4,7"``."""
    parts: list[str] = []
    i = 0
    while i < len(indexes):
        j = i
        while j + 1 < len(indexes) and indexes[j + 1] == indexes[j] + 1:
            j += 1
        parts.append(str(indexes[i]) if i == j else f"{indexes[i]}:{indexes[j] + 1}")
        i = j + 1
    return ",".join(parts)


def disk_size(path: Path) -> int:
    """Bytes of all files under ``path``."""
    total = 0
    for root, _dirs, files in os.walk(path):
        for f in files:
            with contextlib.suppress(OSError):
                total += os.stat(os.path.join(root, f)).st_size
    return total


@dataclass
class TubInfo:
    """What ``vehicle tub info`` prints."""

    path: Path
    records: int                 # not deleted
    deleted: int
    current_index: int
    fields: list[tuple[str, str]]
    sessions: dict[str, int]     # session id -> records (not deleted)
    first_ms: int | None
    last_ms: int | None
    catalogs: int
    disk_bytes: int
    metadata: dict[str, Any]
    problems: list[str] = field(default_factory=list)
    torn: dict[str, int] = field(default_factory=dict)  # catalog -> bytes of its torn last line

    def lines(self) -> list[str]:
        def when(ms: int | None) -> str:
            return "-" if ms is None else time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(ms / 1000))

        span = "-" if self.first_ms is None or self.last_ms is None else \
            f"{when(self.first_ms)} .. {when(self.last_ms)} ({(self.last_ms - self.first_ms) / 1000:.1f} s)"
        out = [f"tub:       {self.path}",
               f"records:   {self.records} ({self.deleted} deleted, next index {self.current_index})",
               f"sessions:  {len(self.sessions)}"
               + "".join(f"\n           {s}: {n}" for s, n in self.sessions.items()),
               f"time span: {span}",
               "fields:    " + ", ".join(f"{k} ({t})" for k, t in self.fields),
               f"catalogs:  {self.catalogs}",
               f"disk size: {self.disk_bytes / 1e6:.2f} MB"
               + (f" ({self.disk_bytes / max(1, self.current_index):.0f} bytes/record)"
                  if self.current_index else ""),
               f"metadata:  {self.metadata}"]
        out += [f"torn last line: {n} bytes at the end of {name} (a write cut short; the record is not "
                "counted; `vehicle tub repair` cuts it)" for name, n in self.torn.items()]
        if self.problems:
            out.append("recovered: " + "; ".join(self.problems))
        return out


def tub_info(path: str | os.PathLike[str]) -> TubInfo:
    """Summarise a tub (read-only)."""
    tub = Tub(path, read_only=True)
    sessions: Counter[str] = Counter()
    first = last = None
    for _, rec in tub.records():
        sessions[str(rec.get(SESSION, "?"))] += 1
        ts = rec.get(TIMESTAMP)
        if isinstance(ts, int | float):
            first = ts if first is None else min(first, ts)
            last = ts if last is None else max(last, ts)
    return TubInfo(tub.path, len(tub), len(tub.manifest.deleted_indexes), tub.current_index,
                   list(zip(tub.inputs, tub.types, strict=True)), dict(sessions),
                   None if first is None else int(first), None if last is None else int(last),
                   len(tub.manifest.paths), disk_size(tub.path), dict(tub.metadata), list(tub.problems),
                   dict(tub.torn))


def format_header(fields: list[str]) -> str:
    """The header line of ``vehicle tub ls``."""
    return "  ".join(["  index", " "] + [f"{k:>8}" for k in fields])


def check_fields(fields: Sequence[str], known: Iterable[str], where: str) -> None:
    """Raise :class:`TubError` naming the first of ``fields`` that is not in ``known`` (the tubs'
    inputs), the closest known name and all of them; a misspelt field would show as empty."""
    import difflib

    known = list(dict.fromkeys([*known, INDEX, TIMESTAMP, SESSION]))
    for name in fields:
        if name not in known:
            close = difflib.get_close_matches(name, known, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise TubError(f"{where} has no field {name!r}{hint}; its fields: {', '.join(known)}")


def format_record(index: int, rec: dict[str, Any], deleted: bool, fields: list[str]) -> str:
    """One ``vehicle tub ls`` line, cells aligned under format_header."""
    cells = [f"{index:>7}", "D" if deleted else " "]
    for key in fields:
        v = rec.get(key)
        text = f"{v:+.3f}" if isinstance(v, float) else str(v)
        cells.append(f"{text:>{max(8, len(key))}}")
    return "  ".join(cells)
