"""SIGKILL a recording process at random instants, many times: the tub always opens, whole records only."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from parts.tub.check import check_tub
from parts.tub.reader import load_records
from parts.tub.tub import Tub

CHILD = Path(__file__).with_name("crash_child.py")
ROOT = Path(__file__).resolve().parents[3]
KILLS = 24


def test_sigkill_at_random_points_never_corrupts_the_tub(tmp_path):
    tub_path = tmp_path / "tub"
    rng = random.Random(1234)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    checked = 0  # records whose image was already verified
    sessions_with_records = set()
    for kill in range(KILLS):
        proc = subprocess.Popen([sys.executable, str(CHILD), str(tub_path), str(kill)], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        if kill % 4 == 3:
            time.sleep(rng.uniform(0.0, 0.4))  # anywhere, start-up and recovery included
        else:
            assert proc.stdout.readline() == b"ready\n", proc.stderr.read().decode()[-2000:]
            time.sleep(rng.uniform(0.0, 0.25))  # while recording
        proc.send_signal(signal.SIGKILL)
        _, err = proc.communicate(timeout=10)
        assert proc.returncode == -signal.SIGKILL, err.decode()[-2000:]
        if not tub_path.exists() or not (tub_path / "manifest.json").exists() and \
                not list(tub_path.glob("catalog_*.catalog")):
            continue  # killed before the tub was created
        tub = Tub(tub_path, read_only=True)
        lines = list(tub.scan())
        assert all(rec is not None and not salvaged for _, _, rec, _, salvaged in lines), \
            f"kill {kill}: an unparsable or merged catalog line"
        indexes = [i for _, i, _, _, _ in lines]
        assert indexes == list(range(len(indexes))), f"kill {kill}: indexes not contiguous/unique"
        assert tub.current_index == len(indexes)
        records = load_records(tub_path, on_error="raise")
        for rec in records[checked:]:  # every record points to a whole image with its own content
            img = rec.image()
            assert img.shape == (24, 32, 3)
            assert abs(int(img.mean()) - (rec["n"] * 7) % 256) <= 3
            assert rec["_timestamp_ms"] > 1_600_000_000_000
            sessions_with_records.add(rec["_session_id"])
        checked = len(records)
        # each run's records carry that run's own session id: ids never repeat across runs
        by_session = {}
        for rec in records:
            by_session.setdefault(rec["_session_id"], []).append(rec.index)
        for idx in by_session.values():
            assert idx == list(range(idx[0], idx[0] + len(idx))), "a session id was reused"
    assert checked > 50, "the recorder wrote too little to test anything"
    assert len(sessions_with_records) >= KILLS // 3
    report = check_tub(tub_path, repair=True)
    assert not report.bad_records and not report.unparsable and not report.duplicate_indexes
    final = Tub(tub_path, read_only=True)
    assert len(final) == checked and final.problems == []
    assert np.all(np.diff([r.index for r in load_records(tub_path)]) == 1)


def test_sigkill_right_after_a_catalog_rollover_leaves_a_tub_donkeycar_opens(tmp_path, donkeycar_opens):
    """issue 21: a kill just after the writer started a new catalog left it empty (0 bytes, with
    its .catalog_manifest): DonkeyCar 5.3's read-only open fails on it (cannot mmap an empty file).
    Each run is killed the moment a new catalog file appears."""
    tub_path = tmp_path / "tub"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    seen = 1  # catalog_0 comes with the tub: aim at the rollovers to catalog_1, catalog_2 ...
    for kill in range(8):
        # a wide durability window: the first line of a new catalog waits for the next commit
        proc = subprocess.Popen([sys.executable, str(CHILD), str(tub_path), str(kill), "10", "200"],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        assert proc.stdout.readline() == b"ready\n", proc.stderr.read().decode()[-2000:]
        end = time.monotonic() + 20
        while len(list(tub_path.glob("catalog_*.catalog"))) <= seen:
            assert time.monotonic() < end and proc.poll() is None, proc.stderr.read().decode()[-2000:]
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=10)
        seen = len(list(tub_path.glob("catalog_*.catalog")))
        assert donkeycar_opens(tub_path) == [], f"kill {kill}"
        tub = Tub(tub_path, read_only=True)
        empty = [p.name for p in tub_path.glob("catalog_*.catalog") if p.stat().st_size == 0]
        assert empty == [], f"kill {kill}: empty catalog left behind"
        indexes = [i for _, i, _, _, _ in tub.scan()]
        assert indexes == list(range(len(indexes))), f"kill {kill}: indexes not contiguous"
    check_tub(tub_path, repair=True)
    report = check_tub(tub_path)
    assert report.ok, report.lines()
