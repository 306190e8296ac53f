"""How a car's manage.py ends: every way of stopping gives its exit code and no traceback."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


def _records(car: Path) -> int:
    lines = 0
    for catalog in car.glob("data/*/catalog_*.catalog"):
        lines += catalog.read_bytes().count(b"\n")
    return lines


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_drive_expert_stopped_by_a_signal_exits_with_its_code(tmp_path, sig, code):
    # issue 21: Ctrl-C printed a traceback and exited -2, SIGTERM exited 1
    car = tmp_path / "car"
    shutil.copytree(ROOT / "mycar", car, ignore=shutil.ignore_patterns("data", "models", "__pycache__"))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, str(car / "manage.py"), "drive", "--expert",
                             "--record-records", "1000000"], cwd=car, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 60
        while _records(car) < 30:  # recording: the vehicle loop runs
            assert proc.poll() is None and time.monotonic() < end, proc.communicate()[1][-2000:]
            time.sleep(0.05)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err[-2000:]
    assert "Traceback" not in err, err[-2000:]
    assert "throttle set to neutral" in err
    assert _records(car) >= 30  # what was recorded is kept
