"""Reading tubs for training: records across many tubs, deleted ones skipped, bad ones reported.

>>> records = load_records(["data"])          # a tub, or a folder of tubs
>>> img = records[0].image()                 # HxWx3 uint8 RGB
>>> for rec, img in iter_images(iter_records(["data"], check_images=False)): ...  # parallel decoding

A bad record (unparsable catalog line, missing or empty image file) is reported with tub, index and
file, then skipped (``on_error="skip"``) or raised as :class:`CorruptRecord` (``on_error="raise"``).
An image that exists but does not decode raises CorruptRecord from ``TubRecord.image()``.
"""

from __future__ import annotations

import logging
import os
from collections import deque
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, Literal

import numpy as np

from parts.tub.codec import decode_image
from parts.tub.errors import CorruptRecord, TubError
from parts.tub.format import CATALOG_RE, IMAGE_TYPES, IMAGES, MANIFEST, O_BINARY
from parts.tub.tub import Tub
from vehicle.keys import key_names

logger = logging.getLogger(__name__)

OnError = Literal["skip", "raise"]
IMAGE_KEY = "cam/image_array"
ANGLE_KEYS = ("user/angle", "user/steering")  # DonkeyCar renamed user/angle for a while (#1103)
SPEED_KEYS = ("enc/speed", "sim/speed")         # measured speed (m/s): encoder first, else the simulator's


class TubRecord:
    """One record of a tub: ``tub`` (folder), ``index`` (``_index``), ``data`` (catalog fields)."""

    __slots__ = ("tub", "index", "data")

    def __init__(self, tub: Path, index: int, data: dict[str, Any]) -> None:
        self.tub = tub
        self.index = index
        self.data = data

    def __repr__(self) -> str:
        return f"TubRecord({str(self.tub)!r}, {self.index})"

    def __getitem__(self, key: str) -> Any:
        return self.data[key]

    def get(self, key: str, default: Any = None) -> Any:
        return self.data.get(key, default)

    @property
    def angle(self) -> float | None:
        """Steering label: ``user/angle``, or ``user/steering`` in tubs of DonkeyCar 4.x/5.0."""
        for key in ANGLE_KEYS:
            if key in self.data:
                return self.data[key]
        return None

    @property
    def throttle(self) -> float | None:
        return self.data.get("user/throttle")

    @property
    def timestamp_ms(self) -> int | None:
        return self.data.get("_timestamp_ms")

    def image_path(self, key: str = IMAGE_KEY) -> Path:
        """The image file of ``key``; CorruptRecord if the record has no such image."""
        name = self._image_name(key)
        if name is None:
            raise CorruptRecord(self.tub, self.index, self.tub / IMAGES, f"record has no image {key!r}")
        return self.tub / IMAGES / name

    def _image_name(self, key: str) -> str | None:
        """The image file name under ``key``, or under another name of the same key (an older
        name, see ``vehicle.keys.KEY_ALIASES``); None if the record has none."""
        name = self.data.get(key)
        if isinstance(name, str) and name:
            return name
        for other in key_names(key)[1:]:
            name = self.data.get(other)
            if isinstance(name, str) and name:
                return name
        return None

    def has_image(self, key: str) -> bool:
        """Whether the record names an image file under ``key`` (or another name of it)."""
        return self._image_name(key) is not None

    def image_bytes(self, key: str = IMAGE_KEY) -> bytes:
        """The image file's bytes; CorruptRecord if missing or empty."""
        name = self.data.get(key)
        if not isinstance(name, str) or not name:
            name = self._image_name(key)
            if name is None:
                self.image_path(key)  # raises the "no image" error
        path = os.path.join(self.tub, IMAGES, name)  # str join: this runs once per training sample
        try:
            data = _read_file(path)
        except OSError as exc:
            raise CorruptRecord(self.tub, self.index, path, f"cannot read image ({exc.strerror})") from exc
        if not data:
            raise CorruptRecord(self.tub, self.index, path, "image file is empty (0 bytes)")
        return data

    def image(self, key: str = IMAGE_KEY, out: np.ndarray | None = None) -> np.ndarray:
        """The decoded image, HxWx3 uint8 RGB; CorruptRecord naming tub, index and file if bad.

        ``out``: an array to decode into when the frame fits (see ``codec.decode_image``).
        """
        data = self.image_bytes(key)
        img = decode_image(data, out)
        if img is None:
            raise CorruptRecord(self.tub, self.index, self.image_path(key), "image does not decode")
        return img


_READ_SIZE = 64 * 1024  # one read() takes a whole 160x120 JPEG (~3 KB); below malloc's mmap threshold


def _read_file(path: str) -> bytes:
    """A small file's bytes in as few system calls as possible (open, read, close: each one lets
    another decoding thread take the GIL, so fewer calls also means fewer thread hand-offs)."""
    fd = os.open(path, os.O_RDONLY | O_BINARY)
    try:
        data = os.read(fd, _READ_SIZE)
        if len(data) < _READ_SIZE:
            return data
        parts = [data]
        while chunk := os.read(fd, 1 << 20):
            parts.append(chunk)
        return b"".join(parts)
    finally:
        os.close(fd)


def is_tub(path: Path) -> bool:
    """Whether a folder holds a tub (a manifest.json or a catalog file)."""
    if (path / MANIFEST).is_file():
        return True
    try:
        return any(CATALOG_RE.match(p.name) for p in path.iterdir())
    except OSError:
        return False


def find_tubs(paths: str | os.PathLike[str] | Iterable[str | os.PathLike[str]]) -> list[Path]:
    """Tub folders in ``paths``: each path is a tub or a folder searched (recursively) for tubs.

    Raises TubError when a path does not exist or holds no tub.
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    found: list[Path] = []
    for p in paths:
        path = Path(os.path.expanduser(os.fspath(p)))
        if not path.is_dir():
            raise TubError(f"{path}: no such folder; give a tub folder or a folder of tubs")
        if is_tub(path):
            found.append(path)
            continue
        inside = []
        for root, dirs, _files in os.walk(path):
            # hidden folders are tubs and datasets being built (parts.tub.births): not yet tubs
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            here = Path(root)
            if here != path and is_tub(here):
                inside.append(here)
                dirs.clear()  # a tub's images/ is not searched
        if not inside:
            raise TubError(f"{path} holds no tub (no manifest.json or catalog_*.catalog in it or below)")
        found.extend(inside)
    return found


def _report(error: CorruptRecord, on_error: OnError, errors: list[CorruptRecord] | None) -> None:
    if errors is not None:
        errors.append(error)
    if on_error == "raise":
        raise error
    logger.warning("skipped: %s", error)


def iter_records(paths: str | os.PathLike[str] | Iterable[str | os.PathLike[str]], *,
                 on_error: OnError = "skip", include_deleted: bool = False, check_images: bool = True,
                 errors: list[CorruptRecord] | None = None) -> Iterator[TubRecord]:
    """Records of every tub in ``paths``, in tub and index order, deleted ones skipped.

    Args:
        paths: tub folders and/or folders of tubs.
        on_error: "skip" logs a bad record (tub, index, file) and goes on; "raise" raises
            CorruptRecord at the first one.
        include_deleted: also yield soft-deleted records.
        check_images: skip records whose image files are missing or empty (a cheap stat; decoding
            errors surface in ``TubRecord.image()``).
        errors: if given, every bad record found is appended to it.
    """
    if on_error not in ("skip", "raise"):
        raise ValueError(f"on_error must be 'skip' or 'raise', got {on_error!r}")
    for tub_path in find_tubs(paths):
        try:
            tub = Tub(tub_path, read_only=True)
        except TubError as exc:
            _report(CorruptRecord(tub_path, None, tub_path / MANIFEST, str(exc)), on_error, errors)
            continue
        image_keys = [k for k, t in zip(tub.inputs, tub.types, strict=True) if t in IMAGE_TYPES]
        deleted = tub.manifest.deleted_indexes
        images = os.fspath(tub.images_path)  # str paths: pathlib costs more than the stat itself
        for catalog, index, rec, _line, salvaged in tub.scan():
            if rec is None:
                _report(CorruptRecord(tub.path, index, catalog, "unparsable catalog line"), on_error, errors)
                continue
            if salvaged:
                logger.warning("%s: record %d salvaged from a line with a torn record before it",
                               catalog, index)
            if index in deleted and not include_deleted:
                continue
            if check_images and not _images_ok(tub.path, index, rec, image_keys, images, on_error, errors):
                continue
            yield TubRecord(tub.path, index, rec)


def _images_ok(tub: Path, index: int, rec: dict[str, Any], keys: list[str], images: str,
               on_error: OnError, errors: list[CorruptRecord] | None) -> bool:
    for key in keys:
        name = rec.get(key)
        if name is None:
            _report(CorruptRecord(tub, index, images, f"record has no image {key!r}"), on_error, errors)
            return False
        path = os.path.join(images, str(name))
        try:
            size = os.stat(path).st_size
        except OSError:
            _report(CorruptRecord(tub, index, path, "image file is missing"), on_error, errors)
            return False
        if size == 0:
            _report(CorruptRecord(tub, index, path, "image file is empty (0 bytes)"), on_error, errors)
            return False
    return True


def load_records(paths: str | os.PathLike[str] | Iterable[str | os.PathLike[str]], **kwargs: Any
                 ) -> list[TubRecord]:
    """``list(iter_records(paths, **kwargs))``."""
    return list(iter_records(paths, **kwargs))


def iter_images(records: Iterable[TubRecord], key: str = IMAGE_KEY, *, workers: int | None = None,
                on_error: OnError = "skip", prefetch: int | None = None
                ) -> Iterator[tuple[TubRecord, np.ndarray]]:
    """(record, decoded image) pairs in order, files read and decoded by ``workers`` threads.

    The JPEG codecs release the GIL while decoding, so threads use several cores. ``workers`` defaults to
    one per core, at most 4 (a consumer that only collects frames would leave a core of its own
    idle; give fewer when it works hard itself). ``prefetch``: records decoded ahead of the
    consumer (default: two tasks per worker, at most 128 frames in memory).

    A missing, empty or undecodable image of ``key`` is reported with tub, index and file and
    skipped, or raised with ``on_error="raise"``. ``records`` may be a generator:
    ``iter_records(paths, check_images=False)`` parses catalogs while the first frames decode,
    without a stat of every image beforehand (its own reports of bad catalog lines may then come
    up to ``prefetch`` records ahead of the frames).
    """
    frames = iter_frames(records, (key,), workers=workers, on_error=on_error, prefetch=prefetch)
    try:
        for rec, images in frames:
            yield rec, images[0]
    finally:  # stopped early: end the decoding threads now, not when the generator is collected
        frames.close()


def iter_frames(records: Iterable[TubRecord], keys: Sequence[str], *, workers: int | None = None,
                on_error: OnError = "skip", prefetch: int | None = None,
                errors: list[CorruptRecord] | None = None) -> Iterator[tuple[TubRecord, list[np.ndarray]]]:
    """:func:`iter_images` for several image keys: (record, [image of each key]) in order.

    A record any of whose images is bad is reported (tub, index, file) and skipped as a whole;
    ``errors``, if given, collects the reports.
    """
    if workers is None:
        workers = max(1, min(4, os.cpu_count() or 1))
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if prefetch is None:  # two tasks per worker, so none idles between tasks; frames held: <= 128
        prefetch = min(2 * workers * _CHUNK, 4 * _CHUNK)
    keys = tuple(keys)

    def load(chunk: list[TubRecord]) -> list[list[np.ndarray] | CorruptRecord]:
        out: list[list[np.ndarray] | CorruptRecord] = []
        for rec in chunk:
            try:
                out.append([rec.image(key) for key in keys])
            except CorruptRecord as exc:
                out.append(exc)
        return out

    # Chunks of records per task keep the executor's per-task overhead small.
    window: deque[tuple[list[TubRecord], Future[Any]]] = deque()
    chunk: list[TubRecord] = []
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="tub-read")
    try:
        for rec in records:
            chunk.append(rec)
            if len(chunk) >= _CHUNK:
                window.append((chunk, pool.submit(load, chunk)))
                chunk = []
                if len(window) * _CHUNK >= prefetch:
                    yield from _take(window, on_error, errors)
        if chunk:
            window.append((chunk, pool.submit(load, chunk)))
        while window:
            yield from _take(window, on_error, errors)
    finally:  # the consumer may stop early (break, an error): drop the tasks not started yet
        pool.shutdown(wait=True, cancel_futures=True)


_CHUNK = 32  # records per task: a task hand-off costs about as much as decoding a frame


def _take(window: deque[tuple[list[TubRecord], Future[Any]]], on_error: OnError,
          errors: list[CorruptRecord] | None) -> Iterator[tuple[TubRecord, list[np.ndarray]]]:
    chunk, fut = window.popleft()
    for rec, result in zip(chunk, fut.result(), strict=True):
        if isinstance(result, CorruptRecord):
            _report(result, on_error, errors)
        else:
            yield rec, result
