"""Image files of a tub being recorded: written at once, made durable together at the next commit.

On Linux, where the images folder is on a filesystem whose ``syncfs()`` flushes the device's
write cache (ext4, xfs, btrfs, f2fs; tmpfs has nothing to flush), one ``syncfs()`` makes a whole
commit's images durable: about a third of the cost of fsyncing each file, even with the fsyncs
issued in parallel (``bench/commit.py``). Elsewhere (FAT and exFAT SD cards or USB sticks, FUSE
mounts, macOS, Windows) every file is fsynced, in parallel, then the folder.

After a failed sync the pending files are written again before the next one: Linux marks pages
whose write-back failed clean, and reports the error once, so a plain retry would succeed with
the images never on the disk. Their bytes are kept until a sync covers them (a few windows of
~3 KB JPEGs while the disk works). While a disk keeps failing, memory stays bounded: beyond
``KEEP_BYTES`` only the sizes are kept, and those files are read back for their rewrite, which is
best effort (the kernel may have dropped its copy; a file whose size changed is not rewritten).
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import platform
import re
import sys
import threading
import weakref
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from parts.tub.format import O_BINARY, fsync_dir, write_all
from parts.tub.pools import submit_or_run

logger = logging.getLogger(__name__)

FSYNC_THREADS = 8  # fsyncs of many small files issued together share journal commits (~4x faster)
KEEP_BYTES = 64 << 20  # bytes of pending images kept for a rewrite after a failed sync (~20k JPEGs)

# Filesystems whose syncfs() writes everything and flushes the device cache, as fsync does.
# vfat/exfat write the blocks but send no cache flush; FUSE mounts do not pass syncfs on.
SYNCFS_FILESYSTEMS = frozenset({"ext4", "ext3", "xfs", "btrfs", "f2fs", "tmpfs"})

_syncfs: Callable[[int], int] | None | bool = False  # False: not looked up yet


SYNCFS_REPORTS_ERRORS = (5, 8)  # Linux reports writeback errors from syncfs() since 5.8


def kernel_version(release: str | None = None) -> tuple[int, int]:
    """(major, minor) of the running kernel (``platform.release()``), (0, 0) when unreadable."""
    match = re.match(r"(\d+)\.(\d+)", release if release is not None else platform.release())
    return (int(match[1]), int(match[2])) if match else (0, 0)


def syncfs_function() -> Callable[[int], int] | None:
    """libc's ``syncfs(fd)`` on Linux 5.8 or later, else None. Looked up on first use.

    Older kernels (Jetson Nano's 4.9) return success from syncfs() even when writing back failed,
    so there each image is fsynced, which reports it.
    """
    global _syncfs
    if _syncfs is False:
        _syncfs = None
        if sys.platform.startswith("linux") and kernel_version() >= SYNCFS_REPORTS_ERRORS:
            try:
                fn = ctypes.CDLL(None, use_errno=True).syncfs  # CDLL calls release the GIL
                fn.argtypes, fn.restype = [ctypes.c_int], ctypes.c_int
                _syncfs = fn
            except (OSError, AttributeError):
                logger.debug("no syncfs in libc: tub commits fsync each image")
    return _syncfs  # type: ignore[return-value]


def filesystem_type(path: str | os.PathLike[str], mounts: str = "/proc/self/mounts") -> str | None:
    """The type of the filesystem holding ``path`` ("ext4", "vfat", ...) from the mount table, or
    None when it cannot be told (no /proc: not Linux)."""
    target = os.path.realpath(path)
    best, best_type = "", None
    try:
        with open(mounts, encoding="utf-8", errors="replace") as f:
            for line in f:
                fields = line.split()
                if len(fields) < 3:
                    continue
                # the mount table escapes spaces and the like as octal: "\040"
                point = fields[1].encode().decode("unicode_escape")
                inside = target == point or target.startswith(point.rstrip("/") + "/")
                if inside and len(point) >= len(best):
                    best, best_type = point, fields[2]
    except OSError:
        return None
    return best_type


class ImageFiles:
    """Writes image files into ``folder``; with ``durable``, :meth:`sync` makes them survive power loss.

    ``use_syncfs``: None = syncfs where it is as strong as fsync (see the module docstring);
    False = fsync each file.
    """

    def __init__(self, folder: Path, durable: bool, use_syncfs: bool | None = None, movable: bool = False) -> None:
        self.folder = folder
        self.durable = durable
        self._use_syncfs = use_syncfs
        self._syncfs: Callable[[int], int] | None | bool = False  # False: decided at the first sync
        # names of files written, not yet synced (kept until a sync succeeds), with their bytes, or their
        # size once KEEP_BYTES are held (only a failed sync trims: the list is short otherwise)
        self._pending: list[tuple[str, bytes | int]] = []
        self._rewrite = False  # the last sync failed: write the pending files again first
        self._pool: ThreadPoolExecutor | None = None
        # The folder, opened once for syncfs; closed by close() or when this object is collected.
        # The lock keeps close() from closing it under a sync that still runs (a writer thread
        # that outlived its shutdown timeout): a reused descriptor number could sync another disk.
        self._folder_fd = -1
        self._folder_close: weakref.finalize | None = None
        self._folder_lock = threading.Lock()
        # A new tub's folder is renamed once (parts.tub.births): until then writes take this lock,
        # so none lands in the folder's old name while it moves.
        self._movable = movable
        self._move_lock = threading.Lock()

    def __len__(self) -> int:
        """Files written and not yet synced."""
        return len(self._pending)

    @property
    def uses_syncfs(self) -> bool:
        return self._syncfs_for_folder() is not None

    def _syncfs_for_folder(self) -> Callable[[int], int] | None:
        """syncfs when the folder's filesystem flushes the device with it (looked up once, when
        first needed: a tub opened only to be read never reads the mount table)."""
        if self._syncfs is False:
            self._syncfs = None
            if self.durable and self._use_syncfs is not False:
                fs = filesystem_type(self.folder)
                self._syncfs = syncfs_function() if fs in SYNCFS_FILESYSTEMS else None
                if self._syncfs is None:
                    logger.debug("%s is on %s: commits fsync each image", self.folder,
                                 fs or "an unknown filesystem")
        return self._syncfs  # type: ignore[return-value]

    def write(self, name: str, data: bytes) -> None:
        if self._movable:
            with self._move_lock:
                _write_file(os.path.join(self.folder, name), data)
        else:
            _write_file(os.path.join(self.folder, name), data)
        if self.durable:
            self._pending.append((name, data))

    @contextlib.contextmanager
    def moving(self) -> Iterator[None]:
        """While inside, no file is written: the caller renames the folder and sets :attr:`folder`
        to its new path. A movable folder moves once."""
        with self._move_lock:
            yield
            self._movable = False

    def sync(self) -> None:
        """Make every file written before this call (and not synced yet) durable, with its folder
        entry. A thread may write further files meanwhile: they stay pending for the next sync.

        On an error nothing is forgotten: the next sync writes these files again, then syncs them.
        """
        count = len(self._pending)  # files written before the sync began
        if not count:
            return
        try:
            self._sync(count)
        except BaseException:
            self._rewrite = True
            self._trim_kept_bytes()
            raise
        self._rewrite = False
        del self._pending[:count]  # in place: write() in another thread appends to this list

    def _sync(self, count: int) -> None:
        if self._rewrite:
            lost = []
            for name, data in self._pending[:count]:
                path = os.path.join(self.folder, name)
                if isinstance(data, int):
                    data = _read_back(path, data)
                if data is None:
                    lost.append(path)
                else:
                    _write_file(path, data)
            if lost:
                logger.error("%s: %d images written while the disk failed could not be written again "
                             "(gone, or changed size), e.g. %s; readers report them if they are damaged",
                             self.folder, len(lost), os.path.basename(lost[0]))
        syncfs = self._syncfs_for_folder()
        if syncfs is not None:
            with self._folder_lock:
                if self._folder_fd < 0:  # kept open: two system calls less per commit
                    self._folder_fd = os.open(self.folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
                    self._folder_close = weakref.finalize(self, os.close, self._folder_fd)
                    # not among the exit hooks: a writer's own exit hook commits through this
                    # descriptor, and hooks registered before the first finalize run after it
                    self._folder_close.atexit = False
                if syncfs(self._folder_fd) != 0:
                    err = ctypes.get_errno()
                    raise OSError(err, f"syncfs of the filesystem holding {self.folder}: {os.strerror(err)}")
        else:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(max_workers=FSYNC_THREADS, thread_name_prefix="tub-fsync")
            jobs = [submit_or_run(self._pool, _fsync_file, os.path.join(self.folder, name))
                    for name, _data in self._pending[:count]]
            errors = []
            for job in jobs:  # wait for every job, even after a failure
                if (exc := job.exception()) is not None:
                    errors.append(exc)
            if errors:
                raise errors[0]
            fsync_dir(self.folder)

    def _trim_kept_bytes(self) -> None:
        """Keep the bytes of the oldest pending files up to KEEP_BYTES, the sizes of the others.

        Runs in the syncing thread only; writers append meanwhile, which leaves items in place.
        """
        kept = 0
        for i, (name, data) in enumerate(self._pending):
            if isinstance(data, bytes):
                kept += len(data)
                if kept > KEEP_BYTES:
                    self._pending[i] = (name, len(data))

    def close(self) -> None:
        """Forget pending files (not synced) and stop the fsync threads."""
        self._pending = []
        with self._folder_lock:
            if self._folder_close is not None:
                self._folder_close()  # os.close, once
                self._folder_close, self._folder_fd = None, -1
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None


def _write_file(path: str, data: bytes) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | O_BINARY, 0o644)
    try:
        write_all(fd, data)
    finally:
        os.close(fd)


def _read_back(path: str, size: int) -> bytes | None:
    """The bytes of a file written earlier, or None when it is gone or its size changed."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except FileNotFoundError:
        return None
    return data if len(data) == size else None


def _fsync_file(path: str) -> None:
    # opened for writing: Windows flushes only handles with write access
    try:
        fd = os.open(path, os.O_WRONLY | O_BINARY)
    except FileNotFoundError:  # removed meanwhile (by hand): nothing to sync, readers report it
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
