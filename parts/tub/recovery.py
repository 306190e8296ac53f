"""Work out a tub's true state from what is on disk, whatever instant a crash hit.

Rules (docs/data-format.md "Recovery"):

- manifest.json unreadable or missing lines -> rebuilt: inputs/types inferred from the catalog
  records, catalog list from the ``catalog_<n>.catalog`` files, metadata empty if lost;
- catalogs on disk after the last listed one (crash after creating it) are adopted;
- ``current_index`` = highest ``_index`` in the catalogs + 1 (a stale manifest would give duplicate
  indexes); deleted indexes beyond it are dropped;
- the next session number is above every session in the manifest *and* in the last catalog (the
  session of a crashed run may never have reached the manifest: it is added);
- line 4 lost: ``created_at`` and the sessions are rebuilt from the records (``_timestamp_ms``,
  ``_session_id``);
- empty catalogs at the end (a kill right after a catalog was started; DonkeyCar cannot open an
  empty catalog) are dropped, and so are listed catalogs whose file is gone;
- the torn tail of a catalog is cut when the tub is opened for writing (``CatalogFile``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from parts.tub.catalog import parse_line, read_catalog_manifest, record_index, scan_catalog
from parts.tub.format import CATALOG_RE, IMAGES, MANIFEST, SESSION, TIMESTAMP, session_number
from parts.tub.manifest import Manifest, parse_manifest

_INFER_SAMPLE = 200  # records looked at to infer a lost schema


@dataclass
class TubState:
    """A tub as found on disk, with the fixes recovery made (in memory; the Tub writes them)."""

    manifest: Manifest
    has_schema: bool
    is_tub: bool                      # a manifest.json or a catalog exists
    problems: list[str] = field(default_factory=list)
    session_floor: int | None = None  # highest session number seen in the catalogs
    torn: dict[str, int] = field(default_factory=dict)  # catalog name -> torn bytes at its end
    dropped: list[str] = field(default_factory=list)  # empty trailing catalogs (files to remove)

def catalogs_on_disk(tub: Path) -> list[str]:
    """``catalog_<n>.catalog`` names in the folder, by n."""
    found = []
    try:
        for p in tub.iterdir():
            m = CATALOG_RE.match(p.name)
            if m and p.is_file():
                found.append((int(m.group(1)), p.name))
    except FileNotFoundError:
        return []
    return [name for _, name in sorted(found)]


def infer_types(tub: Path, records: list[dict]) -> tuple[list[str], list[str]]:
    """Inputs and types guessed from records (used only when manifest lines 1-2 are lost)."""
    inputs: list[str] = []
    types: list[str] = []
    for rec in records:
        for key, value in rec.items():
            if key.startswith("_") or key in inputs:
                continue
            if isinstance(value, bool):
                tp = "boolean"
            elif isinstance(value, int):
                tp = "int"
            elif isinstance(value, float):
                tp = "float"
            elif isinstance(value, list):
                tp = "list"
            elif isinstance(value, str) and value.endswith((".jpg", ".png")) \
                    and (tub / IMAGES / value).exists():
                tp = "gray16_array" if value.endswith(".png") else "image_array"
            else:
                tp = "str"
            inputs.append(key)
            types.append(tp)
    return inputs, types


def inspect_tub(tub: Path, default_max_len: int = 1000) -> TubState:
    """Read manifest and catalogs and reconcile them (nothing is written here)."""
    parsed = parse_manifest(tub / MANIFEST)
    m = parsed.manifest
    on_disk = catalogs_on_disk(tub)
    is_tub = (tub / MANIFEST).exists() or bool(on_disk)
    state = TubState(m, parsed.has_schema, is_tub)
    if not is_tub:
        return state
    if (tub / MANIFEST).exists() and parsed.problems:
        state.problems.extend(parsed.problems)
    elif not (tub / MANIFEST).exists():
        state.problems.append("manifest.json is missing")

    if parsed.has_catalog_line:
        listed = [p for p in m.paths if CATALOG_RE.match(Path(p).name)]
        if listed != m.paths:
            state.problems.append(f"catalog list had invalid names {m.paths}")
        last_n = int(CATALOG_RE.match(listed[-1]).group(1)) if listed else -1
        extra = [c for c in on_disk if int(CATALOG_RE.match(c).group(1)) > last_n]
        if extra:
            state.problems.append(f"catalogs {extra} were missing from the manifest")
        m.paths = listed + extra
    else:
        m.paths = list(on_disk)
        m.max_len = _infer_max_len(tub, on_disk, default_max_len)
    while len(m.paths) > 1 and not scan_catalog(tub / m.paths[-1]).lines:
        name = m.paths.pop()
        state.dropped.append(name)
        if not (tub / name).exists() and (tub / f".{name}.new").exists():  # parts.tub.births
            state.problems.append(f"{name} waits in .{name}.new (the writer was killed while putting it in "
                                  "place; DonkeyCar cannot open the tub): `vehicle tub check --repair` completes it")
            continue
        gone = "is missing" if not (tub / name).exists() else "is empty"
        state.problems.append(f"{name} {gone} (a kill right after it was started; DonkeyCar cannot open "
                              "such a tub): dropped")

    # Find the last record: walk back from the last catalog to the first one that holds records.
    # Only the last parsable line is needed: indexes and session numbers grow along a tub.
    last_index = -1
    last_record: dict | None = None
    for pos in range(len(m.paths) - 1, -1, -1):
        scan = scan_catalog(tub / m.paths[pos])
        if scan.torn_bytes and pos == len(m.paths) - 1:
            state.torn[m.paths[pos]] = scan.torn_bytes
        for i in range(len(scan.lines) - 1, -1, -1):
            rec, _ = parse_line(scan.lines[i])
            if rec is not None:
                last_record = rec
                last_index = record_index(rec, _start_of(tub, m, pos) + i)
                break
        if last_record is not None:
            break
    state.session_floor = session_number(last_record.get(SESSION)) if last_record else None

    true_index = last_index + 1
    if parsed.has_catalog_line and true_index != m.current_index:
        state.problems.append(f"manifest said current_index {m.current_index}, the catalogs hold "
                              f"records up to index {last_index}")
    m.current_index = true_index
    stale = {i for i in m.deleted_indexes if i >= true_index}
    if stale:
        m.deleted_indexes -= stale
        state.problems.append(f"dropped {len(stale)} deleted indexes beyond the last record")

    if not parsed.has_schema:
        sample = _sample_records(tub, m.paths)
        if sample:
            m.inputs, m.types = infer_types(tub, sample)
            state.has_schema = True
            state.problems.append(f"inputs/types rebuilt from the catalogs: {m.inputs} {m.types}")
    if not parsed.has_sessions_line:
        _rebuild_line_four(tub, m)
        state.problems.append("created_at and sessions (line 4) rebuilt from the records")
    last_known = m.last_session_number()
    if state.session_floor is not None and (last_known is None or state.session_floor > last_known):
        state.problems.append("the last session never reached the manifest (crashed run): added")
        full_id = last_record.get(SESSION) if last_record else None
        if isinstance(full_id, str):
            m.add_session(state.session_floor, full_id)
    return state


def _rebuild_line_four(tub: Path, m: Manifest) -> None:
    """``created_at`` (the first record's time) and the sessions, in order, from the records."""
    first_ms: float | None = None
    sessions: list[str] = []
    for name in m.paths:
        for line in scan_catalog(tub / name).lines:
            rec, _ = parse_line(line)
            if rec is None:
                continue
            ts = rec.get(TIMESTAMP)
            if isinstance(ts, int | float) and not isinstance(ts, bool) and (first_ms is None or ts < first_ms):
                first_ms = ts
            sid = rec.get(SESSION)
            if isinstance(sid, str) and (not sessions or sessions[-1] != sid) and sid not in sessions:
                sessions.append(sid)
    meta = dict(m.manifest_metadata)
    if first_ms is not None:
        meta["created_at"] = first_ms / 1000.0
    meta.pop("sessions", None)
    m.manifest_metadata = meta
    for sid in sessions:
        number = session_number(sid)
        if number is not None:
            m.add_session(number, sid)


def _start_of(tub: Path, m: Manifest, pos: int) -> int:
    meta = read_catalog_manifest(tub / m.paths[pos]) or {}
    start = meta.get("start_index")
    return start if isinstance(start, int) else pos * m.max_len


def _infer_max_len(tub: Path, names: list[str], default: int) -> int:
    for name in names[1:]:
        start = (read_catalog_manifest(tub / name) or {}).get("start_index")
        n = int(CATALOG_RE.match(name).group(1))
        if isinstance(start, int) and start > 0 and n > 0:
            return start // n
    if len(names) > 1:
        return max(1, len(scan_catalog(tub / names[0]).lines))
    return default


def _sample_records(tub: Path, paths: list[str]) -> list[dict]:
    out: list[dict] = []
    for name in paths:
        for line in scan_catalog(tub / name).lines:
            rec, _ = parse_line(line)
            if rec is not None:
                out.append(rec)
                if len(out) >= _INFER_SAMPLE:
                    return out
    return out

