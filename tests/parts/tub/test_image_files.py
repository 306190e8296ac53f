"""ImageFiles: when images are made durable (syncfs on Linux filesystems where it flushes the
device, else one fsync per file), and the Tub's order: images durable before their catalog lines."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from parts.tub import image_files
from parts.tub.image_files import ImageFiles, filesystem_type, syncfs_function
from parts.tub.reader import load_records
from parts.tub.tub import Tub

# syncfs is used on Linux 5.8+ only (older kernels hide write-back errors from it)
needs_syncfs = pytest.mark.skipif(
    image_files.syncfs_function() is None, reason="no syncfs here (Linux 5.8 or later)")


@needs_syncfs
def test_syncfs_commit_syncs_once_on_the_images_folder(tmp_path, monkeypatch):
    real = syncfs_function()
    assert real is not None
    calls: list[int] = []

    def counting(fd: int) -> int:
        calls.append(os.fstat(fd).st_ino)
        return real(fd)

    monkeypatch.setattr(image_files, "_syncfs", counting)
    monkeypatch.setattr(image_files, "filesystem_type", lambda path: "ext4")
    monkeypatch.setattr(os, "fsync", lambda fd: pytest.fail("fsync called although syncfs is used"))
    files = ImageFiles(tmp_path, durable=True)
    assert files.uses_syncfs
    for i in range(3):
        files.write(f"{i}_cam_.jpg", b"\xff\xd8" + bytes([i]) * 100 + b"\xff\xd9")
    assert len(files) == 3
    files.sync()
    assert calls == [tmp_path.stat().st_ino]  # one call, on the images folder
    assert len(files) == 0
    files.sync()  # nothing pending: no call
    assert len(calls) == 1
    assert (tmp_path / "2_cam_.jpg").read_bytes()[2] == 2
    files.write("3_cam_.jpg", b"\xff\xd8\xff\xd9")
    files.sync()
    assert calls == [tmp_path.stat().st_ino] * 2  # the folder stays open between commits


@needs_syncfs
def test_the_folder_kept_open_for_syncfs_is_closed(tmp_path, monkeypatch):
    monkeypatch.setattr(image_files, "filesystem_type", lambda path: "ext4")

    def open_fds() -> int:
        return len(os.listdir("/proc/self/fd"))

    before = open_fds()
    files = ImageFiles(tmp_path, durable=True)
    files.write("0.jpg", b"x")
    files.sync()
    assert open_fds() == before + 1
    files.close()
    assert open_fds() == before
    files.write("1.jpg", b"x")  # a sync after close opens the folder again
    files.sync()
    assert open_fds() == before + 1
    del files  # collected without close(): the descriptor is not leaked
    assert open_fds() == before


def test_on_fat_or_fuse_each_file_and_the_folder_are_fsynced(tmp_path, monkeypatch):
    monkeypatch.setattr(image_files, "filesystem_type", lambda path: "vfat")
    synced: list[int] = []
    real_fsync = os.fsync

    def counting(fd: int) -> None:
        synced.append(os.fstat(fd).st_ino)
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", counting)
    files = ImageFiles(tmp_path, durable=True)
    assert not files.uses_syncfs
    for i in range(4):
        files.write(f"{i}.jpg", b"x" * 10)
    files.sync()
    inodes = {(tmp_path / f"{i}.jpg").stat().st_ino for i in range(4)}
    assert set(synced) == inodes | {tmp_path.stat().st_ino} and len(synced) == 5
    assert len(files) == 0
    files.close()


def test_a_failed_fsync_keeps_every_file_pending_for_the_next_sync(tmp_path, monkeypatch):
    files = ImageFiles(tmp_path, durable=True, use_syncfs=False)
    files.write("a.jpg", b"a")
    files.write("b.jpg", b"b")
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (_ for _ in ()).throw(OSError(5, "I/O error")))
    with pytest.raises(OSError, match="I/O error"):
        files.sync()
    assert len(files) == 2
    synced: list[int] = []
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real_fsync(fd)))
    files.sync()
    assert len(synced) == 3 and len(files) == 0  # both files and the folder
    files.close()


@pytest.mark.parametrize("use_syncfs", [None, False])
def test_after_a_failed_sync_the_files_are_written_again_before_the_retry(tmp_path, monkeypatch, use_syncfs):
    # After a failed write-back Linux marks the pages clean and reports the error once: the
    # retry must write the bytes again, or it succeeds with the images never on the disk.
    if use_syncfs is None:
        if syncfs_function() is None:
            pytest.skip("no syncfs here (Linux 5.8 or later)")
        monkeypatch.setattr(image_files, "filesystem_type", lambda path: "ext4")
    failing = {"on": True}

    def sync_fails(fd: int) -> int:
        if failing["on"]:
            # what reached the disk: nothing (the kernel's copy may be dropped later)
            for name in ("a.jpg", "b.jpg"):
                (tmp_path / name).write_bytes(b"")
            raise OSError(5, "I/O error")
        return 0

    real_fsync = os.fsync
    monkeypatch.setattr(image_files, "_syncfs", sync_fails)
    monkeypatch.setattr(os, "fsync", lambda fd: sync_fails(fd) or real_fsync(fd))
    files = ImageFiles(tmp_path, durable=True, use_syncfs=use_syncfs)
    assert files.uses_syncfs is (use_syncfs is None)
    files.write("a.jpg", b"first")
    files.write("b.jpg", b"second")
    with pytest.raises(OSError, match="I/O error"):
        files.sync()
    files.write("c.jpg", b"third")  # written after the failure: part of the retry, rewritten too
    failing["on"] = False
    files.sync()
    assert [(tmp_path / n).read_bytes() for n in ("a.jpg", "b.jpg", "c.jpg")] == [b"first", b"second", b"third"]
    assert len(files) == 0
    (tmp_path / "a.jpg").write_bytes(b"changed")  # a sync that succeeded writes nothing again
    files.write("d.jpg", b"fourth")
    files.sync()
    assert (tmp_path / "a.jpg").read_bytes() == b"changed"
    files.close()


def test_beyond_keep_bytes_a_failed_sync_keeps_sizes_and_the_rewrite_reads_back(tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(image_files, "KEEP_BYTES", 10)
    files = ImageFiles(tmp_path, durable=True, use_syncfs=False)
    for name, data in (("a.jpg", b"kept"), ("b.jpg", b"read"), ("c.jpg", b"gone"), ("d.jpg", b"grows")):
        files.write(name, data)
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (_ for _ in ()).throw(OSError(5, "I/O error")))
    with pytest.raises(OSError):
        files.sync()
    # 4 + 4 bytes fit in KEEP_BYTES; of the later files only the sizes are kept
    assert [data for _path, data in files._pending] == [b"kept", b"read", 4, 5]
    rewritten: list[tuple[str, bytes]] = []
    real_write = image_files._write_file
    monkeypatch.setattr(image_files, "_write_file",
                        lambda path, data: (rewritten.append((os.path.basename(path), data)), real_write(path, data)))
    (tmp_path / "c.jpg").unlink()
    (tmp_path / "d.jpg").write_bytes(b"grown!")
    monkeypatch.setattr(os, "fsync", real_fsync)
    files.sync()
    assert rewritten == [("a.jpg", b"kept"), ("b.jpg", b"read")]
    assert "2 images written while the disk failed could not be written again" in caplog.text
    assert len(files) == 0
    files.close()


def test_not_durable_writes_and_never_syncs(tmp_path, monkeypatch):
    monkeypatch.setattr(os, "fsync", lambda fd: pytest.fail("fsync called"))
    monkeypatch.setattr(image_files, "_syncfs", lambda fd: pytest.fail("syncfs called"))
    files = ImageFiles(tmp_path, durable=False)
    files.write("a.jpg", b"abc")
    assert len(files) == 0
    files.sync()
    assert (tmp_path / "a.jpg").read_bytes() == b"abc"


def test_filesystem_type_takes_the_longest_mount_point(tmp_path):
    table = tmp_path / "mounts"
    table.write_text("/dev/root / ext4 rw 0 0\n"
                     f"/dev/sda1 {tmp_path}/sd\\040card vfat rw 0 0\n"
                     f"/dev/sdb1 {tmp_path}/sd vfat rw 0 0\n"
                     "sshfs#me@host: /mnt/far fuse.sshfs rw 0 0\n")
    (tmp_path / "sd card" / "tub").mkdir(parents=True)
    assert filesystem_type(tmp_path / "sd card" / "tub", str(table)) == "vfat"
    assert filesystem_type(tmp_path / "sdcard", str(table)) == "ext4"  # not inside "sd"
    assert filesystem_type("/mnt/far/x", str(table)) == "fuse.sshfs"
    assert filesystem_type("/x", str(tmp_path / "missing")) is None


def test_tub_commit_makes_images_durable_before_their_catalog_lines(tmp_path, monkeypatch):
    events: list[str] = []
    tub = Tub(tmp_path / "t", ["cam/image_array", "n"], ["image_array", "int"], fsync_records=3,
              fsync_ms=60_000)
    catalog = tub._committer.catalog
    real_sync, real_append = tub._images.sync, catalog.append
    fail = [True]

    def sync() -> None:
        events.append(f"sync {len(tub._images)}")
        if fail[0]:
            raise OSError(5, "I/O error")
        real_sync()

    def append(lines, *, durable):
        events.append(f"append {len(lines)}")
        real_append(lines, durable=durable)

    monkeypatch.setattr(tub._images, "sync", sync)
    monkeypatch.setattr(catalog, "append", append)
    frame = np.zeros((8, 8, 3), np.uint8)
    tub.write_record({"cam/image_array": frame, "n": 0})
    tub.write_record({"cam/image_array": frame, "n": 1})
    with pytest.raises(OSError):
        tub.write_record({"cam/image_array": frame, "n": 2})  # the commit's sync fails
    assert events == ["sync 3"]  # no catalog line was written for images not known durable
    fail[0] = False
    tub.write_record({"cam/image_array": frame, "n": 3})
    # the retry covers the first images too, and only then are all the lines appended
    assert events == ["sync 3", "sync 4", "append 4"]
    tub.write_record({"cam/image_array": frame, "n": 4})
    tub.write_record({"cam/image_array": frame, "n": 5})
    tub.close()
    assert events[3:5] == ["sync 2", "append 2"]
    assert [r["n"] for r in load_records(tmp_path / "t")] == [0, 1, 2, 3, 4, 5]


def test_syncfs_is_used_only_where_the_kernel_reports_its_errors(monkeypatch):
    assert image_files.kernel_version("4.9.337-tegra") == (4, 9)
    assert image_files.kernel_version("6.6.31+rpt-rpi-v8") == (6, 6)
    assert image_files.kernel_version("weird") == (0, 0)
    monkeypatch.setattr(image_files, "_syncfs", False)  # look it up again
    monkeypatch.setattr(image_files.platform, "release", lambda: "4.9.337-tegra")  # Jetson Nano
    assert syncfs_function() is None
    monkeypatch.setattr(image_files, "_syncfs", False)
    monkeypatch.setattr(image_files.platform, "release", lambda: "5.8.0")
    assert syncfs_function() is not None or not sys.platform.startswith("linux")
