"""Export tubs to a LeRobot dataset (codebase version v3.0), streaming, in bounded memory.

>>> report = export_lerobot(["data/tub_1", "data/tub_2"], "datasets/mycar")

Two passes over the records: the first reads the catalogs (fields, episodes, loop rate, see
``survey``), the second decodes the frames (threads), encodes the videos (PyAV), writes the
data rows and episode metadata in parquet files (pyarrow) and accumulates the statistics, one
episode at a time, never holding more than a few thousand rows. The dataset is written into a
hidden folder beside ``out`` and renamed to ``out`` once complete: an interrupted export leaves
no half dataset. The mapping from tub fields to features is in docs/data-format.md.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from parts.tub.errors import TubError
from parts.tub.format import IMAGE_TYPES, SESSION, TIMESTAMP, building_folder, check_new_folder
from parts.tub.lerobot import stats as st
from parts.tub.lerobot.columns import CAMERA_PREFIX, Column, Part, camera_name
from parts.tub.lerobot.format import (
    CAMERA_NAMES,
    CHUNKS_SIZE,
    CODEBASE_VERSION,
    DATA_FILES_SIZE_IN_MB,
    DATA_PATH,
    DEFAULT_FEATURES,
    EPISODES_PATH,
    INFO_PATH,
    SIDECAR_PATH,
    STATS_PATH,
    TASKS_PATH,
    VIDEO_FILES_SIZE_IN_MB,
    LeRobotFormatError,
    chunk_file_path,
    data_schema,
    info_dict,
    next_file,
    pyarrow,
    size_mb,
    tasks_table,
    write_json,
)
from parts.tub.lerobot.survey import (
    DEFAULT_FPS,
    LABEL_KEY,
    ONE_HOT_KEY,
    THROTTLE_KEY,
    TRACK_KEY,
    EpisodeSplitter,
    FieldSurvey,
    Survey,
    exported_records,
    short,
    survey_tubs,
)
from parts.tub.lerobot.video import DEFAULT_CODEC, DEFAULT_CRF, VideoFiles, check_codec
from parts.tub.reader import ANGLE_KEYS, SPEED_KEYS, TubRecord, iter_frames

logger = logging.getLogger(__name__)

DEFAULT_TASK = "drive along the track"
ROBOT_TYPE = "donkeycar"
CAPTURE_FEATURE = "capture_timestamp"  # capture time of the frame, seconds since the episode's first
ROWS_PER_GROUP = 2000                  # data rows buffered before a parquet row group is written
BYTES_PER_GROUP = 64 << 20             # ... or this many image bytes (--images)
EPISODES_PER_GROUP = 64                # episode rows buffered before they are written
# ``timestamp`` is float32 (LeRobot's schema): 24 bits, so past 2048 s its step is 2.4e-4 s and
# frame_index / fps can be stored 1.2e-4 s off, beyond the 1e-4 s within which LeRobot's video
# reader accepts a frame. Below 2048 s the error is at most 6.1e-5 s. Longer sessions are split.
MAX_EPISODE_S = 2048
DEFAULT_MAX_EPISODE_S = 1800           # 30 min: a margin below MAX_EPISODE_S
_RESERVED = ("observation", "action", "next.", "task", "tub.", *DEFAULT_FEATURES, CAPTURE_FEATURE)


@dataclass
class ExportReport:
    """What ``export_lerobot`` wrote."""

    out: Path
    frames: int = 0
    episodes: int = 0
    fps: int = 0
    fps_measured: bool = True
    video: bool = True
    features: list[str] = field(default_factory=list)
    tasks: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)  # "tub: record N: reason"
    seconds: float = 0.0

    def lines(self) -> list[str]:
        rate = f"{self.frames / self.seconds:.0f} records/s" if self.seconds > 0 else ""
        out = [f"{self.out}: {self.frames} frames in {self.episodes} episodes, {len(self.tasks)} tasks, "
               f"{self.fps} fps ({'measured' if self.fps_measured else 'given'}), "
               f"{'video' if self.video else 'images'}; {self.seconds:.1f} s, {rate}",
               "features: " + ", ".join(self.features)]
        if self.skipped:
            out.append(f"skipped {len(self.skipped)} records, first: {self.skipped[0]}")
        return out


# -- the mapping ---------------------------------------------------------------------------------------

def _safe_name(key: str, taken: set[str]) -> str:
    """A feature name for a carried tub field: its key with "/" -> "." (LeRobot forbids "/"),
    prefixed with "tub." where it would look like one of LeRobot's own features."""
    name = key.replace("/", ".")
    if name.startswith(_RESERVED) or name in taken:
        name = "tub." + name
    while name in taken:
        name += "_"
    taken.add(name)
    return name


def _numeric(info: FieldSurvey) -> bool:
    return info.kinds <= {"int", "float", "bool"}


def plan_columns(survey: Survey, *, video: bool) -> list[Column]:
    """The features of the dataset and the tub fields behind each (see docs/data-format.md)."""
    fields = survey.fields
    columns: list[Column] = []
    used: set[str] = set()
    for key in survey.image_keys():
        shape = survey.image_shapes.get(key)
        if shape is None:
            continue  # no exported record holds this image
        gray16 = fields[key].type == "gray16_array"
        dtype = "video" if video and not gray16 else "image"
        dims = [int(shape[0]), int(shape[1]), 1 if len(shape) == 2 else int(shape[2])]
        columns.append(Column(CAMERA_PREFIX + camera_name(key), "camera",
                              {"dtype": dtype, "shape": dims, "names": list(CAMERA_NAMES)},
                              key=key, type=fields[key].type))
        used.add(key)

    state: list[Part] = []
    names: list[str] = []
    speed = next((k for k in SPEED_KEYS if k in fields and fields[k].present and _numeric(fields[k])), None)
    if speed:
        state.append(Part(speed, fields[speed].type))
        names.append("speed")
    hot = fields.get(ONE_HOT_KEY)
    if hot and hot.present and hot.numeric_items and hot.length and hot.length > 0:
        state.append(Part(ONE_HOT_KEY, hot.type, hot.length, "int" if hot.int_items else "float"))
        names += [f"behavior.{survey.behaviours.get(i, i)}" for i in range(hot.length)]
    if state:
        columns.append(Column("observation.state", "vector",
                              {"dtype": "float32", "shape": [len(names)], "names": names}, parts=state))
        used.update(p.key for p in state)

    angle = next((k for k in ANGLE_KEYS if k in fields), ANGLE_KEYS[0])
    columns.append(Column("action", "vector", {"dtype": "float32", "shape": [2], "names": ["angle", "throttle"]},
                          parts=[Part(angle, "float", aliases=tuple(k for k in ANGLE_KEYS if k != angle)),
                                 Part(THROTTLE_KEY, "float")]))
    used.update((*ANGLE_KEYS, THROTTLE_KEY))

    taken = {c.name for c in columns}
    for key in sorted(fields):
        info = fields[key]
        if key in used or not info.present or info.type in IMAGE_TYPES:
            continue
        columns.append(_carried(key, info, _safe_name(key, taken), complete=info.present == survey.records))
    return columns


def _carried(key: str, info: FieldSurvey, name: str, *, complete: bool) -> Column:
    """The column of a field kept as it is (a missing value: NaN in float columns, "" in text)."""
    scalar = {"dtype": "float64", "shape": [1], "names": None}
    if info.type in ("float", "int", "boolean") and _numeric(info):
        if complete and info.type == "int" and info.kinds <= {"int"}:
            scalar["dtype"] = "int64"
        elif complete and info.type == "boolean" and info.kinds <= {"bool"}:
            scalar["dtype"] = "bool"
        return Column(name, "vector", scalar, parts=[Part(key, info.type)])
    if info.type in ("nparray", "list", "vector") and info.kinds <= {"list"} and info.numeric_items \
            and info.length is not None and info.length > 0:
        dtype = "int64" if complete and info.int_items else "float64"
        return Column(name, "vector", {"dtype": dtype, "shape": [info.length], "names": None},
                      parts=[Part(key, info.type, info.length, "int" if info.int_items else "float")])
    plain = info.type == "str" and info.kinds <= {"str"}
    return Column(name, "text", {"dtype": "string", "shape": [1], "names": None}, key=key, type=info.type,
                  encoding="plain" if plain else "json")


def task_source(survey: Survey, default: str) -> dict[str, Any]:
    """Where each frame's task text comes from: the behaviour label, else the simulator track,
    else ``default``."""
    if LABEL_KEY in survey.fields and survey.fields[LABEL_KEY].present:
        return {"key": LABEL_KEY, "default": default}
    if TRACK_KEY in survey.fields and survey.fields[TRACK_KEY].present:
        return {"key": TRACK_KEY, "format": "track {}", "default": default}
    return {"default": default}


def _task_text(source: dict[str, Any], data: dict[str, Any]) -> str:
    value = data.get(source["key"]) if "key" in source else None
    if value is None or value == "":
        return source["default"]
    return source.get("format", "{}").format(value)


# -- writing ----------------------------------------------------------------------------------------

class _ParquetFiles:
    """Parquet files of one kind (data or episodes), rolled over at ``max_mb``."""

    def __init__(self, root: Path, template: str, max_mb: float, chunks_size: int) -> None:
        self.root = root
        self.template = template
        self.max_mb = max_mb
        self.chunks_size = chunks_size
        self.chunk, self.file = 0, 0
        self._writer: Any = None
        self._path: Path | None = None
        self.schema: Any = None

    def roll_if_full(self) -> None:
        """Close the current file if it reached the size limit (call at an episode boundary)."""
        if self._writer is not None and size_mb(self._path) >= self.max_mb:  # type: ignore[arg-type]
            self.close()
            self.chunk, self.file = next_file(self.chunk, self.file, self.chunks_size)

    def write(self, table: Any) -> None:
        pa = pyarrow()
        if self._writer is None:
            self._path = self.root / chunk_file_path(self.template, self.chunk, self.file)
            self._path.parent.mkdir(parents=True, exist_ok=True)
            if self.schema is None:
                self.schema = table.schema
            self._writer = pa.parquet.ParquetWriter(self._path, self.schema, compression="snappy",
                                                    use_dictionary=True)
        self._writer.write_table(table if table.schema.equals(self.schema) else table.cast(self.schema))

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None


class _Exporter:
    """The second pass: frames in, dataset files out."""

    def __init__(self, root: Path, survey: Survey, columns: list[Column], *, fps: int, codec: str, crf: int,
                 task: dict[str, Any], report: ExportReport, progress: bool) -> None:
        self.root = root
        self.survey = survey
        self.columns = columns
        self.fps = fps
        self.task = task
        self.report = report
        self.progress = progress
        self.cameras = [c for c in columns if c.kind == "camera"]
        self.features: dict[str, dict[str, Any]] = {c.name: dict(c.feature) for c in columns}
        self.features[CAPTURE_FEATURE] = {"dtype": "float64", "shape": [1], "names": None}
        self.features.update({k: dict(v) for k, v in DEFAULT_FEATURES.items()})
        # file limits read when the export starts (module constants: a test makes them tiny)
        self.limits = {"chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": DATA_FILES_SIZE_IN_MB,
                       "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB}
        self.tub_index = {t.path: i for i, t in enumerate(survey.tubs)}
        self.videos = {c.name: VideoFiles(root, c.name, fps, c.feature["shape"][1], c.feature["shape"][0],
                                          codec=codec, crf=crf, max_mb=VIDEO_FILES_SIZE_IN_MB,
                                          chunks_size=CHUNKS_SIZE)
                       for c in self.cameras if c.dtype == "video"}
        self.data = _ParquetFiles(root, DATA_PATH, DATA_FILES_SIZE_IN_MB, CHUNKS_SIZE)
        self.data.schema = data_schema(self.features)
        self.episode_files = _ParquetFiles(root, EPISODES_PATH, DATA_FILES_SIZE_IN_MB, CHUNKS_SIZE)
        self.tasks: dict[str, int] = {}
        self.global_stats = self._new_stats()
        self.episode_rows: list[dict[str, Any]] = []
        self.rows: dict[str, list[Any]] = {k: [] for k in self.features if self.features[k]["dtype"] != "video"}
        self.row_bytes = 0
        self.frames = 0
        self.episode: dict[str, Any] | None = None

    def _new_stats(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for name, ft in self.features.items():
            if ft["dtype"] in ("video", "image"):
                gray16 = any(c.name == name and c.type == "gray16_array" for c in self.cameras)
                out[name] = st.ImageStats(ft["shape"][2], 65536 if gray16 else 256)
            elif ft["dtype"] != "string":
                out[name] = st.RunningStats(int(ft["shape"][0]))
        return out

    # -- episodes --------------------------------------------------------------------------------------
    def _start_episode(self, rec: TubRecord) -> None:
        self.data.roll_if_full()
        ts = rec.data.get(TIMESTAMP)
        self.episode = {
            "index": self.report.episodes, "from": self.frames, "length": 0, "tasks": {},
            "start_ms": int(ts) if isinstance(ts, int | float) else None,
            "data": (self.data.chunk, self.data.file), "stats": self._new_stats(),
            "videos": {name: v.start_episode() for name, v in self.videos.items()},
            "tub": rec.tub, "session": rec.data.get(SESSION), "first": rec.index, "last": rec.index,
        }

    def _end_episode(self) -> None:
        ep = self.episode
        if ep is None:
            return
        self._flush_rows()
        row: dict[str, Any] = {"episode_index": ep["index"], "tasks": list(ep["tasks"]), "length": ep["length"],
                               "data/chunk_index": ep["data"][0], "data/file_index": ep["data"][1],
                               "dataset_from_index": ep["from"], "dataset_to_index": ep["from"] + ep["length"]}
        for name, video in self.videos.items():
            chunk, file, start = ep["videos"][name]
            row.update({f"videos/{name}/chunk_index": chunk, f"videos/{name}/file_index": file,
                        f"videos/{name}/from_timestamp": start,
                        f"videos/{name}/to_timestamp": video.end_episode()})
        episode_stats = {}
        for name, acc in ep["stats"].items():
            episode_stats[name] = st.to_json(acc.result())
            if isinstance(acc, st.ImageStats):
                self.global_stats[name].merge(acc)
        row.update(st.flatten(episode_stats))
        row.update({"meta/episodes/chunk_index": self.episode_files.chunk,
                    "meta/episodes/file_index": self.episode_files.file,
                    "tub/index": self.tub_index[ep["tub"]], "tub/name": ep["tub"].name,
                    "tub/session_id": str(ep["session"] or ""),
                    "tub/first_index": ep["first"], "tub/last_index": ep["last"],
                    "tub/capture_start_ms": ep["start_ms"] if ep["start_ms"] is not None else -1})
        self.episode_rows.append(row)
        self.report.episodes += 1
        self.episode = None
        if len(self.episode_rows) >= EPISODES_PER_GROUP:
            self._flush_episodes()

    def _flush_episodes(self) -> None:
        if not self.episode_rows:
            return
        pa = pyarrow()
        table = pa.Table.from_pylist(self.episode_rows)
        self.episode_rows = []
        self.episode_files.write(table)
        self.episode_files.roll_if_full()

    # -- frames ----------------------------------------------------------------------------------------
    def add(self, rec: TubRecord, images: list[np.ndarray]) -> None:
        ep = self.episode
        assert ep is not None
        frame_index = ep["length"]
        task = _task_text(self.task, rec.data)
        task_index = self.tasks.setdefault(task, len(self.tasks))
        ep["tasks"].setdefault(task, None)
        ts = rec.data.get(TIMESTAMP)
        capture = (float(ts) - ep["start_ms"]) / 1000.0 if isinstance(ts, int | float) and ep["start_ms"] is not None \
            else math.nan
        rows = self.rows
        for col in self.columns:
            if col.kind != "camera":
                rows[col.name].append(col.read(rec.data))
        for col, img in zip(self.cameras, images, strict=True):
            if tuple(img.shape[:2]) != tuple(col.feature["shape"][:2]):
                raise LeRobotFormatError(
                    f"{rec.tub}: record {rec.index}: {col.key} is {img.shape[1]}x{img.shape[0]}, the first frame "
                    f"{col.feature['shape'][1]}x{col.feature['shape'][0]}: a camera's frames must all have one "
                    "size; export these tubs separately")
            ep["stats"][col.name].update(img)
            if col.dtype == "video":
                self.videos[col.name].add(img)
            else:
                data = rec.image_bytes(col.key)
                self.row_bytes += len(data)
                suffix = os.path.splitext(rec[col.key])[1]  # not pathlib: a Path per record grows sys.intern's table
                rows[col.name].append({"bytes": data, "path": f"frame-{frame_index:06d}{suffix}"})
        rows[CAPTURE_FEATURE].append(capture)
        rows["timestamp"].append(frame_index / self.fps)
        rows["frame_index"].append(frame_index)
        rows["episode_index"].append(ep["index"])
        rows["index"].append(self.frames)
        rows["task_index"].append(task_index)
        ep["length"] += 1
        ep["last"] = rec.index
        self.frames += 1
        if len(rows["index"]) >= ROWS_PER_GROUP or self.row_bytes >= BYTES_PER_GROUP:
            self._flush_rows()

    def _flush_rows(self) -> None:
        """Write the buffered rows as a row group and add them to the statistics."""
        if not self.rows["index"]:
            return
        pa = pyarrow()
        ep_stats = self.episode["stats"] if self.episode else {}
        arrays = []
        for name in self.data.schema.names:
            values = self.rows[name]
            ft = self.features[name]
            if ft["dtype"] == "image":
                arrays.append(pa.array(values, self.data.schema.field(name).type))
                continue
            if ft["dtype"] == "string":
                arrays.append(pa.array(values, pa.string()))
                continue
            width = int(ft["shape"][0])
            typed = np.asarray(values, dtype=np.float64).reshape(len(values), width).astype(np.dtype(ft["dtype"]))
            ep_stats[name].update(typed)  # the statistics of the values as stored (float32 ...)
            self.global_stats[name].update(typed)
            flat = pa.array(typed.reshape(-1))
            arrays.append(flat if list(ft["shape"]) == [1] else pa.FixedSizeListArray.from_arrays(flat, width))
        self.data.write(pa.Table.from_arrays(arrays, schema=self.data.schema))
        for values in self.rows.values():
            values.clear()
        self.row_bytes = 0

    # -- the whole run -----------------------------------------------------------------------------------
    def run(self, max_gap_ms: float | None, max_frames: int) -> None:
        from tqdm import tqdm

        splitter = EpisodeSplitter(max_gap_ms, max_frames)
        errors: list[Any] = []
        # the records skipped here were reported by the survey already
        records = exported_records([t.path for t in self.survey.tubs], [])
        keys = [c.key for c in self.cameras]
        # decoding threads: leave a core to the encoder and this thread
        workers = max(1, min(4, (os.cpu_count() or 2) - 1))
        stream = iter_frames(records, keys, workers=workers, errors=errors) if keys else ((r, []) for r in records)
        try:
            for rec, images in tqdm(stream, total=self.survey.records, desc="export", unit="rec",
                                    disable=not self.progress, leave=False):
                if splitter.is_new(rec):
                    self._end_episode()
                    self._start_episode(rec)
                self.add(rec, images)
            self._end_episode()
            self._flush_episodes()
        except BaseException:
            self._close_files(quiet=True)
            raise
        self._close_files(quiet=False)
        known = set(self.survey.skipped)
        self.report.skipped.extend(r for r in map(short, errors) if r not in known)

    def _close_files(self, *, quiet: bool) -> None:
        """Close every writer (videos are flushed); the first error is raised once all are closed,
        unless ``quiet`` (an error is already on its way, which a second must not hide)."""
        first: Exception | None = None
        for close in [v.close for v in self.videos.values()] + [self.data.close, self.episode_files.close]:
            try:
                close()
            except Exception as exc:  # kept, raised below
                first = first or exc
        if first is not None and not quiet:
            raise first

    def finish(self) -> None:
        """Write info.json, stats.json, tasks.parquet, the sidecar and the dataset card."""
        pa = pyarrow()
        for name, video in self.videos.items():
            self.features[name]["info"] = video.feature_info()
        pa.parquet.write_table(tasks_table(list(self.tasks)), self.root / TASKS_PATH)
        write_json(self.root / STATS_PATH, {k: st.to_json(v.result()) for k, v in self.global_stats.items()})
        info = info_dict(fps=self.fps, features=self.features, total_episodes=self.report.episodes,
                         total_frames=self.frames, total_tasks=len(self.tasks), robot_type=ROBOT_TYPE,
                         videos=bool(self.videos), **self.limits)
        write_json(self.root / INFO_PATH, info)
        write_json(self.root / SIDECAR_PATH, {
            "format": 1, "codebase_version": CODEBASE_VERSION,
            "tubs": [{"name": t.path.name, "inputs": t.inputs, "types": t.types, "metadata": t.metadata}
                     for t in self.survey.tubs],
            "columns": [c.spec() for c in self.columns], "task": self.task,
            "capture_feature": CAPTURE_FEATURE,
        })
        (self.root / "README.md").write_text(_card(info, [t.path.name for t in self.survey.tubs]), encoding="utf-8")
        self.report.tasks = list(self.tasks)
        self.report.features = list(self.features)
        self.report.frames = self.frames


def _card(info: dict[str, Any], tubs: list[str]) -> str:
    """A dataset card like LeRobot's, so the folder can be uploaded to the Hub as it is."""
    return ("---\ntask_categories:\n- robotics\ntags:\n- LeRobot\n- donkeycar\n- vehicle-rc\nconfigs:\n"
            "- config_name: default\n  data_files: data/*/*.parquet\n---\n\n"
            f"A LeRobot dataset (codebase version {info['codebase_version']}) exported by vehicle-rc's "
            f"`vehicle tub export-lerobot` from the tubs {', '.join(tubs)}: {info['total_episodes']} episodes, "
            f"{info['total_frames']} frames at {info['fps']} fps.\n\nSchema: [meta/info.json](meta/info.json). "
            "Tub fields behind each feature: [meta/vehicle_rc.json](meta/vehicle_rc.json).\n")


def export_lerobot(tubs: Sequence[str | os.PathLike[str]] | str | os.PathLike[str], out: str | os.PathLike[str], *,
                   fps: int | None = None, video: bool = True, codec: str = DEFAULT_CODEC, crf: int = DEFAULT_CRF,
                   task: str = DEFAULT_TASK, max_gap_s: float | None = 1.0,
                   max_episode_s: float = DEFAULT_MAX_EPISODE_S, progress: bool = False) -> ExportReport:
    """Write the live records of ``tubs`` as a LeRobot v3.0 dataset in the new folder ``out``.

    Args:
        tubs: tub folders and/or folders of tubs (a car's ``data/``).
        out: the dataset folder; must not exist or be empty.
        fps: the nominal frame rate written to info.json, at which the videos play and from which
            ``timestamp`` = frame_index / fps (default: measured from the capture times, see
            ``survey.Intervals.fps``).
        video: camera frames as MP4 videos (LeRobot's default), else as JPEG bytes in the data files.
        codec, crf: video codec (libsvtav1 as LeRobot, h264 or hevc) and quality (lower = better).
        task: the task text of frames without a behaviour label or simulator track.
        max_gap_s: a longer gap in capture time starts a new episode (0 or None: only sessions and tracks).
        max_episode_s: an episode holds at most this many seconds of frames (max_episode_s x fps),
            longer sessions are split: ``timestamp`` is float32 and loses LeRobot's 1e-4 s
            tolerance past 2048 s (``MAX_EPISODE_S``).
        progress: show a progress bar.

    Raises:
        TubError: a path is not a tub, ``out`` is not empty, an option is out of range, the tubs
            disagree on a field's type, no record can be exported, or pyarrow/PyAV are missing or
            the video encoder fails (LeRobotFormatError).
    """
    t0 = time.perf_counter()
    paths = [tubs] if isinstance(tubs, str | os.PathLike) else list(tubs)
    out = Path(os.path.expanduser(os.fspath(out))).absolute()
    check_new_folder(out)  # before the survey: fail fast
    if fps is not None and (not isinstance(fps, int) or isinstance(fps, bool) or fps < 1):
        raise TubError(f"fps must be a whole number >= 1, got {fps!r}")
    check_codec(codec, crf)
    if max_gap_s is not None and not max_gap_s >= 0:  # NaN too
        raise TubError(f"max_gap_s must be >= 0 seconds (0: never split on a gap), got {max_gap_s:g}")
    if not 0 < max_episode_s <= MAX_EPISODE_S:
        raise TubError(f"max_episode_s must be > 0 and <= {MAX_EPISODE_S} s (LeRobot's float32 timestamps lose "
                       f"its 1e-4 s tolerance beyond), got {max_episode_s:g}")
    max_gap_ms = max_gap_s * 1000.0 if max_gap_s else None
    pyarrow()
    if video:
        from parts.tub.lerobot.format import av

        av()
    survey = survey_tubs(paths, max_gap_ms=max_gap_ms)
    if survey.records == 0:
        why = f" ({len(survey.skipped)} skipped, first: {survey.skipped[0]})" if survey.skipped else ""
        raise TubError(f"{', '.join(map(str, paths))}: no records to export{why}")
    measured = survey.fps()
    report = ExportReport(out, fps=fps or measured or DEFAULT_FPS, fps_measured=fps is None, video=video)
    if fps is None and measured is None:
        logger.warning("no interval between records could be measured: fps set to %d (give --fps)", report.fps)
    columns = plan_columns(survey, video=video)
    task_from = task_source(survey, task)
    max_frames = max(1, math.floor(max_episode_s * report.fps + 1e-9))
    with building_folder(out) as tmp:
        exporter = _Exporter(tmp, survey, columns, fps=report.fps, codec=codec, crf=int(crf), task=task_from,
                             report=report, progress=progress)
        exporter.run(max_gap_ms, max_frames)
        if exporter.frames == 0:
            raise TubError(f"{', '.join(map(str, paths))}: no record could be read ({len(report.skipped)} skipped)")
        exporter.finish()
        report.skipped[:0] = survey.skipped
    report.seconds = time.perf_counter() - t0
    if report.skipped:
        logger.warning("%d records not exported, first: %s", len(report.skipped), report.skipped[0])
    return report
