"""manifest.json: five JSON lines, read tolerantly and written atomically.

Line 1 inputs, line 2 types, line 3 user metadata, line 4 ``created_at`` + ``sessions``, line 5
``paths``, ``current_index``, ``max_len``, ``deleted_indexes``. DonkeyCar rewrites line 5 in place
(truncate + write), so a crash can leave any prefix of the file: ``parse_manifest`` returns what it
could read and says which lines were missing or broken, so that recovery fills them in.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parts.tub.errors import TubSchemaError
from parts.tub.format import atomic_write, session_full_id, session_number


def parse_metadata(metadata: Mapping[str, Any] | Iterable[str] | None) -> dict[str, Any]:
    """User metadata as a dict; DonkeyCar's ``["key:value", ...]`` list form is accepted too."""
    if metadata is None:
        return {}
    if isinstance(metadata, Mapping):
        return {str(k): v for k, v in metadata.items()}
    if isinstance(metadata, str):
        metadata = [metadata]
    out: dict[str, Any] = {}
    for item in metadata:
        key, sep, value = str(item).partition(":")
        if not sep or not key:
            raise TubSchemaError(f"metadata item {item!r} must have the form key:value")
        out[key] = value
    return out


@dataclass
class Manifest:
    """The content of manifest.json."""

    inputs: list[str] = field(default_factory=list)
    types: list[str] = field(default_factory=list)
    metadata: dict[str, Any] = field(default_factory=dict)
    # Line 4 as read (kept whole so unknown keys survive a rewrite): created_at, sessions.
    manifest_metadata: dict[str, Any] = field(default_factory=dict)
    paths: list[str] = field(default_factory=list)
    current_index: int = 0
    max_len: int = 1000
    deleted_indexes: set[int] = field(default_factory=set)

    # -- sessions (line 4) ---------------------------------------------------------------------
    @property
    def sessions(self) -> dict[str, Any]:
        s = self.manifest_metadata.get("sessions")
        return s if isinstance(s, dict) else {}

    def last_session_number(self) -> int | None:
        """Highest session number recorded in line 4 (``last_id`` or any of ``all_full_ids``)."""
        s = self.sessions
        numbers = [session_number(x) for x in s.get("all_full_ids", []) or []]
        last = s.get("last_id")
        if isinstance(last, int) and not isinstance(last, bool):
            numbers.append(last)
        numbers = [n for n in numbers if n is not None]
        return max(numbers) if numbers else None

    def add_session(self, number: int, full_id: str) -> None:
        """Register a session in line 4 with DonkeyCar's keys."""
        s = dict(self.sessions)
        ids = list(s.get("all_full_ids", []) or [])
        if full_id not in ids:
            ids.append(full_id)
        s["all_full_ids"] = ids
        s["last_id"] = number
        s["last_full_id"] = full_id
        self.manifest_metadata["sessions"] = s

    def new_session(self, floor: int | None = None) -> tuple[int, str]:
        """Next session (number, full id) after the manifest's sessions and ``floor``."""
        known = [n for n in (self.last_session_number(), floor) if n is not None]
        number = max(known) + 1 if known else 0
        return number, session_full_id(number)

    # -- serialisation -------------------------------------------------------------------------
    def catalog_line(self) -> dict[str, Any]:
        return {"paths": list(self.paths), "current_index": self.current_index, "max_len": self.max_len,
                "deleted_indexes": sorted(self.deleted_indexes)}

    def dumps(self) -> str:
        """The five lines, exactly as DonkeyCar writes them (json.dumps defaults, newline-terminated)."""
        lines = [self.inputs, self.types, self.metadata, self.manifest_metadata, self.catalog_line()]
        return "".join(json.dumps(x) + "\n" for x in lines)

    def save(self, tub: Path, *, durable: bool = True) -> None:
        """Atomically replace ``tub/manifest.json``."""
        atomic_write(tub / "manifest.json", self.dumps(), durable=durable)


@dataclass
class ParsedManifest:
    """What could be read from manifest.json; ``problems`` lists what recovery must fill in."""

    manifest: Manifest
    has_schema: bool
    has_catalog_line: bool
    problems: list[str]
    has_sessions_line: bool = True  # line 4 (created_at, sessions) was read


def _load_line(lines: list[str], i: int, kind: type) -> Any:
    if i >= len(lines):
        return None
    try:
        value = json.loads(lines[i])
    except ValueError:
        return None
    return value if isinstance(value, kind) else None


def parse_manifest(path: Path) -> ParsedManifest:
    """Read manifest.json tolerantly. A missing or empty file gives an empty manifest with problems."""
    try:
        text = path.read_bytes().decode("utf-8", errors="replace")
    except FileNotFoundError:
        return ParsedManifest(Manifest(), False, False, ["manifest.json is missing"], False)
    raw = text.split("\n")
    # A last line without newline may be a torn write; json.loads still accepts it if whole.
    lines = [ln for ln in raw if ln.strip()]
    problems: list[str] = []
    m = Manifest()
    inputs = _load_line(lines, 0, list)
    types = _load_line(lines, 1, list)
    has_schema = (inputs is not None and types is not None and len(inputs) == len(types)
                  and all(isinstance(x, str) for x in inputs + types))
    if has_schema:
        m.inputs, m.types = list(inputs), list(types)
    else:
        problems.append("inputs/types (lines 1-2) unreadable" if lines else "manifest.json is empty")
    meta = _load_line(lines, 2, dict)
    if meta is None and lines:
        problems.append("metadata (line 3) unreadable")
    m.metadata = meta or {}
    mm = _load_line(lines, 3, dict)
    if mm is None and lines:
        problems.append("sessions (line 4) unreadable")
    m.manifest_metadata = mm or {"created_at": time.time()}
    cat = _load_line(lines, 4, dict)
    has_catalog_line = False
    if cat is not None:
        try:
            m.paths = [str(p) for p in cat["paths"]]
            m.current_index = int(cat["current_index"])
            m.max_len = int(cat["max_len"])
            m.deleted_indexes = {int(i) for i in cat.get("deleted_indexes", [])}
            has_catalog_line = m.max_len > 0
        except (KeyError, TypeError, ValueError):
            pass
    if not has_catalog_line and lines:
        problems.append("catalog list (line 5) unreadable")
    return ParsedManifest(m, has_schema, has_catalog_line, problems, mm is not None)
