"""How `vehicle console` ends: a stop signal gives the exit code every other command gives."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[4]


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_the_console_stopped_by_a_signal_exits_with_its_code(tmp_path, sig, code):
    # issue 27: the console exited 0 on Ctrl-C where every other command exits 130
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "vehicle", "console", "--car", str(tmp_path), "--port", "0"],
                            env=env, stderr=subprocess.PIPE, text=True)
    try:
        for line in proc.stderr:  # serving once it says where
            if "trainer console of" in line:
                break
        else:
            pytest.fail(f"the console ended before serving: {proc.wait()}")
        proc.send_signal(sig)
        err = proc.stderr.read()
        assert proc.wait(timeout=60) == code, err
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "Traceback" not in err and "console stopped" in err
