"""Fixtures of the tub tests: tubs built by hand from the documented DonkeyCar tub v2 format."""

from __future__ import annotations

import io
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

DONKEY_INPUTS = ["cam/image_array", "user/angle", "user/throttle", "user/mode"]
DONKEY_TYPES = ["image_array", "float", "float", "str"]


def gradient_image(seed: int, h: int = 120, w: int = 160) -> np.ndarray:
    """A camera-like frame: colour gradients plus noise, different for each seed."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w]
    base = np.stack([x * 255 // w, y * 255 // h, ((x + y + seed * 7) % (w + h)) * 255 // (w + h)], -1)
    return np.clip(base + rng.integers(-15, 16, base.shape), 0, 255).astype(np.uint8)


def jpeg_bytes(img: np.ndarray) -> bytes:
    """Encode like DonkeyCar does (PIL, default quality)."""
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="JPEG")
    return buf.getvalue()


def build_donkey_tub(path: Path, n: int, *, max_len: int = 3, deleted: tuple[int, ...] = (),
                     angle_key: str = "user/angle", sessions: tuple[str, ...] = ("26-11-20_0",),
                     metadata: dict[str, Any] | None = None, image_size: tuple[int, int] = (120, 160),
                     ) -> list[dict[str, Any]]:
    """Write a tub the way DonkeyCar 5.3 does (docs: shared/reference/donkeycar.md section 2).

    Returns the records as written. Records are split over catalogs of ``max_len`` lines; the
    session of record i is ``sessions[i * len(sessions) // n]``.
    """
    inputs = ["cam/image_array", angle_key, "user/throttle", "user/mode"]
    path.mkdir(parents=True)
    (path / "images").mkdir()
    records = []
    catalogs: dict[int, list[str]] = {}
    for i in range(n):
        name = f"{i}_cam_image_array_.jpg"
        (path / "images" / name).write_bytes(jpeg_bytes(gradient_image(i, *image_size)))
        rec = {"cam/image_array": name, angle_key: round(-1 + 2 * i / max(1, n - 1), 6),
               "user/throttle": 0.25 + i / 100, "user/mode": "user",
               "_timestamp_ms": 1_700_000_000_000 + 50 * i, "_index": i,
               "_session_id": sessions[i * len(sessions) // n]}
        records.append(rec)
        catalogs.setdefault(i // max_len, []).append(json.dumps(rec, allow_nan=False, sort_keys=True) + "\n")
    if not catalogs:
        catalogs[0] = []
    for k, lines in catalogs.items():
        (path / f"catalog_{k}.catalog").write_text("".join(lines))
        meta = {"created_at": time.time(), "line_lengths": [len(ln) for ln in lines],
                "path": f"catalog_{k}.catalog_manifest", "start_index": k * max_len}
        (path / f"catalog_{k}.catalog_manifest").write_text(json.dumps(meta, sort_keys=True) + "\n")
    ids = list(dict.fromkeys(sessions))
    last = ids[-1]
    manifest = [inputs, DONKEY_TYPES, metadata or {},
                {"created_at": 1_700_000_000.0,
                 "sessions": {"all_full_ids": ids, "last_id": int(last.rsplit("_", 1)[1]),
                              "last_full_id": last}},
                {"paths": [f"catalog_{k}.catalog" for k in sorted(catalogs)], "current_index": n,
                 "max_len": max_len, "deleted_indexes": sorted(deleted)}]
    (path / "manifest.json").write_text("".join(json.dumps(x) + "\n" for x in manifest))
    return records


@pytest.fixture
def donkey_tub(tmp_path: Path) -> Callable[..., tuple[Path, list[dict[str, Any]]]]:
    """Factory: ``donkey_tub(n, name="tub", **kw) -> (path, records)``."""

    def make(n: int = 8, name: str = "tub", **kw: Any) -> tuple[Path, list[dict[str, Any]]]:
        path = tmp_path / name
        return path, build_donkey_tub(path, n, **kw)

    return make


@pytest.fixture
def jpeg() -> Callable[[np.ndarray], bytes]:
    """The encoder DonkeyCar uses, as a fixture (test folders share the module name conftest)."""
    return jpeg_bytes


@pytest.fixture
def image() -> Callable[[int], np.ndarray]:
    return gradient_image


def catalog_lines(tub: Path) -> list[dict[str, Any]]:
    """Every catalog line of a tub, parsed, in catalog order (fails on an unparsable line)."""
    out = []
    names = sorted(tub.glob("catalog_*.catalog"), key=lambda p: int(p.stem.split("_")[1]))
    for p in names:
        for line in p.read_text().splitlines():
            out.append(json.loads(line))
    return out


@pytest.fixture
def read_lines() -> Callable[[Path], list[dict[str, Any]]]:
    return catalog_lines
