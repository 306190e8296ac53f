"""The committer: commits in a thread of their own keep the order images -> catalog lines ->
manifest, let the writer run one window ahead, retry failures without losing or doubling records,
and a failed catalog append leaves no partial or duplicate line."""

from __future__ import annotations

import json
import logging
import os
import threading
import time

import numpy as np
import pytest

from parts.tub import committer as committer_module
from parts.tub import image_files
from parts.tub import tub as tub_module
from parts.tub.catalog import CatalogFile
from parts.tub.errors import TubError
from parts.tub.reader import load_records
from parts.tub.tub import Tub

INPUTS, TYPES = ["cam/image_array", "n"], ["image_array", "int"]
FRAME = np.zeros((8, 8, 3), np.uint8)
# syncfs is used on Linux 5.8+ only (older kernels hide write-back errors from it)
needs_syncfs = pytest.mark.skipif(
    image_files.syncfs_function() is None, reason="no syncfs here (Linux 5.8 or later)")


def _record(tub: Tub, n: int) -> None:
    tub.write_record({"cam/image_array": FRAME, "n": n})


def _spy(tub: Tub, monkeypatch, sync_fails: int = 0, sync_gate: threading.Event | None = None,
         fail_calls: frozenset[int] = frozenset(), entered: threading.Event | None = None) -> list[str]:
    """Record the committer's syncs and appends; fail the first ``sync_fails`` syncs and the
    syncs numbered in ``fail_calls`` (from 1); ``entered`` is set when a sync begins."""
    events: list[str] = []
    c = tub._committer
    real_sync, real_append = c.images.sync, c.catalog.append
    left = [sync_fails]
    count = [0]

    def sync() -> None:
        count[0] += 1
        if entered is not None:
            entered.set()
        if sync_gate is not None:
            sync_gate.wait(10)
        if left[0] or count[0] in fail_calls:
            left[0] = max(0, left[0] - 1)
            events.append("sync failed")
            raise OSError(5, "I/O error")
        events.append(f"sync {len(c.images)}")
        real_sync()

    def append(lines, *, durable):
        events.append(f"append {[json.loads(ln)['n'] for ln in lines]}")
        real_append(lines, durable=durable)

    monkeypatch.setattr(c.images, "sync", sync)
    monkeypatch.setattr(c.catalog, "append", append)
    return events


def _appended(events: list[str]) -> list[int]:
    """The record numbers of every appended line, in the order they reached the catalog."""
    return [n for e in events if e.startswith("append") for n in json.loads(e[len("append "):])]


def test_background_commits_retry_failures_in_order_without_losing_a_record(tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(committer_module, "RETRY_S", 0.01)
    tub = Tub(tmp_path / "t", INPUTS, TYPES, fsync_records=3, fsync_ms=60_000, commit_thread=True)
    events = _spy(tub, monkeypatch, sync_fails=2)
    with caplog.at_level(logging.WARNING, logger="parts.tub.committer"):
        for n in range(5):  # the commit of 0-2 fails twice and is retried by itself
            _record(tub, n)
        deadline = time.monotonic() + 10
        while not _appended(events) and time.monotonic() < deadline:
            time.sleep(0.005)
        for n in range(5, 7):
            _record(tub, n)
        tub.flush()
    assert events[:2] == ["sync failed", "sync failed"]
    # every line once, in order; no append before a sync succeeded
    assert _appended(events) == list(range(7))
    first_append = next(i for i, e in enumerate(events) if e.startswith("append"))
    assert events[first_append - 1].startswith("sync ") and "sync failed" not in events[first_append - 1]
    assert "commit failed, 3 records not durable yet" in caplog.text
    assert "commits succeed again" in caplog.text
    tub.close()
    assert [r["n"] for r in load_records(tmp_path / "t")] == list(range(7))


def test_the_writer_goes_on_while_a_commit_waits_for_the_disk_but_only_one_window_ahead(tmp_path, monkeypatch):
    tub = Tub(tmp_path / "t", INPUTS, TYPES, fsync_records=3, fsync_ms=60_000, commit_thread=True)
    gate, entered = threading.Event(), threading.Event()
    events = _spy(tub, monkeypatch, sync_gate=gate, entered=entered)
    written: list[int] = []

    def writer() -> None:
        for n in range(7):
            _record(tub, n)
            written.append(n)
            if n == 2:
                entered.wait(10)  # the commit of 0-2 has begun (and waits for the "disk")

    t = threading.Thread(target=writer)
    t.start()
    deadline = time.monotonic() + 10
    while len(os.listdir(tub.images_path)) < 6 and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.05)
    # records 0-2 are being committed (the disk is "slow"); 3-5 were written meanwhile; the
    # commit of 3-5 (due at record 5) waits for the first one: the writer is one window ahead
    assert t.is_alive()
    assert written == [0, 1, 2, 3, 4]
    assert sorted(os.listdir(tub.images_path)) == [f"{i}_cam_image_array_.jpg" for i in range(6)]
    assert events == []
    gate.set()
    t.join(10)
    assert not t.is_alive() and written == list(range(7))
    tub.close()
    # the first sync covers every image written by then; lines follow in order, each once
    assert events[:2] == ["sync 6", "append [0, 1, 2]"]
    assert _appended(events) == list(range(7))
    assert [r["n"] for r in load_records(tmp_path / "t")] == list(range(7))


def test_flush_raises_and_close_reports_records_a_failing_disk_kept_from_the_catalog(tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(committer_module, "RETRY_S", 0.01)
    tub = Tub(tmp_path / "t", INPUTS, TYPES, fsync_records=100, fsync_ms=60_000, commit_thread=True)
    _spy(tub, monkeypatch, sync_fails=10**6)
    _record(tub, 0)
    _record(tub, 1)
    with pytest.raises(TubError, match="cannot commit 2 records"):
        tub.flush()
    committer = tub._committer
    with caplog.at_level(logging.ERROR, logger="parts.tub.committer"), pytest.raises(TubError):
        tub.close()
    assert "closed with 2 records not committed" in caplog.text
    assert committer._thread is None and tub.closed
    # no catalog line points to an image that was never made durable; with no record committed
    # the new tub never appeared: what was written stays in its hidden folder
    assert (tub._dir / "catalog_0.catalog").read_bytes() == b"" and tub._dir.name.startswith(".t.partial-")
    assert not (tmp_path / "t").exists()


@pytest.mark.parametrize("commit_thread", [False, True])
def test_new_catalogs_and_manifests_follow_their_records(tmp_path, commit_thread):
    tub = Tub(tmp_path / "t", INPUTS, TYPES, max_catalog_len=4, fsync_records=3, fsync_ms=60_000,
              commit_thread=commit_thread)
    for n in range(10):
        _record(tub, n)
    tub.close()
    t = tmp_path / "t"
    for i, numbers in enumerate([[0, 1, 2, 3], [4, 5, 6, 7], [8, 9]]):
        lines = (t / f"catalog_{i}.catalog").read_text().splitlines()
        assert [json.loads(ln)["n"] for ln in lines] == numbers
        meta = json.loads((t / f"catalog_{i}.catalog_manifest").read_text())
        assert meta["start_index"] == 4 * i
        assert meta["line_lengths"] == [len(ln) + 1 for ln in lines]
    last = json.loads((t / "manifest.json").read_text().splitlines()[4])
    assert last["current_index"] == 10
    assert last["paths"] == ["catalog_0.catalog", "catalog_1.catalog", "catalog_2.catalog"]


def test_a_failed_catalog_append_is_cut_back_so_a_retry_writes_each_line_once(tmp_path, monkeypatch):
    path = tmp_path / "catalog_0.catalog"
    cat = CatalogFile.open_append(path, 0, durable=True)
    cat.append(['{"_index": 0}\n'], durable=True)
    real_fsync, real_truncate = os.fsync, os.ftruncate
    fsync_fails, truncate_fails = [1], [1]

    def fsync(fd: int) -> None:
        if fsync_fails[0]:
            fsync_fails[0] -= 1
            raise OSError(5, "I/O error")
        real_fsync(fd)

    def ftruncate(fd: int, size: int) -> None:
        if truncate_fails[0]:
            truncate_fails[0] -= 1
            raise OSError(5, "I/O error")
        real_truncate(fd, size)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "ftruncate", ftruncate)
    with pytest.raises(OSError):
        cat.append(['{"_index": 1}\n'], durable=True)  # written, fsync fails, the cut fails too
    assert path.read_text() == '{"_index": 0}\n{"_index": 1}\n'  # the cut is still owed
    cat.append(['{"_index": 1}\n', '{"_index": 2}\n'], durable=True)  # cuts first, then appends
    assert path.read_text() == '{"_index": 0}\n{"_index": 1}\n{"_index": 2}\n'
    assert cat.line_lengths == [14, 14, 14] and cat.size == 42
    cat.close()


def _count_flushes(monkeypatch) -> list[str]:
    """Count syncfs calls and the fsyncs of catalog files (by name) while the tub says ext4."""
    real_syncfs = image_files.syncfs_function()  # present: the tests using this need syncfs
    calls: list[str] = []

    def syncfs(fd: int) -> int:
        calls.append("syncfs")
        return real_syncfs(fd)

    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        name = os.path.basename(os.readlink(f"/proc/self/fd/{fd}"))
        if name.endswith(".catalog"):
            calls.append(f"fsync {name}")
        real_fsync(fd)

    monkeypatch.setattr(image_files, "_syncfs", syncfs)
    monkeypatch.setattr(image_files, "filesystem_type", lambda path: "ext4")
    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(tub_module, "MANIFEST_INTERVAL_S", 3600.0)  # only forced manifests
    return calls


def _records(tub: Tub, numbers: range) -> None:
    for n in numbers:
        _record(tub, n)
        tub._committer.wait()  # one commit at a time, so that the calls counted are exact


@needs_syncfs
def test_background_commits_flush_the_device_once_each_and_lines_ride_on_the_next_syncfs(tmp_path, monkeypatch):
    calls = _count_flushes(monkeypatch)
    tub = Tub(tmp_path / "t", INPUTS, TYPES, fsync_records=3, fsync_ms=60_000, commit_thread=True)
    _records(tub, range(9))
    # 1st commit: its images, then the lines are fsynced before the first manifest lists the
    # session; 2nd and 3rd: one syncfs each, which also makes the previous commit's lines durable
    assert calls == ["syncfs", "fsync catalog_0.catalog", "syncfs", "syncfs"]
    assert [json.loads(ln)["n"] for ln in tub._committer._unsynced] == [6, 7, 8]  # wait for the next
    tub.flush()
    assert calls[4:] == ["fsync catalog_0.catalog"] and tub._committer._unsynced == []
    tub.close()
    assert [r["n"] for r in load_records(tmp_path / "t")] == list(range(9))


@needs_syncfs
def test_lines_no_commit_takes_along_are_fsynced_after_fsync_ms(tmp_path, monkeypatch):
    calls = _count_flushes(monkeypatch)
    tub = Tub(tmp_path / "t", INPUTS, TYPES, fsync_records=3, fsync_ms=60_000, commit_thread=True)
    tub._committer._idle_s = 0.05  # the committer's idle delay only: commits still come by count
    _records(tub, range(6))
    deadline = time.monotonic() + 10
    while len(calls) < 4 and time.monotonic() < deadline:  # recording paused: no commit comes
        time.sleep(0.01)
    tub._committer.wait()  # the idle fsync job has finished (its fsync is counted as it starts)
    assert calls == ["syncfs", "fsync catalog_0.catalog", "syncfs", "fsync catalog_0.catalog"]
    assert tub._committer._unsynced == []
    tub.close()


@needs_syncfs
def test_a_catalog_is_fsynced_before_the_next_one_starts(tmp_path, monkeypatch):
    calls = _count_flushes(monkeypatch)
    tub = Tub(tmp_path / "t", INPUTS, TYPES, fsync_records=3, fsync_ms=60_000, commit_thread=True)
    _records(tub, range(6))
    assert calls == ["syncfs", "fsync catalog_0.catalog", "syncfs"]
    committer = tub._committer
    committer.submit([], next_catalog=(tmp_path / "t" / "catalog_1.catalog", 6))  # no manifest
    committer.wait()
    assert calls[3:] == ["fsync catalog_0.catalog"]  # lines 3-5 durable before catalog_0 closes
    # catalog_1 appears with its first lines (never empty: DonkeyCar cannot open an empty catalog)
    assert committer.catalog is None and not (tmp_path / "t" / "catalog_1.catalog").exists()
    committer.submit(['{"_index": 6}\n'])
    committer.wait()
    assert committer.catalog.path.name == "catalog_1.catalog"
    assert (tmp_path / "t" / "catalog_1.catalog").read_text() == '{"_index": 6}\n'
    tub.close()


@needs_syncfs
def test_lines_whose_syncfs_failed_are_cut_and_appended_again(tmp_path, monkeypatch):
    monkeypatch.setattr(committer_module, "RETRY_S", 0.01)
    monkeypatch.setattr(image_files, "filesystem_type", lambda path: "ext4")
    monkeypatch.setattr(tub_module, "MANIFEST_INTERVAL_S", 3600.0)
    tub = Tub(tmp_path / "t", INPUTS, TYPES, fsync_records=3, fsync_ms=60_000, commit_thread=True)
    events = _spy(tub, monkeypatch, fail_calls=frozenset({3}))
    catalog = tmp_path / "t" / "catalog_0.catalog"
    _records(tub, range(6))
    assert [json.loads(ln)["n"] for ln in catalog.read_text().splitlines()] == list(range(6))
    for n in range(6, 9):
        _record(tub, n)  # this commit's syncfs fails: lines 3-5, which waited for it, are cut
    deadline = time.monotonic() + 10
    while "sync failed" not in events and time.monotonic() < deadline:
        time.sleep(0.002)
    tub.flush()  # the retry appends 3-8 after the syncfs succeeds
    assert events.count("sync failed") == 1
    assert _appended(events) == [0, 1, 2, 3, 4, 5, 3, 4, 5, 6, 7, 8]
    assert [json.loads(ln)["n"] for ln in catalog.read_text().splitlines()] == list(range(9))
    tub.close()
    assert [r["n"] for r in load_records(tmp_path / "t")] == list(range(9))


class _Boom(BaseException):
    """Not an Exception: what a commit failure handler does not catch."""


def test_a_dead_commit_thread_raises_instead_of_hanging(tmp_path, monkeypatch, caplog):
    tub = Tub(tmp_path / "t", INPUTS, TYPES, fsync_records=3, fsync_ms=60_000, commit_thread=True)
    committer = tub._committer

    def boom(job):
        raise _Boom()

    monkeypatch.setattr(committer, "_commit", boom)
    with caplog.at_level(logging.ERROR, logger="parts.tub.committer"):
        for n in range(3):
            _record(tub, n)
        with pytest.raises(TubError, match="the commit thread failed"):
            tub.flush()
        with pytest.raises(TubError, match="the commit thread failed"):
            tub.close()
    assert "closed with 3 records not committed" in caplog.text
    assert committer._thread is None and tub.closed
