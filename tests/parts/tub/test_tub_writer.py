"""TubWriter: off-thread writing, capture timestamps, counted drops, wiper, Vehicle assembly."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from parts.tub.errors import TubError
from parts.tub.image_files import ImageFiles
from parts.tub.reader import load_records
from parts.tub.tub import Tub
from parts.tub.writer import TubWiper, TubWriter
from vehicle.config import Config

ROOT = Path(__file__).resolve().parents[3]
INPUTS = ["cam/image_array", "user/angle", "user/throttle", "user/mode", "cam/timestamp"]
TYPES = ["image_array", "float", "float", "str", "float"]


def test_records_everything_with_capture_timestamps(tmp_path, image):
    w = TubWriter(tmp_path / "t", INPUTS, TYPES, max_catalog_len=10)
    counts = [w.run(image(i), i / 100, 0.3, "user", 1_800_000_000.0 + i * 0.05) for i in range(25)]
    assert counts == list(range(1, 26))
    w.shutdown()
    w.shutdown()  # twice is fine
    tub = Tub(tmp_path / "t", read_only=True)
    assert tub.inputs == INPUTS[:4]  # the timestamp is not a field
    recs = load_records(tmp_path / "t")
    assert [r["_timestamp_ms"] for r in recs] == [1_800_000_000_000 + 50 * i for i in range(25)]
    assert [r["user/angle"] for r in recs] == [i / 100 for i in range(25)]
    assert w.stats.written == 25 and w.stats.dropped == 0


def test_arrays_are_copied_so_a_reused_camera_buffer_is_safe(tmp_path):
    w = TubWriter(tmp_path / "t", ["cam/image_array", "n"], ["image_array", "int"])
    buf = np.zeros((24, 32, 3), np.uint8)
    for i in range(5):
        buf[:] = 40 * i
        w.run(buf, i)
    w.shutdown()
    means = [int(r.image().mean()) for r in load_records(tmp_path / "t")]
    assert all(abs(m - 40 * i) <= 2 for i, m in enumerate(means))


@pytest.mark.parametrize("fsync", [True, False])
def test_a_paused_recording_commits_its_window_by_age(tmp_path, fsync):
    # One record, far fewer than fsync_records, and no later write that could find its window
    # old: only the recording thread, idle, commits it by the window's age (fsync_ms)
    w = TubWriter(tmp_path / "t", ["n"], ["int"], fsync=fsync, fsync_records=1000, fsync_ms=30)
    w.run(7)
    deadline = time.monotonic() + 10
    committed: list[int] = []
    while time.monotonic() < deadline and not committed:
        time.sleep(0.02)
        # the tub appears with its first committed record
        committed = [r["n"] for r in load_records(tmp_path / "t")] if (tmp_path / "t").exists() else []
    try:
        assert committed == [7]  # in the catalog while the writer is still open
        assert w.stats.written == 1 and w.pending() == 0
    finally:
        w.shutdown()


def test_full_queue_drops_counted_and_warned_and_run_never_waits(tmp_path, caplog):
    w = TubWriter(tmp_path / "t", ["n"], ["int"], queue_size=3)
    gate = threading.Event()
    real = w.tub.write_record

    def slow(record, **kw):
        gate.wait(5)  # the disk is stuck
        return real(record, **kw)

    w.tub.write_record = slow
    with caplog.at_level(logging.WARNING, logger="parts.tub.writer"):
        for i in range(300):
            w.run(i)  # returns although the writer thread is blocked
    # 3 records in flight at most (queue_size): the rest is dropped and counted
    assert w.stats.accepted == 3 and w.stats.dropped == 297
    warnings = [r for r in caplog.records if "dropped" in r.getMessage()]
    assert len(warnings) == 1  # rate-limited: one warning for the burst
    gate.set()
    w.shutdown()
    written = [r["n"] for r in Tub(tmp_path / "t", read_only=True)]
    assert len(written) == w.stats.accepted == w.stats.written  # every accepted record is on disk
    assert written == sorted(set(written)) and written[:3] == [0, 1, 2]


def test_a_failed_recording_thread_is_named_in_the_drop_warning_and_at_shutdown(tmp_path, monkeypatch, caplog):
    from parts.tub import writer as writer_module

    def broken(self, records):
        raise RuntimeError("encoder bug")

    monkeypatch.setattr(writer_module._Recorder, "_store_images", broken)
    w = TubWriter(tmp_path / "t", ["n"], ["int"], queue_size=5)
    with caplog.at_level(logging.WARNING):
        for i in range(5):
            w.run(i)
        deadline = time.monotonic() + 10
        while w._recorder.error is None and time.monotonic() < deadline:
            time.sleep(0.01)
        for i in range(3):
            w.run(i)  # queue full: dropped, and the warning says why
        w.shutdown()
    assert isinstance(w._recorder.error, RuntimeError)
    assert w.stats.accepted == 5 and w.stats.dropped == 3 and w.stats.written == 0
    assert "recording thread failed (RuntimeError('encoder bug')): nothing is written" in caplog.text
    assert "5 accepted records were not written" in caplog.text
    assert "disk is too slow" not in caplog.text


def test_a_window_that_cannot_be_committed_is_retried_without_spinning(tmp_path, monkeypatch, caplog):
    from parts.tub.committer import Committer

    def die(self):
        raise RuntimeError("commit thread bug")

    monkeypatch.setattr(Committer, "_run_jobs", die)  # the commit thread fails at once
    w = TubWriter(tmp_path / "t", ["n"], ["int"], fsync=True, fsync_records=1000, fsync_ms=30)
    attempts = []
    real_commit = w.tub.commit

    def commit():
        attempts.append(1)
        real_commit()

    w.tub.commit = commit
    with caplog.at_level(logging.ERROR):
        w.run(1)
        time.sleep(0.6)  # the window is due after 30 ms; each attempt is refused
        assert 1 <= len(attempts) <= 40  # one attempt per 20 ms at most: without the floor, thousands
        with pytest.raises(TubError, match="the commit thread failed"):
            w.shutdown()  # the record could not be committed: said, not hidden


def test_wiper_deletes_on_rising_edge_including_queued_records(tmp_path):
    w = TubWriter(tmp_path / "t", ["n"], ["int"])
    wiper = TubWiper(w, num_records=3)
    for i in range(10):
        w.run(i)
        wiper.run(i in (6, 7, 8))  # held for three loops: one erase
    w.shutdown()
    assert [r["n"] for r in Tub(tmp_path / "t", read_only=True)] == [0, 1, 2, 3, 7, 8, 9]


def test_wrong_arguments_raise(tmp_path):
    with pytest.raises(ValueError, match="one type per input"):
        TubWriter(tmp_path / "t", ["a", "b"], ["float"])
    w = TubWriter(tmp_path / "t", ["a"], ["float"])
    with pytest.raises(ValueError, match="expected 1 inputs"):
        w.run(1.0, 2.0)
    w.shutdown()
    with pytest.raises(RuntimeError, match="shut down"):
        w.run(1.0)


def test_add_tub_writer_in_a_vehicle(tmp_path, image):
    from vehicle import Vehicle
    from vehicle.app.assembly.tub import add_tub_writer
    from vehicle.clock import SimulatedClock

    cfg = Config.defaults(CAR_PATH=str(tmp_path), METADATA=["driver:test"])

    class Camera:
        def __init__(self):
            self.i = 0

        def run(self):
            self.i += 1
            return image(self.i % 5), 1_800_000_000.0 + self.i, self.i % 3 != 0, self.i == 8

    V = Vehicle(clock=SimulatedClock())
    V.add(Camera(), outputs=["cam/image_array", "cam/timestamp", "recording", "tub/erase"])
    V.add(lambda: (0.25, 0.5, "user"), outputs=["user/angle", "user/throttle", "user/mode"])
    writer = add_tub_writer(V, cfg)
    V.start(rate_hz=20, max_loop_count=12)
    tubs = sorted((tmp_path / "data").iterdir())
    assert [t.name.split("_")[1] for t in tubs] == ["1"] and tubs[0] == writer.tub.path
    recs = load_records(tubs[0])
    # recorded loops: i % 3 != 0 -> 1 2 4 5 7 8 10 11; the erase at loop 8 removed 100 (all before)
    assert [r["_timestamp_ms"] for r in recs] == [1_800_000_010_000, 1_800_000_011_000]
    assert Tub(tubs[0], read_only=True).metadata == {"driver": "test"}
    assert V.mem["tub/num_records"] == 8

    V2 = Vehicle(clock=SimulatedClock())
    V2.add(lambda: (image(0), False), outputs=["cam/image_array", "recording"])
    V2.add(lambda: (0.0, 0.0, "user"), outputs=["user/angle", "user/throttle", "user/mode"])
    add_tub_writer(V2, cfg)
    V2.start(rate_hz=20, max_loop_count=3)
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == [tubs[0].name]  # no empty tub left


def test_add_tub_writer_inputs_follow_config_and_available_keys(tmp_path, image):
    from vehicle import Vehicle
    from vehicle.app.assembly.tub import add_tub_writer
    from vehicle.errors import UserError

    cfg = Config.defaults(CAR_PATH=str(tmp_path), RECORD_DURING_AI=True, AUTO_CREATE_NEW_TUB=False)
    (tmp_path / "data").mkdir()  # as createcar makes it: a tub the writer did not create stays when empty
    V = Vehicle()
    V.add(lambda: (image(0), 0.0, 0.0, "user", True),
          outputs=["cam/image_array", "user/angle", "user/throttle", "user/mode", "recording"])
    plain = add_tub_writer(V, cfg)  # no pilot part, no cam/timestamp: neither is recorded
    assert plain.inputs == ["cam/image_array", "user/angle", "user/throttle", "user/mode"]
    assert plain.tub.path == tmp_path / "data"  # AUTO_CREATE_NEW_TUB=False: data/ is the tub
    plain.run(image(0), 0.0, 0.0, "user")  # a tub without records is never created
    plain.shutdown()
    V.add(lambda: (0.1, 0.2), outputs=["pilot/angle", "pilot/throttle"])
    with_ai = add_tub_writer(V, cfg.replace(DATA_PATH="data2"))
    assert with_ai.inputs[-2:] == ["pilot/angle", "pilot/throttle"]
    with_ai.shutdown()
    with pytest.raises(UserError, match="cannot record into"):
        add_tub_writer(V, cfg, inputs=["user/angle"], types=["float"])  # data/ holds another schema


@pytest.mark.parametrize("encode_threads", [1, 3])
def test_several_encoding_threads_keep_record_order(tmp_path, encode_threads, monkeypatch):
    from concurrent.futures import ThreadPoolExecutor

    from parts.tub import writer as writer_module

    handed_off: list[int] = []

    class CountingPool(ThreadPoolExecutor):
        def submit(self, fn, /, *args, **kwargs):
            handed_off.append(1)
            return super().submit(fn, *args, **kwargs)

    monkeypatch.setattr(writer_module, "ThreadPoolExecutor", CountingPool)
    w = TubWriter(tmp_path / "t", ["cam/image_array", "n"], ["image_array", "int"], queue_size=500,
                  encode_threads=encode_threads)
    frame = np.zeros((24, 32, 3), np.uint8)
    for i in range(120):  # queued faster than encoded: the encoder takes batches and splits them
        frame[:] = 2 * i
        w.run(frame, i)
    w.shutdown()
    recs = load_records(tmp_path / "t")
    assert [r["n"] for r in recs] == list(range(120))
    assert [r.index for r in recs] == list(range(120))
    assert all(abs(int(r.image().mean()) - 2 * r["n"]) <= 2 for r in recs)
    assert w.stats.written == 120 and w.stats.failed == 0
    # with helpers, batches really were split (one hand-off per helper and batch)
    assert (len(handed_off) > 0) == (encode_threads > 1)


def test_encode_threads_must_be_positive(tmp_path):
    with pytest.raises(ValueError, match="encode_threads must be >= 1"):
        TubWriter(tmp_path / "t", ["n"], ["int"], encode_threads=0)


@pytest.mark.parametrize("encode_threads", [1, 2])
def test_an_image_that_cannot_be_encoded_is_counted_and_the_rest_written(tmp_path, encode_threads, caplog):
    w = TubWriter(tmp_path / "t", ["cam/image_array", "n"], ["image_array", "int"], queue_size=50,
                  encode_threads=encode_threads)
    good = np.full((8, 8, 3), 90, np.uint8)
    with caplog.at_level(logging.ERROR, logger="parts.tub.writer"):
        for i in range(10):
            w.run(np.zeros((8, 8, 5), np.uint8) if i == 4 else good, i)  # 5 channels: not an image
        w.shutdown()
    assert w.stats.failed == 1 and w.stats.written == 9 and w.pending() == 0
    assert [(r.index, r["n"]) for r in load_records(tmp_path / "t")] == [(i, i) for i in range(10) if i != 4]
    assert Tub(tmp_path / "t", read_only=True).deleted_indexes == {4}  # its index kept, deleted
    assert "writing failed (record 4)" in caplog.text and "cannot be stored" in caplog.text


@pytest.mark.parametrize("encode_threads", [1, 2])
def test_a_record_whose_image_cannot_be_written_keeps_its_index_as_a_deleted_record(
        tmp_path, encode_threads, monkeypatch, caplog):
    real_write = ImageFiles.write

    def write(self, name, data):
        if name.startswith("4_"):
            raise OSError(28, "No space left on device")
        real_write(self, name, data)

    monkeypatch.setattr(ImageFiles, "write", write)
    w = TubWriter(tmp_path / "t", ["cam/image_array", "n"], ["image_array", "int"], queue_size=50,
                  encode_threads=encode_threads)
    with caplog.at_level(logging.WARNING):
        for i in range(8):
            w.run(np.full((8, 8, 3), 30 * i, np.uint8), i)
        w.shutdown()
    assert w.stats.failed == 1 and w.stats.written == 7 and w.pending() == 0
    records = load_records(tmp_path / "t", on_error="raise")
    assert [(r.index, r["n"]) for r in records] == [(0, 0), (1, 1), (2, 2), (3, 3), (5, 5), (6, 6), (7, 7)]
    assert [round(r.image().mean() / 30) for r in records] == [0, 1, 2, 3, 5, 6, 7]  # each its own image
    tub = Tub(tmp_path / "t", read_only=True)
    assert tub.current_index == 8 and tub.deleted_indexes == {4} and len(tub) == 7
    assert "writing failed (record 4)" in caplog.text and "No space left" in caplog.text
    assert "records 4..4 could not be written; kept as deleted records" in caplog.text


def test_shutdown_keeps_its_timeout_when_the_disk_stalls_and_the_tub_closes_later(tmp_path, monkeypatch, caplog):
    gate = threading.Event()
    real_sync = ImageFiles.sync

    def stalled_sync(self):
        gate.wait(10)
        real_sync(self)

    monkeypatch.setattr(ImageFiles, "sync", stalled_sync)
    w = TubWriter(tmp_path / "t", ["cam/image_array", "n"], ["image_array", "int"], fsync_records=5)
    for i in range(12):
        w.run(np.full((8, 8, 3), 20 * i, np.uint8), i)
    with caplog.at_level(logging.ERROR, logger="parts.tub.writer"):
        w.shutdown(timeout=0.3)  # returns although the commit waits for the "disk"
    assert "still busy after 0.3 s" in caplog.text
    assert not w.tub.closed
    gate.set()
    deadline = time.monotonic() + 10
    while not w.tub.closed and time.monotonic() < deadline:
        time.sleep(0.01)
    assert w.tub.closed
    assert [r["n"] for r in load_records(tmp_path / "t")] == list(range(12))


EXIT_CHILD = r"""
import os
import sys
import time
import numpy as np
import parts.tub.image_files as image_files
from parts.tub.writer import TubWriter
if sys.argv[2] == "fsync-each":
    image_files._syncfs = None  # as on a FAT card or Linux < 5.8: a pool fsyncs each image
w = TubWriter(sys.argv[1], ["cam/image_array", "n"], ["image_array", "int"], queue_size=500)
for i in range(60):
    w.run(np.full((48, 64, 3), 4 * i, np.uint8), i)
    if i == 29 and sys.argv[3] == "committed-before":
        # a commit before the exit opens the folder's descriptor for syncfs: its closing must not
        # run among the exit hooks before the writer's own hook has committed the rest
        catalog = os.path.join(sys.argv[1], "catalog_0.catalog")
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not (os.path.exists(catalog) and os.path.getsize(catalog)):
            time.sleep(0.05)
# ends without w.shutdown(): its exit hook writes what is queued
"""


@pytest.mark.parametrize("when", ["all-at-exit", "committed-before"])
@pytest.mark.parametrize("sync", ["syncfs", "fsync-each"])
def test_a_program_that_ends_without_shutdown_still_writes_every_queued_record(tmp_path, sync, when):
    # At exit Python's thread pools take no new tasks: the encoding helpers' and the fsync pool's
    # work then runs in the recording thread instead of failing and losing the records
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    res = subprocess.run([sys.executable, "-c", EXIT_CHILD, str(tmp_path / "t"), sync, when], env=env,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "failed" not in res.stderr, res.stderr[-2000:]
    records = load_records(tmp_path / "t", on_error="raise")
    assert [r["n"] for r in records] == list(range(60))
    assert all(abs(int(r.image().mean()) - 4 * r["n"]) <= 2 for r in records)
