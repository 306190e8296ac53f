"""``Committer``: makes a tub's written records durable, in order, inline or in a thread of its own.

A commit job, in this order: makes the image files written so far durable, appends the records'
catalog lines in one write (fsynced), starts the next catalog file when asked, then replaces
manifest.json with the text it carries. Jobs run one at a time in the order they were submitted,
so a catalog line never reaches the disk before its images, and manifest.json never lists records
that the catalogs do not hold durably.

Inline (``background=False``, a plain ``Tub``), a job runs in the caller's thread and a failure
raises there. In the background (``TubWriter`` with fsync), a thread runs the jobs while the
writer goes on writing the next records: the time the disk takes to write back and flush leaves
the writer's path. The writer may run one window ahead: a new job waits while one is being
committed.

In the background, where one ``syncfs`` makes the images durable (ext4, xfs, btrfs, f2fs) and the
catalog is on the same filesystem, the catalog is not fsynced at each commit: the next commit's
``syncfs`` makes the lines appended before it durable together with its own images, so a commit
that replaces no manifest flushes the device once instead of twice (a slow SD card takes
milliseconds per flush). Such lines are fsynced on their own when no commit follows within
twice ``fsync_ms``, before manifest.json is replaced, before a catalog is closed, and at flush and
close. A power cut then loses at most the window whose lines await the next commit, the window
being committed and the one being written.

A new catalog file (DonkeyCar: every max_len records) appears with its first lines: the job
that asks for it closes the current catalog, and the next job's lines are written to a hidden
staged file (synced), then the new catalog's ``.catalog_manifest``, then the manifest.json that
lists it, and only then is the staged file renamed into place (:mod:`parts.tub.births`). A kill at
any instant therefore never leaves an empty catalog behind, which DonkeyCar cannot open (``cannot
mmap an empty file``), nor records in a catalog manifest.json does not list (DonkeyCar would
silently read fewer); a listed catalog still staged is put in place by the next writable open.

A job that fails is kept: records submitted later are merged into it (one sync, one append) and
it is tried again at the next submission (inline) or after ``RETRY_S`` (background), so nothing
is dropped and nothing is written twice. When a sync that lines were waiting for fails, those
lines are cut from the catalog and appended again by the retry: after a failed fsync, Linux may
report the next one as a success although the data never reached the disk.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

from parts.tub.births import put_in_place, staged_catalog
from parts.tub.catalog import CatalogFile, write_catalog_manifest
from parts.tub.errors import TubError
from parts.tub.format import IMAGE_CRCS, IMAGES, O_BINARY, atomic_write, fsync_dir, write_all
from parts.tub.image_files import ImageFiles

logger = logging.getLogger(__name__)

RETRY_S = 1.0  # background: wait between attempts of a failing commit (a full or failing disk)
_LOG_EVERY_S = 5.0  # background: at most one logged failure per this many seconds


@dataclass(eq=False)  # jobs are told apart by identity
class _Job:
    lines: list[str]                                # catalog lines, each ending in a newline
    next_catalog: tuple[Path, int] | None = None    # then start this catalog (path, start index)
    manifest: str | None = None                     # then write this manifest.json text
    durable: bool = False                           # make every line durable now (flush, close)
    crcs: list[str] = field(default_factory=list)   # IMAGE_CRCS lines of these records (after them)

    def absorb(self, later: _Job) -> None:
        """Take a later job's work (only while this one starts no catalog: lines must stay in it)."""
        self.lines.extend(later.lines)
        self.crcs.extend(later.crcs)
        self.next_catalog = later.next_catalog
        if later.manifest is not None:
            self.manifest = later.manifest
        self.durable = self.durable or later.durable


class Committer:
    """Runs a tub's commit jobs in order (see the module docstring).

    Owns the catalog being appended to; the tub's writer threads only write image files and
    submit jobs.
    """

    def __init__(self, tub_path: Path, images: ImageFiles, catalog: CatalogFile, *, durable: bool,
                 background: bool, fsync_ms: float = 500.0, birth: Path | None = None) -> None:
        self.tub_path = tub_path
        # a new tub in its nursery: renamed to ``birth`` by the first commit of a record
        self.birth = birth
        self.images = images
        self.catalog: CatalogFile | None = catalog  # None between a rollover and its first lines
        self._next: tuple[Path, int] | None = None  # the catalog to create with the next lines
        self._held_manifest: str | None = None      # manifest.json text that lists it
        self._crc_failed = False                     # IMAGE_CRCS could not be written (said once)
        self.durable = durable
        # Catalog lines made durable by the next commit's syncfs (see the module docstring): the
        # lines appended since the last sync that covered them, and the catalog's size before.
        self._ride_along = background and durable and images.uses_syncfs \
            and _same_filesystem(catalog.path.parent, images.folder)
        self._unsynced: list[str] = []
        self._durable_size = 0
        self._unsynced_at = 0.0  # time.monotonic() of the oldest unsynced line
        # Lines no commit took along are fsynced after twice the window's age bound: at a steady
        # loop rate the next commit comes before, with its syncfs.
        self._idle_s = 2 * fsync_ms / 1000.0
        self._jobs: deque[_Job] = deque()
        self._running: _Job | None = None     # the job being committed (background)
        self._error: Exception | None = None  # the last attempt's failure; None after a success
        self._failures = 0                    # failed attempts so far
        self._urgent = False                  # wait() asks for a retry now
        self._closing = False
        self._dead: BaseException | None = None  # what ended the commit thread unexpectedly
        self._logged_at = -_LOG_EVERY_S
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None
        if background:
            self._thread = threading.Thread(target=self._loop, name=f"tub-commit {tub_path.name}",
                                            daemon=True)
            self._thread.start()

    # -- submitting ------------------------------------------------------------------------------
    def submit(self, lines: list[str], next_catalog: tuple[Path, int] | None = None,
               manifest: str | None = None, durable: bool = False, crcs: list[str] | None = None) -> None:
        """Queue a commit (inline: run it now, raising on failure; the job is kept for a retry).

        ``durable``: every catalog line is made durable by this job, none waits for a later one.
        """
        job = _Job(lines, next_catalog, manifest, durable, list(crcs or []))
        with self._cond:
            if self._thread is not None:
                # one window ahead at most: wait while a job is being committed
                self._cond.wait_for(lambda: self._running is None or self._dead is not None)
                self._check_alive()
            last = self._jobs[-1] if self._jobs else None
            if last is not None and last is not self._running and last.next_catalog is None:
                last.absorb(job)
            else:
                self._jobs.append(job)
            self._cond.notify_all()
        if self._thread is None:
            self._drain()

    @property
    def failing_records(self) -> int:
        """Inline: catalog lines of a job whose last attempt failed (0 when commits succeed, and
        always 0 in the background, which retries on its own)."""
        if self._error is None or self._thread is not None:
            return 0
        return self._pending_lines()

    def wait(self) -> None:
        """Return when every submitted job is committed; raise the failure if one fails."""
        if self._thread is None:
            self._drain()
            return
        with self._cond:
            seen = self._failures
            self._urgent = True  # a failed job is retried now instead of after RETRY_S
            self._cond.notify_all()
            while self._jobs:
                self._check_alive()
                if self._failures > seen:
                    raise TubError(f"{self.tub_path}: cannot commit {self._pending_lines()} records: "
                                   f"{self._error}") from self._error
                self._cond.wait()

    def close(self) -> None:
        """Commit what is queued, write the catalog's line index, close it and stop the thread.

        After a failed commit (raised already), the records it holds are reported lost.
        """
        try:
            if self._error is None and self._dead is None:
                self.wait()
                if self.catalog is not None:
                    self.catalog.save_manifest(durable=self.durable)
        finally:
            with self._cond:
                self._closing = True
                self._cond.notify_all()
            if self._thread is not None:
                self._thread.join()
                self._thread = None
            try:
                self._sync_lines()  # lines of earlier commits, when the last one failed
            except OSError as exc:
                logger.error("%s: cannot fsync the catalog at close: %s", self.tub_path, exc)
            if self.catalog is not None:
                self.catalog.close()
            lost = self._pending_lines()
            if lost:
                logger.error("%s: closed with %d records not committed (%s)", self.tub_path, lost,
                             self._error or self._dead)

    # -- running jobs ----------------------------------------------------------------------------
    def _pending_lines(self) -> int:
        return sum(len(j.lines) for j in self._jobs)

    def _check_alive(self) -> None:
        if self._dead is not None:
            raise TubError(f"{self.tub_path}: the commit thread failed ({self._dead!r}); "
                           f"{self._pending_lines()} records not committed") from self._dead

    def _drain(self) -> None:
        """Inline: run the queued jobs in order; the first failure raises and keeps its job."""
        while self._jobs:
            job = self._jobs[0]
            try:
                self._commit(job)
            except Exception as exc:
                self._error = exc
                self._failures += 1
                raise
            self._error = None
            self._jobs.popleft()

    def _loop(self) -> None:
        """Background thread; if it ever fails, waiting callers get the error instead of hanging."""
        try:
            self._run_jobs()
        except BaseException as exc:
            logger.exception("%s: the commit thread failed", self.tub_path)
            with self._cond:
                self._dead = exc
                self._running = None
                self._cond.notify_all()

    def _run_jobs(self) -> None:
        """Run jobs as they come; back off after a failure; fsync lines no commit takes along."""
        while True:
            with self._cond:
                if self._unsynced and not self._jobs and not self._closing:
                    left = self._unsynced_at + self._idle_s - time.monotonic()
                    if not self._cond.wait_for(lambda: self._jobs or self._closing, timeout=max(0.0, left)):
                        job = self._running = _Job([], durable=True)  # an fsync of those lines
                        self._jobs.appendleft(job)
                self._cond.wait_for(lambda: self._jobs or self._closing)
                if self._closing and (not self._jobs or self._error is not None):
                    return
                job = self._running = self._jobs[0]
            try:
                self._commit(job)
                failure = None
            except Exception as exc:
                failure = exc
            with self._cond:
                self._running = None
                if failure is None:
                    self._jobs.popleft()  # the job run is always the first
                    if self._error is not None:
                        logger.warning("%s: commits succeed again", self.tub_path)
                    self._error = None
                else:
                    self._error = failure
                    self._failures += 1
                    self._log_failure(failure)
                self._cond.notify_all()
                if failure is not None:
                    self._urgent = False
                    self._cond.wait_for(lambda: self._urgent or self._closing, timeout=RETRY_S)

    def _log_failure(self, exc: Exception) -> None:
        now = time.monotonic()
        if now - self._logged_at >= _LOG_EVERY_S:
            self._logged_at = now
            logger.error("%s: commit failed, %d records not durable yet; retrying every %.0f s: %s",
                         self.tub_path, self._pending_lines(), RETRY_S, exc)

    def _commit(self, job: _Job) -> None:
        """One job, step by step; a step that succeeded is not repeated when the job is retried."""
        if job.lines and self.catalog is None:
            self._start_catalog(job)
        if job.lines:
            catalog = self.catalog
            assert catalog is not None  # noqa: S101 - started above
            # With images to sync, that syncfs also writes the lines appended before it, and this
            # job's lines wait for the next one; else the catalog is fsynced as usual.
            ride = self._ride_along and len(self.images) > 0
            try:
                if self.durable:
                    self.images.sync()  # the images before their catalog lines
                if ride:
                    self._unsynced = []
                    self._durable_size = catalog.size
                catalog.append(job.lines, durable=self.durable and not ride)
            except Exception:
                self._take_back_unsynced(job)  # their sync failed, or may have
                raise
            if ride:
                self._unsynced = job.lines
                self._unsynced_at = time.monotonic()
            elif self.durable:
                self._unsynced = []  # the fsync covered earlier lines too
            job.lines = []
        if job.crcs:  # their records' lines are in the catalog now
            self._append_crcs(job.crcs)
            job.crcs = []
        if job.durable or job.manifest is not None or job.next_catalog is not None:
            try:  # before a manifest lists them, their catalog closes, or flush() returns
                self._sync_lines()
            except Exception:
                self._take_back_unsynced(job)
                raise
            job.durable = False
        if job.next_catalog is not None:
            if self.catalog is not None:
                self.catalog.save_manifest(durable=self.durable)
                self.catalog.close()
                self.catalog = None
            self._next = job.next_catalog  # created with its first lines (see the module docstring)
            job.next_catalog = None
        if job.manifest is not None:
            if self.catalog is None:  # it lists a catalog that has no file yet: wait for it
                self._held_manifest = job.manifest
            else:
                atomic_write(self.tub_path / "manifest.json", job.manifest, durable=self.durable)
            job.manifest = None
        if self.birth is not None and self.catalog is not None and self.catalog.size:
            self._be_born(self.birth)

    def _be_born(self, final: Path) -> None:
        """Rename a new tub's nursery, whose first records are durable now, to its path: the tub
        appears with records, never with the empty catalog DonkeyCar cannot open (parts.tub.births).
        A failure fails the job, which retries only this step."""
        assert self.catalog is not None  # noqa: S101 - checked by the caller
        self._sync_lines()
        self.catalog.save_manifest(durable=self.durable)  # DonkeyCar seeks by its line lengths
        with self.images.moving():  # no image lands in the old name meanwhile
            put_in_place(self.tub_path, final, durable=self.durable)
            self.images.folder = final / IMAGES
            self.catalog.path = final / self.catalog.path.name
            self.tub_path = final
        self.birth = None
        logger.debug("%s: created with its first records", final)

    def _start_catalog(self, job: _Job) -> None:
        """Create the next catalog holding ``job``'s lines (after their images): staged in a hidden
        file, then its ``.catalog_manifest``, then the manifest.json held back for it (which lists
        it), then renamed into place (parts.tub.births: DonkeyCar never silently reads fewer)."""
        assert self._next is not None  # noqa: S101 - a rollover job ran before
        name, start = self._next
        path = self.tub_path / name.name  # named before the tub's birth perhaps: its folder now
        if self.durable:
            self.images.sync()  # the images before their catalog lines
        data = "".join(job.lines).encode()
        staged = staged_catalog(path)
        fd = os.open(staged, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | O_BINARY, 0o644)  # a retry rewrites it whole
        try:
            write_all(fd, data)
            if self.durable:
                os.fsync(fd)
        finally:
            os.close(fd)
        write_catalog_manifest(path, start, [len(line) for line in job.lines],
                               durable=self.durable)
        if self._held_manifest is not None:
            atomic_write(self.tub_path / "manifest.json", self._held_manifest, durable=self.durable)
            self._held_manifest = None
        os.replace(staged, path)
        if self.durable:
            fsync_dir(path.parent)
        self.catalog = CatalogFile.open_append(path, start, durable=self.durable)
        self._next = None
        self._unsynced, self._durable_size = [], self.catalog.size
        job.lines = []

    def _append_crcs(self, lines: list[str]) -> None:
        """Append the records' image checksums to IMAGE_CRCS. Never fails a commit: a line lost
        (a crash, a full disk) leaves its images unchecked; a line whose record a crash lost names
        a session no later record has (sessions are never reused), so it is never applied."""
        try:
            fd = os.open(self.tub_path / IMAGE_CRCS, os.O_WRONLY | os.O_CREAT | os.O_APPEND | O_BINARY, 0o644)
            try:
                write_all(fd, "".join(lines).encode())
            finally:
                os.close(fd)
        except OSError as exc:
            if not self._crc_failed:
                self._crc_failed = True
                logger.warning("%s: cannot record image checksums (%s): tub check will not verify them",
                               self.tub_path, exc)

    def _sync_lines(self) -> None:
        """fsync the catalog lines that were appended without one."""
        if self._unsynced and self.catalog is not None:
            os.fsync(self.catalog.fd)
            self._unsynced = []

    def _take_back_unsynced(self, job: _Job) -> None:
        """Cut the lines that waited for a failed sync from the catalog; ``job`` appends them again."""
        if self._unsynced and self.catalog is not None:
            self.catalog.cut_back(self._durable_size, len(self._unsynced))
            job.lines[:0] = self._unsynced
            self._unsynced = []


def _same_filesystem(a: Path, b: Path) -> bool:
    try:
        return os.stat(a).st_dev == os.stat(b).st_dev
    except OSError:
        return False
