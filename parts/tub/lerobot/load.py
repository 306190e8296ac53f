"""Import a LeRobot dataset (codebase version v3.0) into a new tub.

>>> report = import_lerobot("datasets/mycar", "data/tub_back")

A dataset exported here carries meta/vehicle_rc.json, which names the tub field behind every
feature: the tub comes back with the same fields, types and values (camera frames within the
video's loss, see docs/data-format.md) and the same capture times. Any other v3.0 dataset is
mapped by convention: the first camera becomes ``cam/image_array`` (the others
``cam/image_array_<name>``), a 2-value ``action`` becomes ``user/angle`` and ``user/throttle``,
every other feature a field named after it ("." -> "/"), and the task text and episode index go
into ``lerobot/task`` and ``lerobot/episode_index``.

Rows are read in parquet batches and frames decoded in order, so memory stays bounded. The tub is
written by the crash-safe ``Tub`` in a hidden folder and renamed into place when complete.
"""

from __future__ import annotations

import json
import logging
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from parts.tub.codec import decode_image, looks_whole_jpeg
from parts.tub.format import building_folder, check_new_folder
from parts.tub.lerobot.columns import CAMERA_PREFIX, Column, Part, column_from_spec
from parts.tub.lerobot.format import (
    DEFAULT_FEATURES,
    EPISODES_DIR,
    SIDECAR_PATH,
    VIDEO_PATH,
    LeRobotFormatError,
    chunk_file_path,
    not_parquet,
    open_parquet,
    parquet_files,
    pyarrow,
    read_info,
    read_tasks,
)
from parts.tub.lerobot.video import FrameReader
from parts.tub.tub import Tub

logger = logging.getLogger(__name__)

BATCH_ROWS = 512        # data rows read at a time
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
EPISODE_GAP_S = 1.0     # datasets without capture times: their episodes are laid 1 s apart


@dataclass
class ImportReport:
    """What ``import_lerobot`` did."""

    source: Path
    tub: Path
    records: int = 0
    episodes: int = 0
    exact: bool = False            # the dataset came from our export (fields restored exactly)
    fields: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def lines(self) -> list[str]:
        how = "fields as exported" if self.exact else "fields mapped by convention"
        return [f"{self.tub}: imported {self.records} records of {self.episodes} episodes from {self.source} "
                f"({how}) in {self.seconds:.1f} s", "fields: " + ", ".join(self.fields)]


@dataclass
class _Mapping:
    """How rows become records."""

    columns: list[Column]
    inputs: list[str]
    types: list[str]
    metadata: dict[str, Any]
    capture: str | None = None     # feature holding capture seconds since the episode start
    task_key: str | None = None    # generic: field for the task text
    episode_key: str | None = None  # generic: field for the episode index
    tub_names: list[str] = field(default_factory=list)              # ours: the exported tubs, in order
    renames: list[dict[str, str]] = field(default_factory=list)     # ... the key each used for a field

    def renames_of(self, ep: dict[str, Any]) -> dict[str, str] | None:
        """The renames for the records of an episode: by its tub/index (by tub/name in datasets
        exported before tub/index was written, where the name is unique)."""
        index = ep.get("tub/index")
        if not isinstance(index, int):
            name = ep.get("tub/name")
            index = self.tub_names.index(name) if self.tub_names.count(name) == 1 else None
        return self.renames[index] if index is not None and 0 <= index < len(self.renames) else None


def _own_mapping(sidecar: dict[str, Any], features: dict[str, dict[str, Any]], source: Path) -> _Mapping:
    """The mapping saved by our export."""
    try:
        columns = [column_from_spec(spec, features) for spec in sidecar["columns"]]
        inputs: list[str] = []
        types: list[str] = []
        for tub in sidecar["tubs"]:
            for key, tp in zip(tub["inputs"], tub["types"], strict=True):
                if key not in inputs:
                    inputs.append(key)
                    types.append(tp)
        metadata = dict(sidecar["tubs"][0].get("metadata") or {}) if sidecar["tubs"] else {}
        tub_names = [str(tub.get("name")) for tub in sidecar["tubs"]]
        renames = [{k: v for col in columns for k, v in col.renames(list(tub["inputs"])).items()}
                   for tub in sidecar["tubs"]]
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise LeRobotFormatError(f"{source / SIDECAR_PATH} does not fit meta/info.json ({exc!r}); "
                                 "remove it to import the dataset by convention") from exc
    # fields the exported records held beyond the manifests' inputs (edited tubs)
    for col in columns:
        for key, tp in col.fields():
            if key not in inputs:
                inputs.append(key)
                types.append(tp)
    capture = sidecar.get("capture_feature")
    return _Mapping(columns, inputs, types, metadata, capture if capture in features else None,
                    tub_names=tub_names, renames=renames)


def _generic_mapping(features: dict[str, dict[str, Any]]) -> _Mapping:
    """A mapping by convention for datasets made elsewhere."""
    columns: list[Column] = []
    cameras = [k for k, f in features.items() if f.get("dtype") in ("video", "image")]
    for i, name in enumerate(cameras):
        suffix = name.removeprefix(CAMERA_PREFIX).replace(".", "_")
        key = "cam/image_array" if i == 0 else f"cam/image_array_{suffix}"
        columns.append(Column(name, "camera", features[name], key=key, type="image_array"))
    for name, ft in features.items():
        if name in DEFAULT_FEATURES or name in cameras:
            continue
        dtype, shape = ft.get("dtype"), list(ft.get("shape") or [1])
        if dtype == "string":
            columns.append(Column(name, "text", ft, key=name.replace(".", "/"), type="str"))
        elif name == "action" and shape == [2]:
            columns.append(Column(name, "vector", ft, parts=[Part("user/angle", "float"),
                                                            Part("user/throttle", "float")]))
        elif shape == [1]:
            tp = "int" if dtype in ("int64", "int32", "int16", "int8", "uint8") else \
                "boolean" if dtype == "bool" else "float"
            columns.append(Column(name, "vector", ft, parts=[Part(name.replace(".", "/"), tp)]))
        elif len(shape) == 1:
            items = "int" if str(dtype).startswith(("int", "uint")) else "float"
            columns.append(Column(name, "vector", ft, parts=[Part(name.replace(".", "/"), "vector", shape[0], items)]))
        else:
            logger.warning("feature %s of shape %s is not imported (tubs hold scalars and vectors)", name, shape)
    inputs: list[str] = []
    types: list[str] = []
    for col in columns:
        for key, tp in col.fields():
            inputs.append(key)
            types.append(tp)
    inputs += ["lerobot/task", "lerobot/episode_index"]
    types += ["str", "int"]
    return _Mapping(columns, inputs, types, {}, None, "lerobot/task", "lerobot/episode_index")


def _need_columns(path: Path, names: list[str], needed: list[str], why: str) -> None:
    for name in needed:
        if name not in names:
            raise LeRobotFormatError(f"{path}: no column {name} ({why}); the dataset is incomplete")


def _episodes(root: Path, videos: list[str]) -> dict[int, dict[str, Any]]:
    """episode_index -> the episode's offsets (the stats columns are not read); every episode must
    say where the frames of each video feature in ``videos`` are."""
    pa = pyarrow()
    out: dict[int, dict[str, Any]] = {}
    files = parquet_files(root / EPISODES_DIR)
    if not files:
        raise LeRobotFormatError(f"{root} has no {EPISODES_DIR}/chunk-*/file-*.parquet: not a complete v3.0 dataset")
    located = [f"videos/{v}/{k}" for v in videos for k in ("chunk_index", "file_index", "from_timestamp")]
    for path in files:
        pf = open_parquet(path)
        names = pf.schema_arrow.names
        _need_columns(path, names, ["episode_index"], "the episode of each row")
        _need_columns(path, names, located, "where the episode's frames are in the videos")
        try:
            rows = pf.read(columns=[c for c in names if not c.startswith("stats/")]).to_pylist()
        except (pa.ArrowException, OSError) as exc:
            raise not_parquet(path, exc) from exc
        for row in rows:
            index = row["episode_index"]
            if not isinstance(index, int):
                raise LeRobotFormatError(f"{path}: an episode has episode_index {index!r}, not a whole number")
            for name in located:
                if not isinstance(row[name], int | float) or isinstance(row[name], bool):
                    raise LeRobotFormatError(f"{path}: episode {index} has no {name} (found {row[name]!r})")
            out[index] = row
    return out


def _rows(path: Path, needed: list[str]) -> Iterator[dict[str, Any]]:
    """The rows of a data file, a batch at a time; LeRobotFormatError naming the file when it is
    not parquet or lacks a column the import reads."""
    pa = pyarrow()
    pf = open_parquet(path)
    _need_columns(path, pf.schema_arrow.names, needed, "a feature of meta/info.json")
    try:
        for batch in pf.iter_batches(batch_size=BATCH_ROWS):
            yield from batch.to_pylist()
    except (pa.ArrowException, OSError) as exc:
        raise not_parquet(path, exc) from exc


def _image_value(value: Any, col: Column) -> Any:
    """An image column's parquet value -> what the tub stores: the file's bytes when they are what
    the tub keeps (JPEG for image_array, PNG for gray16_array), else the decoded frame."""
    data = value.get("bytes") if isinstance(value, dict) else value
    if not data:
        raise LeRobotFormatError(f"feature {col.name}: a row has no image bytes")
    if col.type == "gray16_array" and bytes(data[:8]) == PNG_SIGNATURE or \
            col.type == "image_array" and looks_whole_jpeg(data):
        return bytes(data)
    img = decode_image(bytes(data))
    if img is None:
        raise LeRobotFormatError(f"feature {col.name}: an image does not decode")
    return img


def import_lerobot(source: str | os.PathLike[str], tub_path: str | os.PathLike[str], *, jpeg_quality: int = 95,
                   progress: bool = False) -> ImportReport:
    """Read the LeRobot v3.0 dataset ``source`` into the new tub ``tub_path``.

    ``jpeg_quality``: for frames decoded from videos (or non-JPEG images), encoded again as the
    tub's JPEGs (JPEG images in the data files are copied as they are).

    Raises:
        LeRobotFormatError: ``source`` is not a v3.0 dataset or its files do not agree.
        TubError: ``tub_path`` exists and is not empty.
    """
    from tqdm import tqdm

    t0 = time.perf_counter()
    root = Path(os.path.expanduser(os.fspath(source))).absolute()
    out = Path(os.path.expanduser(os.fspath(tub_path))).absolute()
    info = read_info(root)
    check_new_folder(out)
    if not 1 <= int(jpeg_quality) <= 100:
        raise ValueError(f"jpeg_quality must be within 1..100, got {jpeg_quality!r}")
    features: dict[str, dict[str, Any]] = info["features"]
    fps = float(info["fps"])
    sidecar = _read_sidecar(root)
    own = sidecar is not None and sidecar.get("format") == 1
    mapping = _own_mapping(sidecar, features, root) if own else _generic_mapping(features)  # type: ignore[arg-type]
    videos = [c.name for c in mapping.columns if c.kind == "camera" and c.dtype == "video"]
    episodes = _episodes(root, videos)
    tasks = read_tasks(root)
    data_files = parquet_files(root / "data")
    if not data_files:
        raise LeRobotFormatError(f"{root} has no data/chunk-*/file-*.parquet: not a complete v3.0 dataset")
    needed = [c.name for c in mapping.columns if c.dtype != "video"] + ["timestamp", "episode_index"] \
        + (["task_index"] if mapping.task_key else [])
    video_path = info.get("video_path") or VIDEO_PATH
    readers = {name: FrameReader(tolerance=0.49 / fps) for name in videos}
    report = ImportReport(root, out, exact=own, fields=list(mapping.inputs))
    metadata = {**mapping.metadata, "source": "lerobot", "lerobot_dataset": root.name}
    base_ms = int(time.time() * 1000)
    offsets: dict[int, float] = {}  # generic: start of each episode on one time line, seconds
    next_start = 0.0
    seen_episodes: set[int] = set()
    try:
        with building_folder(out) as tmp, \
                Tub(tmp, mapping.inputs, mapping.types, metadata, fsync_records=200, fsync_ms=5000,
                    jpeg_quality=int(jpeg_quality)) as tub, \
                tqdm(total=int(info.get("total_frames") or 0), desc="import", unit="rec", disable=not progress,
                     leave=False) as bar:
            for path in data_files:
                for row in _rows(path, needed):
                    ep_index = int(row["episode_index"])
                    ep = episodes.get(ep_index)
                    if ep is None:
                        raise LeRobotFormatError(f"{path}: row {row.get('index')} is in episode {ep_index}, "
                                                 f"which {EPISODES_DIR} does not list")
                    if ep_index not in seen_episodes:
                        seen_episodes.add(ep_index)
                        offsets[ep_index] = next_start
                        next_start += int(ep.get("length") or 0) / fps + EPISODE_GAP_S
                    renames = mapping.renames_of(ep)
                    record: dict[str, Any] = {}
                    for col in mapping.columns:
                        if col.kind == "camera":
                            if col.dtype == "video":
                                v = f"videos/{col.name}/"
                                file = root / chunk_file_path(video_path, int(ep[v + "chunk_index"]),
                                                              int(ep[v + "file_index"]), video_key=col.name)
                                t = float(ep[v + "from_timestamp"]) + float(row["timestamp"])
                                record[col.key] = readers[col.name].frame(file, t)
                            else:
                                record[col.key] = _image_value(row[col.name], col)
                        else:
                            col.restore(row[col.name], record, renames)
                    if mapping.task_key:
                        record[mapping.task_key] = tasks.get(int(row["task_index"]), "")
                        record[mapping.episode_key] = ep_index  # type: ignore[index]
                    tub.write_record(record, timestamp_ms=_capture_ms(row, ep, mapping, base_ms, offsets[ep_index]))
                    report.records += 1
                    bar.update(1)
            if not report.records:
                raise LeRobotFormatError(f"{root}: its data files hold no frames; nothing to import")
    finally:
        for reader in readers.values():
            reader.close()
    report.episodes = len(seen_episodes)
    report.seconds = time.perf_counter() - t0
    return report


def _read_sidecar(root: Path) -> dict[str, Any] | None:
    """meta/vehicle_rc.json, written by our export (None when the dataset has none)."""
    path = root / SIDECAR_PATH
    if not path.is_file():
        return None
    try:
        sidecar = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LeRobotFormatError(f"{path} is not valid JSON ({exc}); restore it, or remove it to import the "
                                 "dataset by convention") from exc
    if not isinstance(sidecar, dict):
        raise LeRobotFormatError(f"{path} holds no JSON object; restore it, or remove it to import the dataset "
                                 "by convention")
    return sidecar


def _capture_ms(row: dict[str, Any], ep: dict[str, Any], mapping: _Mapping, base_ms: int, offset: float) -> int:
    """The record's _timestamp_ms: the exported capture time where the dataset has one, else the
    import time plus the frame's time on a line where episodes follow each other."""
    start = ep.get("tub/capture_start_ms")
    if mapping.capture and isinstance(start, int) and start >= 0:
        rel = row.get(mapping.capture)
        if isinstance(rel, float) and not math.isnan(rel):
            return start + int(round(rel * 1000.0))
    return base_ms + int(round((offset + float(np.float32(row["timestamp"]))) * 1000.0))
