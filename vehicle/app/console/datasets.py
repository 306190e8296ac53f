"""The console's datasets: the car's tubs with their statistics, and every change made to them.

Tubs are found in the car's data folder (DATA_PATH) and registered in the car's model database
(:class:`training.model_db.ModelDB`); folders elsewhere can be registered by path.
Statistics (records, duration, sessions, size, steering histogram, thumbnails) are read from the
catalogs and cached until a tub changes on disk. Deleting a dataset is first a soft delete, the
tub's own record deletes (``vehicle tub restore`` undoes it too); only a soft-deleted dataset can
be removed from the disk.

Nothing here imports torch or aiohttp: the web layer calls these functions in a worker thread.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import re
import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from parts.tub.errors import TubError
from parts.tub.format import IMAGE_TYPES, IMAGES, SESSION, TIMESTAMP, inside, links_leaving
from training.model_db import DatasetEntry, ModelDB, ModelDBError
from vehicle.errors import UserError

logger = logging.getLogger(__name__)

#: steering histogram bins over [-1, 1]
HISTOGRAM_BINS = 21
#: thumbnails shown per dataset in the list
THUMBNAILS = 6
#: most points of the steering/throttle series sent to the dataset page (longer tubs are strided)
MAX_SERIES_POINTS = 20000
#: a tub whose catalog changed this recently is being recorded into: edits wait
RECORDING_GRACE_S = 5.0
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")
ANGLE_KEYS = ("user/angle", "user/steering")
THROTTLE_KEY = "user/throttle"



def _not_born(path: Path) -> bool:
    """An empty folder: a dataset created in the console that nothing has recorded into yet (a tub
    appears there with its first record)."""
    return path.is_dir() and not any(path.iterdir())

class DatasetError(UserError):
    """A dataset action cannot be done; the message says why and what to do."""

    def __init__(self, message: str, field: str | None = None, status: int = 400) -> None:
        super().__init__(message)
        self.field = field
        self.status = status


def check_folder_name(name: str, field: str = "name") -> str:
    """A dataset folder name: letters, digits, '.', '_', '-' (no path)."""
    name = (name or "").strip()
    if not name:
        raise DatasetError("must not be empty: it is the dataset's folder name", field)
    if not _NAME_RE.match(name):
        raise DatasetError(f"{name!r}: use letters, digits, '.', '_' or '-' (a folder name, at most 100 "
                           "characters, starting with a letter or digit)", field)
    return name


def check_label(label: Any) -> str | None:
    """The track/label: free text up to 60 characters, None when blank (Track Driver AI's track number
    is a label like any other: "1", "3", "oval", "right lane")."""
    if label is None:
        return None
    if not isinstance(label, str | int) or isinstance(label, bool):
        raise DatasetError("must be text", "label")
    text = str(label).strip()
    if len(text) > 60:
        raise DatasetError("at most 60 characters", "label")
    return text or None


def check_comment(comment: Any) -> str | None:
    """A free comment up to 2000 characters (None when blank)."""
    if comment is None:
        return None
    if not isinstance(comment, str):
        raise DatasetError("must be text", "comment")
    if len(comment) > 2000:
        raise DatasetError("at most 2000 characters", "comment")
    return comment.strip() or None


@dataclass
class _Stats:
    signature: tuple[Any, ...]
    summary: dict[str, Any]
    indexes: np.ndarray
    angles: np.ndarray
    throttles: np.ndarray
    deleted: np.ndarray
    times: np.ndarray
    images: dict[int, str]


def _signature(path: Path) -> tuple[Any, ...]:
    """Changes whenever the tub changes on disk (manifest or catalogs)."""
    sig: list[Any] = []
    try:
        for p in sorted(path.iterdir()):
            if p.name == "manifest.json" or p.name.startswith("catalog_"):
                st = p.stat()
                sig.append((p.name, st.st_size, st.st_mtime_ns))
    except OSError:
        return ("missing",)
    return tuple(sig)


def _angle(rec: dict[str, Any]) -> float:
    for key in ANGLE_KEYS:
        v = rec.get(key)
        if isinstance(v, int | float) and not isinstance(v, bool):
            return float(v)
    return math.nan


def _number(v: Any) -> float:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan


class DatasetStore:
    """The datasets of one car (its model database and data folder)."""

    def __init__(self, cfg: Any, db: ModelDB) -> None:
        self.cfg = cfg
        self.db = db
        self.data_path = cfg.path("DATA_PATH").resolve()
        self._cache: dict[Path, _Stats] = {}
        self._lock = threading.Lock()
        # folders a queued or running job reads: not renamed, deleted or edited meanwhile
        self.busy: Callable[[], set[Path]] | None = None

    # -- discovery ----------------------------------------------------------------------------
    def sync(self) -> list[DatasetEntry]:
        """Register the tubs of the data folder that are not managed yet; returns every dataset."""
        from parts.tub.reader import find_tubs

        if self.data_path.is_dir():
            known = {e.path for e in self.db.datasets()}
            try:
                found = find_tubs([self.data_path])
            except TubError:
                found = []  # an empty data folder
            for tub in found:
                if tub.resolve() not in known:
                    self.db.add_dataset(tub, "found")
        return self.db.datasets()

    def get(self, dataset_id: int) -> DatasetEntry:
        """The dataset ``dataset_id`` (404-style error when unknown)."""
        try:
            return self.db.dataset(int(dataset_id))
        except (ModelDBError, ValueError) as exc:
            raise DatasetError(f"no dataset {dataset_id}: it was removed; reload the list", status=404) from exc

    # -- statistics -----------------------------------------------------------------------------
    def _stats(self, path: Path) -> _Stats:
        from parts.tub.tools import disk_size
        from parts.tub.tub import Tub

        sig = _signature(path)
        with self._lock:
            cached = self._cache.get(path)
            if cached is not None and cached.signature == sig:
                return cached
        contained(path)
        # a folder created to record into holds no tub until its first record: the car's schema
        schema = () if any(path.iterdir()) else (list(self.cfg.TUB_INPUTS), list(self.cfg.TUB_TYPES))
        tub = Tub(path, *schema, read_only=True)
        deleted_set = tub.manifest.deleted_indexes
        image_key = next((k for k, t in zip(tub.inputs, tub.types, strict=True) if t in IMAGE_TYPES), None)
        idx, ang, thr, dele, ts = [], [], [], [], []
        images: dict[int, str] = {}
        sessions: dict[str, int] = {}
        for index, rec in tub.records(include_deleted=True):
            idx.append(index)
            ang.append(_angle(rec))
            thr.append(_number(rec.get(THROTTLE_KEY)))
            is_deleted = index in deleted_set
            dele.append(is_deleted)
            ts.append(_number(rec.get(TIMESTAMP)))
            if image_key is not None and isinstance(rec.get(image_key), str):
                images[index] = rec[image_key]
            if not is_deleted:
                s = str(rec.get(SESSION, "?"))
                sessions[s] = sessions.get(s, 0) + 1
        indexes = np.asarray(idx, np.int64)
        angles = np.asarray(ang, np.float64)
        throttles = np.asarray(thr, np.float64)
        deleted = np.asarray(dele, bool)
        times = np.asarray(ts, np.float64)
        live = ~deleted
        live_times = times[live & np.isfinite(times)]
        duration = float((live_times.max() - live_times.min()) / 1000.0) if live_times.size > 1 else 0.0
        finite = angles[live & np.isfinite(angles)]
        hist = np.histogram(np.clip(finite, -1, 1), bins=HISTOGRAM_BINS, range=(-1.0, 1.0))[0] if finite.size \
            else np.zeros(HISTOGRAM_BINS, np.int64)
        live_idx = indexes[live & np.isin(indexes, list(images))] if images else np.zeros(0, np.int64)
        picks = [int(live_idx[int(round(i))]) for i in np.linspace(0, live_idx.size - 1, THUMBNAILS)] \
            if live_idx.size >= THUMBNAILS else [int(i) for i in live_idx]
        summary = {
            "records": int(live.sum()), "deleted_records": int(deleted.sum()),
            "current_index": tub.current_index, "sessions": len(sessions),
            "duration_s": round(duration, 1),
            "first_time": float(live_times.min()) / 1000.0 if live_times.size else None,
            "size_bytes": disk_size(path), "inputs": list(tub.inputs), "types": list(tub.types),
            "image_key": image_key, "histogram": [int(v) for v in hist],
            "mean_angle": round(float(finite.mean()), 4) if finite.size else None,
            "thumbnails": sorted(dict.fromkeys(picks)), "metadata": dict(tub.metadata),
            "problems": list(tub.problems),
        }
        stats = _Stats(sig, summary, indexes, angles, throttles, deleted, times, images)
        with self._lock:
            self._cache[path] = stats
        return stats

    def summary(self, entry: DatasetEntry) -> dict[str, Any]:
        """What the dataset list shows for one dataset (the stats are None for a missing folder)."""
        out = entry.as_dict()
        out["in_data_folder"] = entry.path.is_relative_to(self.data_path)
        out["models"] = self.db.models_of_dataset(entry.id)
        if not entry.path.is_dir():
            out["stats"] = None
            out["error"] = f"{entry.path} is missing: it was moved or deleted outside the console"
            return out
        try:
            out["stats"] = self._stats(entry.path).summary
        except DatasetError as exc:
            out["stats"] = None
            out["error"] = str(exc)
        except (TubError, OSError, ValueError) as exc:
            out["stats"] = None
            out["error"] = f"cannot read the tub: {exc}"
        return out

    def series(self, entry: DatasetEntry) -> dict[str, Any]:
        """Per-record index, steering, throttle, time and deleted flag for the dataset page."""
        st = self._stats(self._existing(entry))
        step = max(1, math.ceil(st.indexes.size / MAX_SERIES_POINTS))

        def clean(a: np.ndarray) -> list[float | None]:
            return [None if not math.isfinite(v) else round(float(v), 4) for v in a[::step]]

        t0 = np.nanmin(st.times) if np.isfinite(st.times).any() else math.nan
        return {"step": step, "index": [int(i) for i in st.indexes[::step]], "angle": clean(st.angles),
                "throttle": clean(st.throttles), "time": clean((st.times - t0) / 1000.0),
                "deleted": [bool(d) for d in st.deleted[::step]], "images": bool(st.images)}

    def image_path(self, entry: DatasetEntry, index: int) -> Path:
        """The image file of record ``index`` (DatasetError when it has none)."""
        path = self._existing(entry)
        st = self._stats(path)
        name = st.images.get(int(index))
        if name is None or "/" in name or "\\" in name or name.startswith("."):
            raise DatasetError(f"record {index} of {entry.name} has no image", status=404)
        file = path / "images" / name
        if not file.is_file():
            raise DatasetError(f"the image of record {index} is missing ({file})", status=404)
        if not inside(path, file):
            raise DatasetError(f"the image of record {index} ({file}) is a link to a file outside the tub: the "
                               "console serves no file from outside a tub; replace the link with the image",
                               status=403)
        return file

    def record(self, entry: DatasetEntry, index: int) -> dict[str, Any]:
        """One record's catalog fields (images as file names)."""
        from parts.tub.tub import Tub

        tub = Tub(contained(self._existing(entry)), read_only=True)
        for i, rec in tub.records(include_deleted=True):
            if i == int(index):
                return {"index": i, "deleted": i in tub.manifest.deleted_indexes, "fields": rec}
        raise DatasetError(f"no record {index} in {entry.name}", status=404)

    # -- changes ----------------------------------------------------------------------------------
    def _existing(self, entry: DatasetEntry) -> Path:
        if not entry.path.is_dir():
            raise DatasetError(f"{entry.path} is missing: it was moved or deleted outside the console; "
                               "remove it from the list", status=409)
        return entry.path

    def _writable(self, entry: DatasetEntry) -> Path:
        path = self._existing(entry)
        if self.busy is not None and path in self.busy():
            raise DatasetError(f"{entry.name} is used by a queued or running job; wait for it to finish "
                               "or cancel it", status=409)
        # records appended in the last seconds (an empty catalog is a tub created, not recording)
        newest = max((st.st_mtime for p in path.glob("catalog_*.catalog") if (st := p.stat()).st_size), default=0.0)
        if time.time() - newest < RECORDING_GRACE_S:
            raise DatasetError(f"{entry.name} was written {time.time() - newest:.0f} s ago: the car seems to be "
                               "recording into it; stop recording first", status=409)
        return path

    def create(self, name: str, label: Any = None, comment: Any = None) -> DatasetEntry:
        """An empty folder ``DATA_PATH/name`` to record into later (``vehicle sim record --tub``, or
        DATA_PATH with AUTO_CREATE_NEW_TUB off); the tub (with the car's TUB_INPUTS/TUB_TYPES) appears
        there with its first record: a tub without records is one DonkeyCar cannot open.
        An existing tub of that name is registered instead (Track Driver AI's "not in the datasets folder"
        and "in the datasets folder" both work)."""
        from parts.tub.reader import is_tub

        name = check_folder_name(name)
        label, comment = check_label(label), check_comment(comment)
        path = self.data_path / name
        if path.exists():
            if not path.is_dir() or not (is_tub(path) or not any(path.iterdir())):
                raise DatasetError(f"{path} exists and is not a tub; choose another name", "name")
            if is_tub(path):
                return self._add(path, "registered", label, comment)
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DatasetError(f"cannot create {path}: {exc}", "name") from exc
        return self._add(path, "created", label, comment)

    def register(self, folder: str, label: Any = None, comment: Any = None) -> list[DatasetEntry]:
        """Manage an existing tub folder anywhere (relative paths: from the car folder); a folder of
        tubs registers each tub in it."""
        from parts.tub.reader import find_tubs

        label, comment = check_label(label), check_comment(comment)
        path = self._user_path(folder, "path", "give the path of a tub folder")
        if not path.is_dir():
            raise DatasetError(f"{path}: no such folder", "path")
        try:
            tubs = find_tubs([path])
        except TubError as exc:
            raise DatasetError(str(exc), "path") from exc
        return [self._add(t.resolve(), "registered", label, comment) for t in tubs]

    def _user_path(self, text: Any, field: str, what: str) -> Path:
        """A path typed by the user: ``~`` expanded, relative paths taken from the car folder."""
        text = text.strip() if isinstance(text, str) else ""
        if not text:
            raise DatasetError(f"must not be empty: {what}", field)
        path = Path(os.path.expanduser(text))
        return path if path.is_absolute() else Path(self.cfg.CAR_PATH) / path

    def _add(self, path: Path, origin: str, label: str | None, comment: str | None) -> DatasetEntry:
        entry = self.db.add_dataset(path, origin, label, comment)
        if entry.label != label or entry.comment != comment:
            entry = self.db.update_dataset(entry.id, **{k: v for k, v in
                                                             (("label", label), ("comment", comment)) if v})
        return entry

    def edit(self, dataset_id: int, name: str | None = None, label: Any = ..., comment: Any = ...) -> DatasetEntry:
        """Rename the folder (Track Driver AI's trainer renames it on disk), change label and comment."""
        entry = self.get(dataset_id)
        fields: dict[str, Any] = {}
        if label is not ...:
            fields["label"] = check_label(label)
        if comment is not ...:
            fields["comment"] = check_comment(comment)
        if name is not None and check_folder_name(name) != entry.name:
            old = self._writable(entry)
            new = old.with_name(check_folder_name(name))
            if new.exists():
                raise DatasetError(f"{new} exists already; choose another name", "name")
            old.rename(new)
            try:
                entry = self.db.update_dataset(entry.id, path=new)
            except BaseException:
                new.rename(old)
                raise
            logger.info("renamed dataset %s to %s", old, new)
        return self.db.update_dataset(entry.id, **fields) if fields else self.get(entry.id)

    def soft_delete(self, dataset_id: int) -> DatasetEntry:
        """Mark every record deleted (the tub's own soft delete); restorable."""
        from parts.tub.tub import Tub

        entry = self.get(dataset_id)
        if entry.deleted:
            return entry
        path = self._writable(entry)
        if _not_born(path):  # a created dataset nothing recorded into yet: no record to mark
            return self.db.update_dataset(entry.id, deleted=_now(), kept_deleted=[])
        with Tub(path) as tub:
            before = sorted(tub.manifest.deleted_indexes)
            if tub.current_index:
                tub.delete_records(range(tub.current_index))
        logger.info("dataset %s soft-deleted (%d records were deleted before)", entry.path, len(before))
        return self.db.update_dataset(entry.id, deleted=_now(), kept_deleted=before)

    def restore(self, dataset_id: int) -> DatasetEntry:
        """Undo :meth:`soft_delete`: the records deleted before it stay deleted."""
        from parts.tub.tub import Tub

        entry = self.get(dataset_id)
        if not entry.deleted:
            return entry
        path = self._writable(entry)
        if _not_born(path):
            return self.db.update_dataset(entry.id, deleted=None, kept_deleted=[])
        with Tub(path) as tub:
            keep = set(entry.kept_deleted)
            tub.restore_records([i for i in range(tub.current_index) if i not in keep])
        return self.db.update_dataset(entry.id, deleted=None, kept_deleted=[])

    def purge(self, dataset_id: int) -> None:
        """Delete a soft-deleted dataset's folder from the disk and forget it."""
        entry = self.get(dataset_id)
        if not entry.deleted:
            raise DatasetError(f"{entry.name} is not deleted yet: delete it first (it can be restored until it "
                               "is removed from the disk)", status=409)
        if entry.path.exists():
            path = self._writable(entry)
            from parts.tub.reader import is_tub

            if _not_born(path):
                path.rmdir()
            elif not is_tub(path):
                raise DatasetError(f"{path} is no longer a tub: not removing it", status=409)
            else:
                shutil.rmtree(path)
            logger.info("removed dataset folder %s", path)
        self.db.forget_dataset(entry.id)
        with self._lock:
            self._cache.pop(entry.path, None)

    def forget(self, dataset_id: int) -> None:
        """Stop listing a dataset whose folder is gone (or that was registered by mistake)."""
        entry = self.get(dataset_id)
        if entry.path.is_dir() and entry.path.is_relative_to(self.data_path):
            raise DatasetError(f"{entry.name} is in the car's data folder and would be found again: delete it "
                               "instead", status=409)
        self.db.forget_dataset(entry.id)

    def mark_records(self, dataset_id: int, start: int, end: int, delete: bool) -> dict[str, Any]:
        """Delete (or restore) records ``start..end`` (inclusive) of a dataset."""
        from parts.tub.tub import Tub

        entry = self.get(dataset_id)
        if entry.deleted:
            raise DatasetError(f"{entry.name} is deleted: restore it first", status=409)
        for name, v in (("start", start), ("end", end)):
            if not isinstance(v, int) or isinstance(v, bool):
                raise DatasetError("must be a record index (a whole number)", name)
        if start > end:
            raise DatasetError(f"start {start} is after end {end}", "start")
        with Tub(self._writable(entry)) as tub:
            last = tub.current_index - 1
            if not 0 <= start <= last or not 0 <= end <= last:
                raise DatasetError(f"records are numbered 0 to {last}", "start" if not 0 <= start <= last else "end")
            if delete:
                tub.delete_records(range(start, end + 1))
                kept: list[int] = []
            else:
                kept = tub.restore_records(range(start, end + 1))
        return {"dataset": self.summary(self.get(entry.id)), "kept_deleted": kept}

    def import_udacity(self, source: str, name: str, label: Any = None, comment: Any = None) -> DatasetEntry:
        """Import a Udacity simulator recording (driving_log.csv or its folder) as ``DATA_PATH/name``."""
        from parts.tub.udacity import import_udacity

        name = check_folder_name(name)
        label, comment = check_label(label), check_comment(comment)
        src = self._user_path(source, "source", "give driving_log.csv or the folder holding it")
        target = self.data_path / name
        if target.exists():
            raise DatasetError(f"{target} exists already; choose another name", "name")
        try:
            report = import_udacity(src, target)
        except TubError as exc:
            if target.exists() and not any(target.glob("catalog_*")):
                shutil.rmtree(target, ignore_errors=True)
            raise DatasetError(str(exc), "source") from exc
        entry = self._add(target.resolve(), "udacity", label, comment)
        logger.info("imported %d Udacity rows into %s (%d skipped)", report.imported, target, len(report.skipped))
        return entry


def contained(tub: Path, images: bool = False) -> Path:
    """``tub``, after checking that none of its files the console reads is a link leaving it
    (``images``: every image too); DatasetError (403) naming the link otherwise."""
    leaving = links_leaving(tub)
    if images and IMAGES not in leaving:
        with contextlib.suppress(OSError), os.scandir(tub / IMAGES) as it:
            leaving += [f"{IMAGES}/{e.name}" for e in it if e.is_symlink() and not inside(tub, Path(e.path))]
    if leaving:
        shown = ", ".join(leaving[:3]) + (f" and {len(leaving) - 3} more" if len(leaving) > 3 else "")
        raise DatasetError(f"{tub}: {shown} {'is a link' if len(leaving) == 1 else 'are links'} to files outside "
                           "the tub; the console reads no file outside a tub: replace the links with the files",
                           status=403)
    return tub


def augmentation_preview(tubs: list[Path], settings: Any, rows: int = 3, variants: int = 5,
                         seed: int = 0) -> bytes:
    """A PNG grid of augmented frames from ``tubs`` (``settings``: AugmentSettings)."""
    import cv2

    from training.augment import Augmenter, preview_frames, preview_grid

    for tub in tubs:
        contained(tub, images=True)
    frames, angles = preview_frames(tubs, rows)
    grid = preview_grid(frames, angles, Augmenter(settings), variants, seed, scale=1)
    ok, buf = cv2.imencode(".png", cv2.cvtColor(grid, cv2.COLOR_RGB2BGR))
    if not ok:
        raise DatasetError("could not encode the preview")
    return buf.tobytes()


def _now() -> str:
    from datetime import UTC, datetime

    return datetime.now(UTC).isoformat(timespec="seconds")
