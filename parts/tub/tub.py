"""``Tub``: one DonkeyCar tub v2 folder, opened for reading or for crash-safe appending.

Writing order per commit (the durability window, docs/data-format.md): image files are written
as records arrive; at a commit the images are made durable (one ``syncfs`` on Linux filesystems
where that flushes the device, else an fsync of each, in parallel, and of the images folder), then
the records' catalog lines are appended in one write and fsynced (``parts.tub.committer``, in the
caller's thread or, with ``commit_thread``, in a thread of its own). manifest.json is replaced
atomically at most once a second and at every session start, new catalog, delete, restore and
close (recovery never needs it current). A crash therefore loses at most the records since the
last completed commit, and a catalog line never reaches the disk before its images.
"""

from __future__ import annotations

import atexit
import json
import logging
import os
import shutil
import time
import weakref
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping, MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from parts.tub.births import absent_or_empty, complete_staged, start_nursery
from parts.tub.catalog import CatalogFile, parse_line, record_index, scan_catalog
from parts.tub.codec import encode_image
from parts.tub.committer import Committer
from parts.tub.errors import TubError, TubSchemaError
from parts.tub.format import (
    IMAGE_TYPES,
    IMAGES,
    INDEX,
    MANIFEST,
    SESSION,
    TIMESTAMP,
    catalog_manifest_name,
    catalog_name,
    check_schema,
    dumps_record,
    encode_value,
    image_file_name,
)
from parts.tub.image_files import ImageFiles
from parts.tub.manifest import Manifest, parse_manifest, parse_metadata
from parts.tub.recovery import inspect_tub

logger = logging.getLogger(__name__)

# manifest.json is rewritten at most this often while recording (and at every delete, restore,
# new catalog, first commit of a session and close).
MANIFEST_INTERVAL_S = 1.0


@dataclass(frozen=True)
class StoredImage:
    """An image value already written as the file ``name`` (of record ``index``) in ``images/``."""

    name: str
    index: int
    crc: int | None = None  # CRC-32 of the file's bytes (checked by `tub check`)


def _close_at_exit(tub: Tub) -> Callable[[], None]:
    """An atexit hook that closes the tub if the program forgot to (holds only a weak reference)."""
    ref = weakref.ref(tub)

    def hook() -> None:
        t = ref()
        if t is not None and not t.closed:
            logger.warning("%s: closing the tub at exit (close() was not called)", t.path)
            t.close()

    return hook


class Tub:
    """A tub folder (DonkeyCar tub v2), compatible both ways.

    Args:
        path: the tub folder; created when writable and missing.
        inputs, types: the record schema (memory keys and their types, one of
            :data:`parts.tub.format.ALL_TYPES` each). Needed for a new tub; for an existing
            tub they must equal the stored ones or be omitted (then the stored schema is used).
        metadata: user metadata (dict or DonkeyCar's ``["k:v"]``), merged into manifest line 3.
        max_catalog_len: records per catalog file for a new tub.
        read_only: never write; recovery is then done in memory only.
        fsync: make each commit durable against power loss (off: durable only against a crash of
            the process).
        fsync_records, fsync_ms: the durability window: commit after this many records or when
            the oldest uncommitted record is this old, whichever comes first (0 = every record).
        jpeg_quality: JPEG quality (1-100) for ``image_array`` values.
        commit_thread: commit in a thread of the tub's own, so that writing the next records
            overlaps with the disk's flush (``TubWriter`` with fsync). ``commit()`` then starts a
            commit and ``flush()`` waits for it; a crash may lose one more window (the one being
            committed while the next is written), a power cut two more (docs/data-format.md).
        log_problems: log what recovery found as a warning (False: a reader of a tub being recorded,
            whose manifest lags its catalogs by design; :attr:`problems` lists it all the same).
    """

    def __init__(self, path: str | os.PathLike[str], inputs: list[str] | None = None,
                 types: list[str] | None = None, metadata: Mapping[str, Any] | Iterable[str] | None = None,
                 max_catalog_len: int = 1000, read_only: bool = False, *, fsync: bool = True,
                 fsync_records: int = 20, fsync_ms: float = 500.0, jpeg_quality: int = 75,
                 commit_thread: bool = False, log_problems: bool = True, _skeleton: bool = False) -> None:
        if not isinstance(max_catalog_len, int) or max_catalog_len < 1:
            raise ValueError(f"max_catalog_len must be a positive int, got {max_catalog_len!r}")
        if fsync_records < 0 or fsync_ms < 0:
            raise ValueError("fsync_records and fsync_ms must be >= 0")
        if not 1 <= int(jpeg_quality) <= 100:
            raise ValueError(f"jpeg_quality must be within 1..100, got {jpeg_quality!r}")
        self._final = Path(os.path.expanduser(os.fspath(path))).absolute()
        self.read_only = read_only
        self._commit_thread = commit_thread
        self.fsync = fsync
        self.fsync_records = fsync_records
        self.fsync_ms = fsync_ms
        self.jpeg_quality = int(jpeg_quality)
        self._closed = False
        self._committer: Committer | None = None  # None: read-only
        self._images = ImageFiles(self._final / IMAGES, fsync)  # the tub's folder is its parent (_dir)
        self._pending_lines: list[str] = []
        self._pending_crcs: list[str] = []  # lines of IMAGE_CRCS for the pending records
        self._pending_since: float | None = None
        self._atexit: Callable[[], None] | None = None
        self._session_registered = False
        self._manifest_saved_at = -MANIFEST_INTERVAL_S
        self.written = 0  # records written by this session

        if inputs is not None or types is not None:
            check_schema(list(inputs or []), list(types or []))
        user_meta = parse_metadata(metadata)
        if not read_only and inputs is not None and not _skeleton and absent_or_empty(self._dir):
            # grows in a hidden folder, renamed into place with its first record (parts.tub.births):
            # a kill leaves no tub or one with records, never an empty catalog DonkeyCar cannot open
            nursery = start_nursery(self._dir, lambda tmp: Tub(tmp, inputs, types, metadata=user_meta,
                                                               max_catalog_len=max_catalog_len, fsync=fsync,
                                                               _skeleton=True).close(), durable=fsync)
            self._images = ImageFiles(nursery / IMAGES, fsync, movable=nursery != self._final)
        completed = [] if read_only or not self._dir.is_dir() else \
            complete_staged(self._dir, parse_manifest(self._dir / MANIFEST).manifest.paths)
        if not self._dir.exists():
            if read_only:
                raise TubError(f"{self._dir}: no such tub folder")
            if inputs is None:  # nothing to create a tub with: leave no empty folder behind
                raise TubSchemaError(f"{self._dir} is a new tub: give inputs and types")
            self._dir.mkdir(parents=True)
        elif not self._dir.is_dir():
            raise TubError(f"{self._dir} is a file, not a tub folder")
        state = inspect_tub(self._dir, max_catalog_len)
        self.problems = completed + list(state.problems)
        self.torn = dict(state.torn)  # catalog name -> bytes of its torn last line (cut when writable)
        self._dropped = list(state.dropped)  # empty trailing catalogs, removed when writable
        if read_only and not state.is_tub and inputs is None:  # with inputs: a tub to be, read as empty
            raise TubError(f"{self._dir} is not a tub: it has no manifest.json and no catalog_*.catalog")
        m = state.manifest
        if not state.has_schema or not m.inputs and not m.paths:
            if inputs is None:
                if not read_only:
                    raise TubSchemaError(f"{self._dir} is a new tub: give inputs and types")
                m.inputs, m.types = [], []
            else:
                m.inputs, m.types = list(inputs), list(types or [])
                if not state.is_tub:
                    m.max_len = max_catalog_len
                    m.manifest_metadata.setdefault("created_at", time.time())
        elif inputs is not None and (list(inputs) != m.inputs or list(types or []) != m.types):
            raise TubSchemaError(
                f"{self._dir} stores inputs {m.inputs} with types {m.types}, not {list(inputs)} "
                f"{list(types or [])}. Record into a new tub, or open this one without inputs/types.")
        new_meta = {k: v for k, v in user_meta.items() if m.metadata.get(k) != v}
        m.metadata.update(user_meta)
        self.manifest: Manifest = m
        self._types = dict(zip(m.inputs, m.types, strict=True))
        self.session_number, self.session_id = m.new_session(state.session_floor)
        if not read_only:
            self._open_for_writing(state.is_tub and not state.problems and not new_meta
                                   and not state.torn, commit_thread)
            self._atexit = _close_at_exit(self)
            atexit.register(self._atexit)
        if self.problems and log_problems:
            logger.warning("%s: recovered: %s", self._dir, "; ".join(self.problems))

    # -- properties --------------------------------------------------------------------------------
    @property
    def path(self) -> Path:
        """The tub folder (a new tub appears there with its first record)."""
        return self._final

    @property
    def _dir(self) -> Path:
        """Where the tub's files are now: a new tub's hidden nursery until its first commit."""
        return self._images.folder.parent

    @property
    def unborn(self) -> bool:
        """Whether this new tub has no record yet and is still in its hidden nursery."""
        return self._dir != self._final

    @property
    def inputs(self) -> list[str]:
        return self.manifest.inputs

    @property
    def types(self) -> list[str]:
        return self.manifest.types

    @property
    def metadata(self) -> dict[str, Any]:
        return self.manifest.metadata

    @property
    def current_index(self) -> int:
        """The index the next record gets (records ever written, deleted ones included)."""
        return self.manifest.current_index

    @property
    def deleted_indexes(self) -> set[int]:
        return set(self.manifest.deleted_indexes)

    @property
    def max_len(self) -> int:
        return self.manifest.max_len

    @property
    def catalog_paths(self) -> list[Path]:
        return [self._dir / p for p in self.manifest.paths]

    @property
    def images_path(self) -> Path:
        return self._dir / IMAGES

    def __len__(self) -> int:
        return self.manifest.current_index - len(self.manifest.deleted_indexes)

    def __repr__(self) -> str:
        return f"Tub({str(self._dir)!r}, records={len(self)}, read_only={self.read_only})"

    def __enter__(self) -> Tub:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- writing -------------------------------------------------------------------------------------
    def _open_for_writing(self, clean: bool, commit_thread: bool) -> None:
        m = self.manifest
        self.images_path.mkdir(exist_ok=True)
        if not m.paths:
            m.paths.append(catalog_name(0))
        start = (len(m.paths) - 1) * m.max_len
        catalog = CatalogFile.open_append(self._dir / m.paths[-1], start, durable=self.fsync)
        if not clean:
            m.save(self._dir, durable=self.fsync)
        for name in self._dropped:  # no longer listed: now their files can go
            for dropped in (self._dir / name, self._dir / catalog_manifest_name(name)):
                dropped.unlink(missing_ok=True)
        self._committer = Committer(self._dir, self._images, catalog, durable=self.fsync,
                                    background=commit_thread, fsync_ms=self.fsync_ms,
                                    birth=self._final if self.unborn else None)

    def _check_writable(self) -> None:
        if self.read_only:
            raise TubError(f"{self._dir} was opened read-only")
        if self._closed:
            raise TubError(f"{self._dir} is closed")

    def write_images(self, index: int, record: MutableMapping[str, Any]) -> None:
        """Write the record's images as the files of record ``index``, replacing each value by its
        :class:`StoredImage`. Safe in several threads at once (``TubWriter`` writes a batch's
        images in parallel); ``write_record(record, index=index)`` then stores the record.
        """
        self._check_writable()
        for key, value in record.items():
            tp = self._types.get(key)
            if tp in IMAGE_TYPES and value is not None and not isinstance(value, StoredImage):
                data, ext = encode_image(value, tp, self.jpeg_quality)
                name = image_file_name(index, key, ext)
                self._images.write(name, data)
                record[key] = StoredImage(name, index, zlib.crc32(data))

    def write_record(self, record: Mapping[str, Any], *, timestamp_ms: int | None = None,
                     index: int | None = None) -> int:
        """Write one record (keys not in inputs and None values are skipped); return its index.

        ``timestamp_ms`` is the capture time stored as ``_timestamp_ms`` (default: now). Images
        (``image_array``) may be arrays (encoded to JPEG), bytes of an encoded JPEG (kept as is)
        or a :class:`StoredImage` written by :meth:`write_images` for this record. ``index``
        (default: the next one) may only be ahead of the next one when records given indexes
        could not be written: their indexes are then kept as deleted records without values, so
        that a record's index stays its position in the catalogs (what DonkeyCar relies on).
        """
        self._check_writable()
        m = self.manifest
        if index is None:
            index = m.current_index
        elif index < m.current_index:
            raise ValueError(f"{self._dir}: record index {index} is taken; the next one is {m.current_index}")
        for value in record.values():
            if isinstance(value, StoredImage) and value.index != index:
                raise ValueError(f"{self._dir}: image {value.name} belongs to record {value.index}, "
                                 f"not {index}")
        values = dict(record)
        self.write_images(index, values)
        contents: dict[str, Any] = {}
        for key, value in values.items():
            tp = self._types.get(key)
            if value is None or tp is None:
                continue
            contents[key] = value.name if isinstance(value, StoredImage) else encode_value(key, tp, value)
        if index > m.current_index:
            self.skip_to(index)
        self._append_line(contents, timestamp_ms)
        crcs = {k: v.crc for k, v in values.items() if isinstance(v, StoredImage) and v.crc is not None}
        if crcs:  # committed after the record's catalog line (parts.tub.committer)
            self._pending_crcs.append(json.dumps({INDEX: index, SESSION: self.session_id, "crc32": crcs},
                                                 sort_keys=True) + "\n")
        self.written += 1
        if self.commit_due():
            self.commit()
        return index

    def skip_to(self, index: int, why: str | None = "could not be written") -> None:
        """Fill the indexes from the next one up to ``index - 1`` with deleted records without
        values (a mirror of another tub keeps that tub's indexes this way). Their deletion reaches
        manifest.json before their lines reach the catalog: a crash in between leaves deleted
        indexes beyond the last record, which recovery drops. ``why`` is logged as a warning
        (None: nothing is logged)."""
        self._check_writable()
        m = self.manifest
        if index <= m.current_index:
            return
        if why is not None:
            logger.warning("%s: records %d..%d %s; kept as deleted records", self._dir, m.current_index,
                           index - 1, why)
        m.deleted_indexes.update(range(m.current_index, index))
        self._submit(force_manifest=True)
        while m.current_index < index:
            self._append_line({}, None)

    def _append_line(self, contents: dict[str, Any], timestamp_ms: int | None) -> int:
        """Give ``contents`` the next index and queue its catalog line; returns the index."""
        m = self.manifest
        index = m.current_index
        if index > 0 and index % m.max_len == 0 and len(m.paths) <= index // m.max_len:
            self._add_catalog()  # DonkeyCar: a new catalog every max_len records
        contents[TIMESTAMP] = int(round(time.time() * 1000)) if timestamp_ms is None else int(timestamp_ms)
        contents[INDEX] = index
        contents[SESSION] = self.session_id
        self._pending_lines.append(dumps_record(contents) + "\n")
        if self._pending_since is None:
            self._pending_since = time.monotonic()
        m.current_index = index + 1
        return index

    def commit_due(self) -> bool:
        """Whether the durability window is full (records or age of the oldest pending record).

        Inline, records of a commit that failed count too: every new record retries it.
        """
        failing = self._committer.failing_records if self._committer is not None else 0
        if not self._pending_lines:
            return failing > 0
        if len(self._pending_lines) + failing >= max(1, self.fsync_records):
            return True
        return (time.monotonic() - (self._pending_since or 0.0)) * 1000.0 >= self.fsync_ms

    def seconds_to_commit(self) -> float | None:
        """Seconds until the pending records must be committed (None when nothing is pending)."""
        if self._pending_since is None:
            return None
        return max(0.0, self.fsync_ms / 1000.0 - (time.monotonic() - self._pending_since))

    def commit(self) -> None:
        """Make every record written so far durable (images, then catalog lines, then manifests).

        With ``commit_thread`` this starts the commit; :meth:`flush` waits for it.
        """
        if self._committer is None:
            return
        if self._pending_lines:
            self._submit(force_manifest=False)
        elif self._committer.failing_records:
            self._committer.wait()  # retry the failed commit

    def flush(self) -> None:
        """Commit the pending records and rewrite the manifest; on return both are written, and
        durable with ``fsync``."""
        if self._committer is not None:
            self._submit(force_manifest=True, durable=True)
            self._committer.wait()

    def _submit(self, force_manifest: bool, next_catalog: tuple[Path, int] | None = None,
                durable: bool = False) -> None:
        """Hand the pending catalog lines (and the manifest when due) to the committer."""
        assert self._committer is not None
        lines, since, crcs = self._pending_lines, self._pending_since, self._pending_crcs
        self._pending_lines, self._pending_since, self._pending_crcs = [], None, []
        try:
            self._committer.submit(lines, next_catalog, self._manifest_text(force_manifest), durable, crcs)
        except TubError:  # refused (the commit thread failed): the lines stay pending
            self._pending_lines[:0] = lines
            self._pending_crcs[:0] = crcs
            self._pending_since = since
            raise

    def _manifest_text(self, force: bool) -> str | None:
        """manifest.json's new text when due: at most every MANIFEST_INTERVAL_S unless forced.

        Our recovery does not need it current (current_index is taken from the catalogs); it is
        kept close for DonkeyCar, which trusts it. Taken when the records are handed to the
        committer, it lists exactly the records committed before it is written.
        """
        m = self.manifest
        if self.written and not self._session_registered:
            m.add_session(self.session_number, self.session_id)
            self._session_registered = True
            force = True
        now = time.monotonic()
        if force or now - self._manifest_saved_at >= MANIFEST_INTERVAL_S:
            self._manifest_saved_at = now
            return m.dumps()
        return None

    def _add_catalog(self) -> None:
        """Start the next catalog file (DonkeyCar: when current_index is a multiple of max_len)."""
        m = self.manifest
        name = catalog_name(len(m.paths))
        m.paths.append(name)
        self._submit(force_manifest=True, next_catalog=(self._dir / name, m.current_index))

    # -- deleting ---------------------------------------------------------------------------------------
    def _check_indexes(self, indexes: int | Iterable[int]) -> set[int]:
        idx = {indexes} if isinstance(indexes, int) else {int(i) for i in indexes}
        bad = sorted(i for i in idx if not 0 <= i < self.current_index)
        if bad:
            raise ValueError(f"{self._dir}: indexes {bad[:5]} are outside 0..{self.current_index - 1}")
        return idx

    def delete_records(self, indexes: int | Iterable[int]) -> None:
        """Soft-delete records (DonkeyCar's ``deleted_indexes``): files stay, readers skip them."""
        self._check_writable()
        idx = self._check_indexes(indexes)
        self.manifest.deleted_indexes |= idx
        self.flush()
        if idx:
            logger.info("%s: deleted %d records (%d..%d)", self._dir, len(idx), min(idx), max(idx))

    def restore_records(self, indexes: int | Iterable[int]) -> list[int]:
        """Undo soft deletes; returns the indexes kept deleted because their records have no input
        value, only the private fields: mostly the indexes kept for records that could not be
        written (``write_record``). No reader could use them (DonkeyCar's training would fail on
        them). Told by the records' own keys, not the schema, which older tubs may name otherwise."""
        self._check_writable()
        idx = self._check_indexes(indexes) & self.manifest.deleted_indexes
        empty = {i for i, rec in self.records(include_deleted=True)
                 if i in idx and all(key.startswith("_") for key in rec)} if idx else set()
        self.manifest.deleted_indexes -= idx - empty
        self.flush()
        if empty:
            # debug: callers get the indexes (the CLI prints them)
            logger.debug("%s: %d records kept deleted: they have no input value, e.g. %d", self._dir,
                         len(empty), min(empty))
        return sorted(empty)

    def delete_last_n_records(self, n: int) -> list[int]:
        """Soft-delete the last ``n`` records that are not deleted yet; returns their indexes."""
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        deleted = self.manifest.deleted_indexes
        chosen: list[int] = []
        i = self.current_index - 1
        while i >= 0 and len(chosen) < n:
            if i not in deleted:
                chosen.append(i)
            i -= 1
        if chosen:
            self.delete_records(chosen)
        return sorted(chosen)

    # -- reading --------------------------------------------------------------------------------------
    def scan(self) -> Iterator[tuple[Path, int, dict[str, Any] | None, bytes, bool]]:
        """Every whole catalog line: (catalog, index, record or None if unparsable, raw line, salvaged).

        Deleted records are included; uncommitted records of a writable tub are committed first.
        """
        if self._committer is not None and not self._closed:
            self.commit()
            self._committer.wait()
        position = 0
        for i, catalog in enumerate(self.catalog_paths):
            start = i * self.max_len
            position = max(position, start)
            for line in scan_catalog(catalog).lines:
                rec, salvaged = parse_line(line)
                index = record_index(rec, position) if rec is not None else position
                yield catalog, index, rec, line, salvaged
                position = index + 1

    def records(self, include_deleted: bool = False) -> Iterator[tuple[int, dict[str, Any]]]:
        """(index, record) of every parsable record, skipping deleted ones unless asked."""
        deleted = self.manifest.deleted_indexes
        for catalog, index, rec, _line, _salvaged in self.scan():
            if rec is None:
                logger.error("%s: unparsable line for record %d skipped", catalog, index)
                continue
            if include_deleted or index not in deleted:
                yield index, rec

    def __iter__(self) -> Iterator[dict[str, Any]]:
        """Records (dicts) that are not deleted, like DonkeyCar's ``Tub.__iter__``."""
        return (rec for _, rec in self.records())

    # -- closing --------------------------------------------------------------------------------------
    def close(self) -> None:
        """Commit everything and close the files. Safe to call twice."""
        if self._closed:
            return
        try:
            self.flush()
        finally:
            self._closed = True
            if self._atexit is not None:
                atexit.unregister(self._atexit)
                self._atexit = None
            if self._committer is not None:
                self._committer.close()
            self._images.close()
            if self.unborn:
                self._leave_nursery()
            logger.debug("%s: closed (%d records written this session)", self._dir, self.written)

    def _leave_nursery(self) -> None:
        """At close: a new tub without records leaves nothing (never an empty tub); one whose
        records could not be committed (a failing disk) is left where they are, and named."""
        if self.manifest.current_index == 0:
            shutil.rmtree(self._dir, ignore_errors=True)
            logger.debug("%s: no record written, no tub created", self.path)
        else:
            logger.error("%s: its records could not be committed; what was written is in %s", self.path, self._dir)

    @property
    def closed(self) -> bool:
        return self._closed
