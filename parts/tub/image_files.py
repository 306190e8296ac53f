"""Image files of a tub being recorded: written at once, fsynced together at the next commit."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from parts.tub.format import fsync_dir, write_all

FSYNC_THREADS = 8  # fsyncs of many small files issued together share journal commits (~4x faster)


class ImageFiles:
    """Writes image files into ``folder``; with ``durable`` keeps them open until :meth:`sync`."""

    def __init__(self, folder: Path, durable: bool) -> None:
        self.folder = folder
        self.durable = durable
        self._fds: list[int] = []
        self._pool: ThreadPoolExecutor | None = None

    def __len__(self) -> int:
        """Files written and not yet synced."""
        return len(self._fds)

    def write(self, name: str, data: bytes) -> None:
        fd = os.open(os.path.join(self.folder, name), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            write_all(fd, data)
        except BaseException:
            os.close(fd)
            raise
        if self.durable:
            self._fds.append(fd)  # fsynced at the commit, before the records' catalog lines
        else:
            os.close(fd)

    def sync(self) -> None:
        """fsync every pending file (in parallel) and the folder, then close them."""
        fds, self._fds = self._fds, []
        if not fds:
            return
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
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
