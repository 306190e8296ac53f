"""The tub v2 on-disk format shared with DonkeyCar 5.x: names, record encoding, file helpers.

Layout (see docs/data-format.md)::

    <tub>/manifest.json                      five JSON lines (inputs, types, metadata, sessions, catalogs)
    <tub>/catalog_<n>.catalog                one JSON record per line, keys sorted
    <tub>/catalog_<n>.catalog_manifest       {"created_at", "line_lengths", "path", "start_index"}
    <tub>/images/<index>_<key, "/"->"_">_.jpg
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from parts.tub.errors import TubSchemaError

MANIFEST = "manifest.json"
IMAGES = "images"
#: our side file (DonkeyCar ignores it): one JSON line per committed record with images, its
#: ``_index``, ``_session_id`` and the CRC-32 of each image file, which ``tub check`` verifies
IMAGE_CRCS = "image_crc32.jsonl"
CATALOG_RE = re.compile(r"^catalog_(\d+)\.catalog$")

# The value types a tub declares per input, DonkeyCar's names, declared here only (TUB_TYPES takes
# them as its valid values; docs/data-format.md's table lists them, a test compares). Scalars are
# JSON values, lists JSON lists, images files in images/: "image_array" a JPEG, "gray16_array" a
# 16-bit PNG (broken in DonkeyCar).
SCALAR_TYPES: tuple[str, ...] = ("float", "int", "str", "boolean")
LIST_TYPES: tuple[str, ...] = ("nparray", "list", "vector")
IMAGE_TYPES: tuple[str, ...] = ("image_array", "gray16_array")
ALL_TYPES: tuple[str, ...] = SCALAR_TYPES + LIST_TYPES + IMAGE_TYPES

# Private fields every record carries (DonkeyCar's names).
INDEX = "_index"
TIMESTAMP = "_timestamp_ms"
SESSION = "_session_id"


def catalog_name(n: int) -> str:
    """File name of the n-th catalog (``catalog_<n>.catalog``)."""
    return f"catalog_{n}.catalog"


def catalog_manifest_name(catalog: str) -> str:
    """``catalog_0.catalog`` -> ``catalog_0.catalog_manifest``."""
    return f"{Path(catalog).stem}.catalog_manifest"


def image_file_name(index: int, key: str, extension: str = ".jpg") -> str:
    """DonkeyCar's image name: ``<index>_<key with / -> _>_<ext>``, e.g. ``0_cam_image_array_.jpg``."""
    return f"{index}_{key.replace('/', '_')}_{extension}"


def session_full_id(number: int, when: float | None = None) -> str:
    """``YY-MM-DD_<number>``, DonkeyCar's session id (local date)."""
    return f"{time.strftime('%y-%m-%d', time.localtime(when))}_{number}"


def session_number(full_id: Any) -> int | None:
    """The trailing number of a session id, or None if it has none."""
    if isinstance(full_id, str):
        tail = full_id.rsplit("_", 1)[-1]
        if tail.isdigit():
            return int(tail)
    return None


def check_schema(inputs: list[str], types: list[str]) -> None:
    """Raise TubSchemaError unless inputs and types are parallel lists of names and known types."""
    if len(inputs) != len(types):
        raise TubSchemaError(f"inputs ({len(inputs)}: {inputs}) and types ({len(types)}: {types}) "
                             "must have the same length: give one type per input")
    if len(set(inputs)) != len(inputs):
        raise TubSchemaError(f"inputs contain duplicates: {inputs}")
    for key, tp in zip(inputs, types, strict=True):
        if not isinstance(key, str) or not key or key.startswith("_"):
            raise TubSchemaError(f"input name {key!r} is invalid: use a non-empty string not starting "
                                 "with '_' (names starting with '_' are the tub's private fields)")
        if tp not in ALL_TYPES:
            raise TubSchemaError(f"input {key!r} has unknown type {tp!r}; use one of {list(ALL_TYPES)}")


def encode_value(key: str, tp: str, value: Any) -> Any:
    """Convert a scalar/list value to what the catalog stores for declared type ``tp``."""
    try:
        if tp == "float":
            out = float(value)
            if not math.isfinite(out):
                raise ValueError("NaN and infinity cannot be stored (the format is strict JSON)")
            return out
        if tp == "int":
            return int(value)
        if tp == "str":
            return str(value)
        if tp == "boolean":
            return bool(value)
        if tp == "nparray":
            return np.asarray(value).tolist()
        if tp in ("list", "vector"):
            return np.asarray(value).tolist() if isinstance(value, np.ndarray) else list(value)
    except (TypeError, ValueError) as exc:
        raise TubSchemaError(f"value {value!r} of {key!r} does not fit its type {tp!r}: {exc}") from exc
    raise TubSchemaError(f"{key!r}: type {tp!r} is not a catalog value type")


# one encoder for every line: json.dumps with options builds a new one per call
_LINE_ENCODER = json.JSONEncoder(allow_nan=False, sort_keys=True)


def dumps_record(record: Mapping[str, Any]) -> str:
    """One catalog line (without newline): ASCII JSON, keys sorted, NaN rejected (DonkeyCar's)."""
    return _LINE_ENCODER.encode(record)


# -- file helpers --------------------------------------------------------------------------------

# os.open flags: binary on Windows (else CRLF translation and a stop at byte 0x1A), 0 elsewhere
O_BINARY: int = getattr(os, "O_BINARY", 0)


def fsync_dir(path: str | os.PathLike[str]) -> None:
    """fsync a directory so that new, renamed or removed entries in it survive a power loss.

    Windows cannot open a directory for this; NTFS journals its directory changes itself.
    """
    if os.name == "nt":
        return
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def atomic_write(path: Path, data: str | bytes, *, durable: bool = True) -> None:
    """Replace ``path`` with ``data`` atomically: temp file, fsync, rename, fsync of the folder.

    A crash at any instant leaves either the old or the new content, never a mix or a truncation
    (with ``durable=False`` the fsyncs are skipped: still atomic for a process crash).
    """
    raw = data.encode() if isinstance(data, str) else data
    tmp = path.with_name(f".{path.name}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | O_BINARY, 0o644)
    try:
        view = memoryview(raw)
        while view:
            view = view[os.write(fd, view):]
        if durable:
            os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    if durable:
        fsync_dir(path.parent)


def write_all(fd: int, data: bytes) -> None:
    """os.write until every byte is written."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def inside(tub: Path, path: Path) -> bool:
    """Whether ``path`` is a regular file of ``tub`` once every link is followed: a link that
    leaves the tub (to ``~/.ssh/id_rsa``, say) is not the tub's file and must not be served."""
    try:
        real = path.resolve(strict=True)
    except (OSError, RuntimeError):  # missing, or a link loop
        return False
    return real.is_relative_to(tub.resolve()) and real.is_file()


def links_leaving(tub: Path) -> list[str]:
    """The tub's own files (manifest, catalogs, their manifests, the images folder) that are links
    to somewhere outside the tub, by name."""
    names = [MANIFEST, IMAGES]
    try:
        names += sorted(n for n in os.listdir(tub) if n.startswith("catalog_"))
    except OSError:
        return []
    root = tub.resolve()
    out = []
    for name in names:
        path = tub / name
        if path.is_symlink():
            try:
                real = path.resolve(strict=True)
            except (OSError, RuntimeError):
                out.append(name)
                continue
            if not real.is_relative_to(root):
                out.append(name)
    return out


def check_new_folder(out: Path) -> None:
    """``out`` must not exist or be an empty folder (exports and imports never overwrite)."""
    from parts.tub.errors import TubError

    if out.exists():
        if not out.is_dir():
            raise TubError(f"{out} is a file; give a new folder")
        if any(out.iterdir()):
            raise TubError(f"{out} exists and is not empty; give a new folder (nothing was written)")


_PARTIAL_RE = re.compile(r"^\..+\.partial-(\d+)$")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True  # another user's process (or a number no process can have: kept, to be safe)
    return True


def remove_stale_partials(parent: Path) -> list[Path]:
    """Remove the ``.NAME.partial-PID`` folders in ``parent`` whose process is gone (an export or
    import killed before it finished); returns what was removed. A live process's folder stays."""
    removed = []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return removed
    for entry in entries:
        m = _PARTIAL_RE.match(entry.name)
        if m and entry.is_dir(follow_symlinks=False) and int(m.group(1)) != os.getpid() \
                and not _alive(int(m.group(1))):
            shutil.rmtree(entry.path, ignore_errors=True)
            removed.append(Path(entry.path))
    if removed:
        import logging

        logging.getLogger(__name__).info("removed %d unfinished folder%s left by a killed export or import: %s",
                                         len(removed), "" if len(removed) == 1 else "s",
                                         ", ".join(p.name for p in removed))
    return removed


def new_folder_tmp(out: Path) -> Path:
    """A fresh hidden folder beside ``out`` to build it in; :func:`replace_folder` puts it in place,
    so an interrupted export or import never leaves a half-written ``out``. Folders that killed
    runs left beside it are removed first (:func:`remove_stale_partials`)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_partials(out.parent)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    return tmp


def replace_folder(tmp: Path, out: Path) -> None:
    """Rename the finished ``tmp`` to ``out`` (replacing an empty ``out``), durably."""
    if out.is_dir():
        out.rmdir()
    os.replace(tmp, out)
    fsync_dir(out.parent)


@contextmanager
def building_folder(out: Path) -> Iterator[Path]:
    """Build the new folder ``out`` all at once: yields a hidden folder beside it to write into,
    which replaces ``out`` when the block ends normally and is removed when it raises (anything,
    Ctrl-C included), so ``out`` is either complete or untouched.

    >>> with building_folder(Path("datasets/mycar")) as tmp:
    ...     (tmp / "meta").mkdir()

    Raises TubError (before yielding) if ``out`` exists and is not an empty folder.
    """
    check_new_folder(out)
    tmp = new_folder_tmp(out)
    try:
        yield tmp
        replace_folder(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
