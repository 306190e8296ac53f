"""ImageFiles: when images are made durable (syncfs on Linux, else one fsync per file)."""

from __future__ import annotations

import os
import sys

import pytest

from parts.tub import image_files
from parts.tub.image_files import ImageFiles, syncfs_function


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="syncfs is Linux-only")
def test_syncfs_commit_closes_files_at_once_and_syncs_once(tmp_path, monkeypatch):
    real = syncfs_function()
    assert real is not None
    calls: list[int] = []

    def counting(fd: int) -> int:
        calls.append(os.fstat(fd).st_ino)
        return real(fd)

    monkeypatch.setattr(image_files, "_syncfs", counting)
    files = ImageFiles(tmp_path, durable=True)
    for i in range(3):
        files.write(f"{i}_cam_.jpg", b"\xff\xd8" + bytes([i]) * 100 + b"\xff\xd9")
    assert len(files) == 3 and files.open_files == 0  # nothing held open with syncfs
    files.sync()
    assert calls == [tmp_path.stat().st_ino]  # one call, on the images folder
    assert len(files) == 0
    files.sync()  # nothing pending: no call
    assert len(calls) == 1
    assert (tmp_path / "2_cam_.jpg").read_bytes()[2] == 2


def test_without_syncfs_each_file_and_the_folder_are_fsynced(tmp_path, monkeypatch):
    synced: list[int] = []
    real_fsync = os.fsync

    def counting(fd: int) -> None:
        synced.append(os.fstat(fd).st_ino)
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", counting)
    files = ImageFiles(tmp_path, durable=True, use_syncfs=False)
    for i in range(4):
        files.write(f"{i}.jpg", b"x" * 10)
    assert files.open_files == 4  # held open for their fsync
    files.sync()
    inodes = {(tmp_path / f"{i}.jpg").stat().st_ino for i in range(4)}
    assert set(synced) == inodes | {tmp_path.stat().st_ino} and len(synced) == 5
    assert files.open_files == 0 and len(files) == 0
    files.close()


def test_not_durable_writes_and_never_syncs(tmp_path, monkeypatch):
    monkeypatch.setattr(os, "fsync", lambda fd: pytest.fail("fsync called"))
    monkeypatch.setattr(image_files, "_syncfs", lambda fd: pytest.fail("syncfs called"))
    files = ImageFiles(tmp_path, durable=False)
    files.write("a.jpg", b"abc")
    assert len(files) == 0
    files.sync()
    assert (tmp_path / "a.jpg").read_bytes() == b"abc"
