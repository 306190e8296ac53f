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
