"""``vehicle tub check [--repair]``: find (and fix) everything that would hurt training."""

from __future__ import annotations

import logging
import os
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parts.tub.codec import decode_image, looks_whole_jpeg
from parts.tub.format import IMAGE_TYPES
from parts.tub.tub import Tub

logger = logging.getLogger(__name__)


@dataclass
class CheckReport:
    """Findings of a tub check. ``bad_records`` maps index -> reason."""

    path: Path
    records: int = 0
    recovered: list[str] = field(default_factory=list)     # manifest/catalog problems (fixed on repair)
    torn_bytes: int = 0                                     # bytes of torn last lines (cut on repair)
    unparsable: list[tuple[str, int]] = field(default_factory=list)  # (catalog, position)
    bad_records: dict[int, str] = field(default_factory=dict)
    duplicate_indexes: list[int] = field(default_factory=list)
    orphan_images: int = 0
    repaired: bool = False

    @property
    def ok(self) -> bool:
        return not (self.recovered or self.torn_bytes or self.unparsable or self.bad_records
                    or self.duplicate_indexes)

    def lines(self) -> list[str]:
        out = [f"{self.path}: {self.records} records checked"]
        out += [f"  manifest: {p}" for p in self.recovered]
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
        elif self.repaired:
            out.append("  repaired: manifest rewritten, torn lines cut, bad records marked deleted")
        else:
            out.append("  run with --repair to fix (bad records are soft-deleted, restorable)")
        return out


def check_tub(path: str | os.PathLike[str], repair: bool = False, decode: bool = True,
              progress: bool = False) -> CheckReport:
    """Check one tub: manifest vs catalogs, torn and unparsable lines, duplicate indexes, and every
    image of every live record (exists, non-empty, whole JPEG, decodes when ``decode``).

    With ``repair`` the tub is opened for writing (which rewrites the manifest and cuts torn
    lines) and bad records are soft-deleted.
    """
    ro = Tub(path, read_only=True)
    report = CheckReport(ro.path, recovered=list(ro.problems))
    report.torn_bytes = sum(_torn(p) for p in ro.catalog_paths)
    if repair:
        for catalog in ro.catalog_paths[:-1]:  # the last one is cut by the writable open
            if _torn(catalog):
                with open(catalog, "r+b") as f:
                    f.truncate(catalog.stat().st_size - _torn(catalog))
        ro.close()
    tub = Tub(path) if repair else ro
    image_keys = [k for k, t in zip(tub.inputs, tub.types, strict=True) if t in IMAGE_TYPES]
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
        why = _image_problem(tub.images_path, rec, image_keys, decode)
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
        report.repaired = True
    return report


def _torn(catalog: Path) -> int:
    try:
        data = catalog.read_bytes()
    except OSError:
        return 0
    return len(data) - (data.rfind(b"\n") + 1)


def _image_problem(images: Path, rec: dict, keys: list[str], decode: bool) -> str | None:
    for key in keys:
        name = rec.get(key)
        if not isinstance(name, str):
            return f"no image for {key}"
        path = images / name
        try:
            data = path.read_bytes()
        except OSError:
            return f"{path.name}: missing"
        if not data:
            return f"{path.name}: empty (0 bytes)"
        if name.endswith(".jpg") and not looks_whole_jpeg(data):
            return f"{path.name}: truncated JPEG"
        if decode and decode_image(data) is None:
            return f"{path.name}: does not decode"
    return None


def _progress(total: int, desc: str, enabled: bool) -> Any:
    """A tqdm bar (disabled: a no-op with the same methods)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="rec", disable=not enabled, leave=False)


