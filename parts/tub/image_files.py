"""Image files of a tub being recorded: written at once, made durable together at the next commit.

On Linux one ``syncfs()`` makes a whole commit's images durable: about a third of the cost of
fsyncing each file (even with the fsyncs issued in parallel), measured on ext4. Elsewhere every
file is fsynced, in parallel, then the folder.
"""

from __future__ import annotations

import ctypes
import logging
import os
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from parts.tub.format import fsync_dir, write_all

logger = logging.getLogger(__name__)

FSYNC_THREADS = 8  # fsyncs of many small files issued together share journal commits (~4x faster)

_syncfs: Callable[[int], int] | None | bool = False  # False: not looked up yet


def syncfs_function() -> Callable[[int], int] | None:
    """libc's ``syncfs(fd)`` (Linux), or None where there is none. Looked up on first use."""
    global _syncfs
    if _syncfs is False:
        _syncfs = None
        if sys.platform.startswith("linux"):
            try:
                fn = ctypes.CDLL(None, use_errno=True).syncfs  # CDLL calls release the GIL
                fn.argtypes, fn.restype = [ctypes.c_int], ctypes.c_int
                _syncfs = fn
            except (OSError, AttributeError):
                logger.debug("no syncfs in libc: tub commits fsync each image")
    return _syncfs  # type: ignore[return-value]


class ImageFiles:
    """Writes image files into ``folder``; with ``durable``, :meth:`sync` makes them survive power loss.

    ``use_syncfs``: None = syncfs where available; False = fsync each file (kept open until then).
    """

    def __init__(self, folder: Path, durable: bool, use_syncfs: bool | None = None) -> None:
        self.folder = folder
        self.durable = durable
        self._syncfs = syncfs_function() if durable and use_syncfs is not False else None
        self._fds: list[int] = []  # files held open for their fsync (no syncfs)
        self._unsynced = 0
        self._pool: ThreadPoolExecutor | None = None

    def __len__(self) -> int:
        """Files written and not yet synced."""
        return self._unsynced

    @property
    def open_files(self) -> int:
        """Files held open until the next sync (only without syncfs)."""
        return len(self._fds)

    def write(self, name: str, data: bytes) -> None:
        fd = os.open(os.path.join(self.folder, name), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            write_all(fd, data)
        except BaseException:
            os.close(fd)
            raise
        if self.durable and self._syncfs is None:
            self._fds.append(fd)  # fsynced at the commit, before the records' catalog lines
        else:
            os.close(fd)
        if self.durable:
            self._unsynced += 1

    def sync(self) -> None:
        """Make every file written since the last sync durable, with its folder entry."""
        if not self._unsynced:
            return
        if self._syncfs is not None:
            fd = os.open(self.folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
            try:
                if self._syncfs(fd) != 0:
                    err = ctypes.get_errno()
                    raise OSError(err, f"syncfs of the filesystem holding {self.folder}: {os.strerror(err)}")
            finally:
                os.close(fd)
            self._unsynced = 0
            return
        fds, self._fds = self._fds, []
        self._unsynced = 0
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=FSYNC_THREADS, thread_name_prefix="tub-fsync")
        try:
            jobs = [self._pool.submit(os.fsync, fd) for fd in fds]
            fsync_dir(self.folder)
            for job in jobs:
                job.result()
        finally:
            for fd in fds:
                os.close(fd)

    def close(self) -> None:
        """Close pending files without syncing and stop the fsync threads."""
        for fd in self._fds:
            os.close(fd)
        self._fds = []
        self._unsynced = 0
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
