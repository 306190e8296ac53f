"""What an export file carries, readable without torch: suffixes, metadata keys, the source's hash.

Every export (:mod:`training.export`) stores the source model file's metadata as JSON under
:data:`META_KEY` and the SHA-256 of the source ``.pt`` under :data:`SOURCE_KEY`, so an export is
self-contained and a stale one (the .pt was retrained since) is detected by
:func:`export_matches`. The runtimes (:mod:`parts.pilots.backends`) need only this module to run an
ONNX export, so a car driving an ``.onnx`` or ``.int8.onnx`` file needs onnxruntime, not torch.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any, Literal

ExportFormat = Literal["onnx", "onnx-int8", "torchscript"]
SUFFIXES: dict[str, str] = {"onnx": ".onnx", "onnx-int8": ".int8.onnx", "torchscript": ".ts"}
META_KEY = "vehicle_meta"  # JSON of the source model file's metadata
SOURCE_KEY = "source_sha256"  # SHA-256 of the source model file
QUANT_KEY = "quantization"  # JSON of an int8 export: {"method", "calibration_frames", "calibration_tubs"}


def file_sha256(path: str | os.PathLike[str]) -> str:
    """Hex SHA-256 of a file (1 MiB chunks)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def export_matches(source: str | os.PathLike[str], export_sha256: str | None) -> bool:
    """Whether an export made from a file with hash ``export_sha256`` is of ``source`` as it is now."""
    return bool(export_sha256) and Path(source).is_file() and file_sha256(source) == export_sha256


def quant_record(props: dict[str, str]) -> dict[str, Any] | None:
    """The ``quantization`` record of an export's metadata, None for a float export."""
    raw = props.get(QUANT_KEY)
    return json.loads(raw) if raw else None
