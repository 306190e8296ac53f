"""The LeRobot dataset layout, codebase version v3.0: paths, info.json, feature types, tasks.

What LeRobot's own writer produces (``lerobot/datasets``: utils.py, feature_utils.py,
dataset_metadata.py, lerobot_dataset.py of lerobot 0.4 and later)::

    meta/info.json                                   schema, fps, counts, path templates
    meta/stats.json                                  per-feature min/max/mean/std/count/q01..q99
    meta/tasks.parquet                               task text (pandas index "task") -> task_index
    meta/episodes/chunk-000/file-000.parquet         one row per episode: length, tasks, offsets, stats
    data/chunk-000/file-000.parquet                  one row per frame, many episodes per file
    videos/<feature>/chunk-000/file-000.mp4          the frames of many episodes, one after the other

A new file starts (at an episode boundary) when the current one reaches ``*_files_size_in_mb``;
file numbers run to ``chunks_size - 1``, then the chunk number goes up.
pyarrow and PyAV are imported on first use with a one-line install hint when missing.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from parts.tub.errors import TubError
from parts.tub.format import atomic_write

CODEBASE_VERSION = "v3.0"
INFO_PATH = "meta/info.json"
STATS_PATH = "meta/stats.json"
TASKS_PATH = "meta/tasks.parquet"
EPISODES_DIR = "meta/episodes"
CHUNK_FILE = "chunk-{chunk_index:03d}/file-{file_index:03d}"
EPISODES_PATH = EPISODES_DIR + "/" + CHUNK_FILE + ".parquet"
DATA_PATH = "data/" + CHUNK_FILE + ".parquet"
VIDEO_PATH = "videos/{video_key}/" + CHUNK_FILE + ".mp4"
#: what our export adds for the way back: the tub fields behind each feature (LeRobot ignores it)
SIDECAR_PATH = "meta/vehicle_rc.json"

CHUNKS_SIZE = 1000            # files per chunk folder
DATA_FILES_SIZE_IN_MB = 100   # a data (and episodes) parquet file is closed past this size
VIDEO_FILES_SIZE_IN_MB = 200  # a video file is closed past this size

#: the per-frame columns every LeRobot dataset has (LeRobot's DEFAULT_FEATURES), in its order
DEFAULT_FEATURES: dict[str, dict[str, Any]] = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}
CAMERA_NAMES = ["height", "width", "channels"]
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)  # LeRobot's DEFAULT_QUANTILES, keys q01 .. q99

INSTALL_HINT = "pip install 'vehicle-rc[datasets]'"


class LeRobotFormatError(TubError):
    """A folder is not a LeRobot dataset we can read, or a dataset cannot be written as asked."""


def _missing(module: str) -> LeRobotFormatError:
    return LeRobotFormatError(f"{module} is not installed; LeRobot datasets need it: {INSTALL_HINT}")


def pyarrow() -> Any:
    """The pyarrow module (with pyarrow.parquet loaded); an install hint when missing."""
    try:
        import pyarrow as pa
        import pyarrow.parquet  # noqa: F401 - loads pa.parquet
    except ImportError:
        raise _missing("pyarrow") from None
    return pa


def av() -> Any:
    """The PyAV module; an install hint when missing."""
    try:
        import av as module
    except ImportError:
        raise _missing("PyAV (av)") from None
    return module


def chunk_file_path(template: str, chunk: int, file: int, **keys: Any) -> str:
    """A path template filled in, e.g. ``data/chunk-000/file-003.parquet``."""
    return template.format(chunk_index=chunk, file_index=file, **keys)


def next_file(chunk: int, file: int, chunks_size: int = CHUNKS_SIZE) -> tuple[int, int]:
    """The (chunk, file) after this one: file numbers run to chunks_size - 1 within a chunk."""
    return (chunk + 1, 0) if file >= chunks_size - 1 else (chunk, file + 1)


# -- feature types ----------------------------------------------------------------------------------

def arrow_type(feature: dict[str, Any]) -> Any:
    """The Arrow type of a feature's data column (what ``datasets`` stores for it)."""
    pa = pyarrow()
    dtype = feature["dtype"]
    if dtype == "image":
        return pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    scalar = {"float32": pa.float32(), "float64": pa.float64(), "int64": pa.int64(), "int32": pa.int32(),
              "bool": pa.bool_(), "string": pa.string()}[dtype]
    shape = list(feature["shape"])
    return scalar if shape == [1] else pa.list_(scalar, shape[0])


def hf_feature(feature: dict[str, Any]) -> dict[str, Any]:
    """The feature as ``datasets`` 4 serialises it in a parquet file's "huggingface" metadata."""
    if feature["dtype"] == "image":
        return {"_type": "Image"}
    value = {"dtype": feature["dtype"], "_type": "Value"}
    shape = list(feature["shape"])
    return value if shape == [1] else {"feature": value, "length": shape[0], "_type": "List"}


def data_schema(features: dict[str, dict[str, Any]]) -> Any:
    """The Arrow schema of the data files: every feature but videos, with datasets' metadata."""
    pa = pyarrow()
    columns = {k: f for k, f in features.items() if f["dtype"] != "video"}
    schema = pa.schema([(k, arrow_type(f)) for k, f in columns.items()])
    meta = {"info": {"features": {k: hf_feature(f) for k, f in columns.items()}}}
    return schema.with_metadata({"huggingface": json.dumps(meta)})


# -- json files ---------------------------------------------------------------------------------------

def write_json(path: Path, data: Any) -> None:
    """JSON as LeRobot writes it (indent 4, UTF-8 kept), replaced atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, json.dumps(data, indent=4, ensure_ascii=False) + "\n", durable=False)


def info_dict(*, fps: int, features: dict[str, dict[str, Any]], total_episodes: int, total_frames: int,
              total_tasks: int, robot_type: str | None, videos: bool, chunks_size: int = CHUNKS_SIZE,
              data_files_size_in_mb: float = DATA_FILES_SIZE_IN_MB,
              video_files_size_in_mb: float = VIDEO_FILES_SIZE_IN_MB) -> dict[str, Any]:
    """meta/info.json, keys in the order LeRobot's ``create_empty_dataset_info`` writes them."""
    return {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": robot_type,
        "total_episodes": total_episodes,
        "total_frames": total_frames,
        "total_tasks": total_tasks,
        "chunks_size": chunks_size,
        "data_files_size_in_mb": data_files_size_in_mb,
        "video_files_size_in_mb": video_files_size_in_mb,
        "fps": fps,
        "splits": {"train": f"0:{total_episodes}"},
        "data_path": DATA_PATH,
        "video_path": VIDEO_PATH if videos else None,
        "features": features,
    }


def read_info(root: Path) -> dict[str, Any]:
    """meta/info.json of a v3.0 dataset; LeRobotFormatError saying what is wrong otherwise."""
    path = root / INFO_PATH
    if not root.is_dir():
        raise LeRobotFormatError(f"{root}: no such folder; give the folder of a LeRobot dataset "
                                 "(the one holding meta/info.json)")
    if not path.is_file():
        legacy = (root / "meta" / "episodes.jsonl").is_file()
        raise LeRobotFormatError(f"{root} is not a LeRobot dataset: it has no {INFO_PATH}"
                                 + (" (but meta/episodes.jsonl: a broken v2 dataset?)" if legacy else ""))
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LeRobotFormatError(f"{path} cannot be read: {exc}") from exc
    if not isinstance(info, dict):
        raise LeRobotFormatError(f"{path} holds no JSON object")
    version = info.get("codebase_version")
    if version != CODEBASE_VERSION:
        how = ("convert it first with `python -m lerobot.scripts.convert_dataset_v21_to_v30`"
               if isinstance(version, str) and version.startswith("v2") else "use a LeRobot v3.0 dataset")
        raise LeRobotFormatError(f"{root} is a LeRobot dataset of codebase version {version!r}; only "
                                 f"{CODEBASE_VERSION} is read here: {how}")
    for key in ("fps", "features", "data_path"):
        if key not in info:
            raise LeRobotFormatError(f"{path} lacks {key!r}: not a complete v3.0 info.json")
    fps = info["fps"]
    if isinstance(fps, bool) or not isinstance(fps, int | float) or not fps > 0:
        raise LeRobotFormatError(f"{path}: fps is {fps!r}; it must be a number > 0")
    if not isinstance(info["features"], dict) or not all(isinstance(f, dict) for f in info["features"].values()):
        raise LeRobotFormatError(f"{path}: 'features' must map each feature name to its dtype, shape and names")
    return info


# -- tasks.parquet ------------------------------------------------------------------------------------

def tasks_table(tasks: list[str]) -> Any:
    """meta/tasks.parquet as pandas writes LeRobot's DataFrame: column task_index, index "task".

    The pandas metadata makes ``pd.read_parquet`` return the task texts as the index, which is
    how LeRobot looks tasks up; no pandas is needed to write it.
    """
    pa = pyarrow()
    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode",
                            "numpy_type": "object", "metadata": {"encoding": "UTF-8"}}],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
             "metadata": None},
            {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object",
             "metadata": None},
        ],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.3",
    }
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "task": pa.array(tasks, pa.string())})
    return table.replace_schema_metadata({"pandas": json.dumps(pandas_meta)})


def read_tasks(root: Path) -> dict[int, str]:
    """task_index -> task text from meta/tasks.parquet (index column named by pandas' metadata)."""
    pa = pyarrow()
    path = root / TASKS_PATH
    if not path.is_file():
        return {}
    pf = open_parquet(path)
    try:
        table = pf.read()
    except (pa.ArrowException, OSError) as exc:
        raise not_parquet(path, exc) from exc
    names = table.column_names
    text_col = next((c for c in ("task", "__index_level_0__") if c in names), None)
    meta = table.schema.metadata or {}
    if b"pandas" in meta:
        index_cols = [c for c in json.loads(meta[b"pandas"]).get("index_columns", []) if isinstance(c, str)]
        text_col = index_cols[0] if index_cols else text_col
    if text_col is None or "task_index" not in names:
        raise LeRobotFormatError(f"{path} has columns {names}; expected task_index and the task text")
    return dict(zip(table.column("task_index").to_pylist(), table.column(text_col).to_pylist(), strict=True))


def not_parquet(path: Path, exc: BaseException) -> LeRobotFormatError:
    """The error for a file pyarrow cannot read (its message on one line)."""
    return LeRobotFormatError(f"{path} cannot be read as parquet: {' '.join(str(exc).split())}")


def open_parquet(path: Path) -> Any:
    """A ``pyarrow.parquet.ParquetFile``; LeRobotFormatError naming the file when it is not one."""
    pa = pyarrow()
    try:
        return pa.parquet.ParquetFile(path)
    except (pa.ArrowException, OSError) as exc:
        raise not_parquet(path, exc) from exc


def parquet_files(folder: Path) -> list[Path]:
    """``chunk-*/file-*.parquet`` under ``folder``, in chunk and file order."""
    return sorted(folder.glob("chunk-*/file-*.parquet"))


def size_mb(path: str | os.PathLike[str]) -> float:
    """A file's size in MiB (LeRobot's "MB"), 0 when it does not exist yet."""
    try:
        return os.path.getsize(path) / (1024 ** 2)
    except OSError:
        return 0.0
