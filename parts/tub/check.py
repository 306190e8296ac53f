"""``vehicle tub check [--repair]``: find (and fix) everything that would hurt training."""

from __future__ import annotations

import json
import logging
import os
import zlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parts.tub.births import remove_stillborn, set_aside, stillborn
from parts.tub.catalog import parse_line, read_catalog_manifest, scan_catalog, write_catalog_manifest
from parts.tub.codec import image_problem
from parts.tub.format import (
    ALL_TYPES,
    IMAGE_CRCS,
    IMAGE_TYPES,
    INDEX,
    SESSION,
    atomic_write,
    catalog_manifest_name,
    dumps_record,
)
from parts.tub.tub import Tub

logger = logging.getLogger(__name__)


@dataclass
class CheckReport:
    """Findings of a tub check. ``bad_records`` maps index -> reason."""

    path: Path
    records: int = 0
    recovered: list[str] = field(default_factory=list)     # manifest/catalog problems (fixed on repair)
    catalog_manifests: list[str] = field(default_factory=list)  # .catalog_manifest problems (rewritten)
    torn_bytes: int = 0                                     # bytes of torn last lines (cut on repair)
    unparsable: list[tuple[str, int]] = field(default_factory=list)  # (catalog, position)
    bad_records: dict[int, str] = field(default_factory=dict)
    duplicate_indexes: list[int] = field(default_factory=list)
    orphan_images: int = 0
    stillborn: bool = False  # a tub an older version was killed while creating (parts.tub.births)
    empty: bool = False  # no record at all: DonkeyCar's read-only open fails on its empty catalog
    moved_to: Path | None = None  # where repair moved an empty tub (restorable)
    unknown_types: dict[str, str] = field(default_factory=dict)  # key -> a type manifest.json gives it
    repaired: bool = False

    @property
    def settled(self) -> bool:
        """Nothing is left to do: OK, or repaired with nothing repair cannot decide."""
        return self.ok or (self.repaired and not self.unknown_types)

    @property
    def ok(self) -> bool:
        return not (self.stillborn or self.empty or self.unknown_types or self.recovered or self.catalog_manifests
                    or self.torn_bytes or self.unparsable or self.bad_records or self.duplicate_indexes)

    def lines(self) -> list[str]:
        if self.stillborn:
            return [f"{self.path}: a tub killed while it was created (by an older version): it holds no records "
                    "and DonkeyCar cannot open it",
                    "  removed" if self.repaired else "  run with --repair to remove it (nothing is lost)"]
        if self.empty:
            return [f"{self.path}: holds no records and DonkeyCar cannot open it (its read-only open fails on "
                    "the empty catalog: cannot mmap an empty file)",
                    f"  moved aside to {self.moved_to}; nothing was lost: mv {self.moved_to} {self.path} restores it"
                    if self.repaired else "  run with --repair to move it aside (restorable)"]
        out = [f"{self.path}: {self.records} records checked"]
        out += [f"  manifest.json line 2: {key}: unknown type {tp!r}, its values are not checked (known: "
                f"{', '.join(ALL_TYPES)}); fix the type by hand" for key, tp in self.unknown_types.items()]
        out += [f"  manifest: {p}" for p in self.recovered]
        out += [f"  {p}" for p in self.catalog_manifests]
        if self.torn_bytes:
            out.append(f"  torn last line(s): {self.torn_bytes} bytes")
        out += [f"  {cat}: line {pos + 1}: unparsable" for cat, pos in self.unparsable]
        out += [f"  record {i}: {why}" for i, why in sorted(self.bad_records.items())]
        if self.duplicate_indexes:
            out.append(f"  duplicate _index values: {self.duplicate_indexes[:10]}")
        if self.orphan_images:
            out.append(f"  {self.orphan_images} image files belong to no record (harmless)")
        if self.ok:
            out.append("  OK")
        elif self.repaired and self.unknown_types:
            out.append("  repaired what repair can; the unknown types are left as they are")
        elif self.repaired:
            out.append("  repaired: manifest and catalog manifests rewritten, torn lines cut, bad records "
                       "marked deleted")
        else:
            out.append("  run with --repair to fix (bad records are soft-deleted, restorable)")
        return out


def check_tub(path: str | os.PathLike[str], repair: bool = False, decode: bool = True,
              progress: bool = False) -> CheckReport:
    """Check one tub: manifest vs catalogs, each catalog's ``.catalog_manifest`` (DonkeyCar needs
    it, with the catalog's line lengths), torn and unparsable lines, duplicate indexes, and every
    image of every live record: exists, non-empty, a whole JPEG/PNG, and, with ``decode``, decodes
    without errors (a JPEG damaged in its middle decodes only with libjpeg's warnings).

    With ``repair`` the tub is opened for writing (which rewrites the manifest, cuts torn lines and
    drops empty trailing catalogs), bad records are soft-deleted and the catalog manifests are
    rewritten from the catalogs.
    """
    if stillborn(Path(path)):
        report = CheckReport(Path(path).absolute(), stillborn=True)
        if repair:
            remove_stillborn(Path(path))
            report.repaired = True
        return report
    ro = Tub(path, read_only=True)
    report = CheckReport(ro.path, recovered=list(ro.problems))
    report.unknown_types = {k: t for k, t in zip(ro.inputs, ro.types, strict=True) if t not in ALL_TYPES}
    if ro.current_index == 0:  # not a line in any catalog
        report.empty = True
        ro.close()
        if repair:
            report.moved_to = set_aside(ro.path)
            report.repaired = True
        return report
    report.catalog_manifests = _catalog_manifest_problems(ro)
    report.torn_bytes = sum(_torn(p) for p in ro.catalog_paths)
    if repair:
        for catalog in ro.catalog_paths[:-1]:  # the last one is cut by the writable open
            if _torn(catalog):
                with open(catalog, "r+b") as f:
                    f.truncate(catalog.stat().st_size - _torn(catalog))
        ro.close()
    tub = Tub(path) if repair else ro
    image_keys = [k for k, t in zip(tub.inputs, tub.types, strict=True) if t in IMAGE_TYPES]
    crcs = read_image_crcs(tub.path)
    seen: Counter[int] = Counter()
    referenced: set[str] = set()
    deleted = tub.manifest.deleted_indexes
    lines = list(tub.scan())
    bar = _progress(len(lines), f"check {tub.path.name}", progress)
    for catalog, index, rec, _line, _salvaged in lines:
        bar.update(1)
        if rec is None:
            report.unparsable.append((catalog.name, index))
            continue
        seen[index] += 1
        for key in image_keys:
            if isinstance(rec.get(key), str):
                referenced.add(rec[key])
        if index in deleted:
            continue
        report.records += 1
        crc = crcs.get(index)
        expected = crc[1] if crc is not None and crc[0] == rec.get(SESSION) else None
        why = _image_problem(tub.images_path, rec, image_keys, decode, expected)
        if why:
            report.bad_records[index] = why
    bar.close()
    report.duplicate_indexes = sorted(i for i, n in seen.items() if n > 1)
    if tub.images_path.is_dir():
        report.orphan_images = sum(1 for f in os.listdir(tub.images_path) if f not in referenced)
    if repair:
        parsed = set(seen)
        extra = {pos for _, pos in report.unparsable if pos not in parsed and pos < tub.current_index}
        to_delete = (set(report.bad_records) | extra) - deleted
        if to_delete:
            tub.delete_records(sorted(to_delete))
        tub.close()
        _replace_unparsable(tub, report.unparsable)
        _rewrite_catalog_manifests(Tub(path, read_only=True))
        report.repaired = True
    return report


def _catalog_manifests(tub: Tub) -> list[tuple[Path, int, list[int], dict[str, Any] | None]]:
    """(catalog, its start index, its line lengths, its .catalog_manifest or None) per catalog."""
    return [(p, i * tub.max_len, scan_catalog(p).line_lengths, read_catalog_manifest(p))
            for i, p in enumerate(tub.catalog_paths) if p.exists()]


def _catalog_manifest_problems(tub: Tub) -> list[str]:
    out = []
    for catalog, start, lengths, meta in _catalog_manifests(tub):
        name = catalog_manifest_name(catalog.name)
        if meta is None:
            gone = not catalog.with_name(name).exists()
            out.append(f"{name} is {'missing' if gone else 'unreadable'} (DonkeyCar cannot open the tub)")
        elif meta.get("line_lengths") != lengths:
            out.append(f"{name}: line lengths do not match {catalog.name}")
        elif meta.get("start_index") != start:
            out.append(f"{name}: start_index {meta.get('start_index')!r}, {catalog.name} starts at {start}")
    return out


def _rewrite_catalog_manifests(tub: Tub) -> None:
    for catalog, start, lengths, meta in _catalog_manifests(tub):
        if meta is None or meta.get("line_lengths") != lengths or meta.get("start_index") != start:
            created = (meta or {}).get("created_at")
            if not isinstance(created, int | float):
                created = catalog.stat().st_mtime
            write_catalog_manifest(catalog, start, lengths, created, durable=True)


def _replace_unparsable(tub: Tub, unparsable: list[tuple[str, int]]) -> None:
    """Replace each unparsable line (damaged in its middle) by a bare record of its index, which
    repair has marked deleted: DonkeyCar, which parses every line, can read the tub again, and the
    next check finds nothing left to repair."""
    by_catalog: dict[str, list[int]] = {}
    for name, index in unparsable:
        by_catalog.setdefault(name, []).append(index)
    for catalog in tub.catalog_paths:
        indexes = by_catalog.get(catalog.name)
        if not indexes:
            continue
        lines = list(scan_catalog(catalog).lines)
        bad = [i for i, line in enumerate(lines) if parse_line(line)[0] is None]
        for i, index in zip(bad, indexes, strict=False):
            lines[i] = dumps_record({INDEX: index}).encode()
        atomic_write(catalog, b"".join(line + b"\n" for line in lines))
        logger.info("%s: %d damaged line(s) replaced by deleted records %s", catalog, len(bad), indexes)


def _torn(catalog: Path) -> int:
    try:
        data = catalog.read_bytes()
    except OSError:
        return 0
    return len(data) - (data.rfind(b"\n") + 1)


def read_image_crcs(tub: Path) -> dict[int, tuple[Any, dict[str, int]]]:
    """The image checksums the writer recorded (IMAGE_CRCS): index -> (session id, key -> CRC-32).
    Unreadable lines (a torn last one) are skipped; a record without a line is not verified."""
    out: dict[int, tuple[Any, dict[str, int]]] = {}
    try:
        data = (tub / IMAGE_CRCS).read_bytes()
    except OSError:
        return out
    for line in data.splitlines():
        try:
            entry = json.loads(line)
            out[int(entry[INDEX])] = (entry.get(SESSION), {str(k): int(v) for k, v in entry["crc32"].items()})
        except (ValueError, KeyError, TypeError, AttributeError):
            continue
    return out


def _image_problem(images: Path, rec: dict, keys: list[str], decode: bool,
                   crcs: dict[str, int] | None = None) -> str | None:
    for key in keys:
        name = rec.get(key)
        if not isinstance(name, str):
            return f"no image for {key}"
        path = images / name
        try:
            data = path.read_bytes()
        except OSError:
            return f"{path.name}: missing"
        why = image_problem(data, name, decode)
        if why:
            return f"{path.name}: {why}"
        if crcs is not None and key in crcs and zlib.crc32(data) != crcs[key]:
            return f"{path.name}: changed since it was recorded (its CRC-32 differs from {IMAGE_CRCS})"
    return None


def _progress(total: int, desc: str, enabled: bool) -> Any:
    """A tqdm bar (disabled: a no-op with the same methods)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="rec", disable=not enabled, leave=False)


