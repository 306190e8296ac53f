"""SIGTERM and SIGHUP take the same safe path as an exception (run in a subprocess)."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time

import pytest

SCRIPT = textwrap.dedent("""
    import sys
    from pathlib import Path
    from vehicle import Vehicle
    from vehicle.app.manage import run
    from vehicle.config import Config

    log = Path(sys.argv[1])

    class Throttle:
        def run(self, x):
            if x == 3:
                print("running", flush=True)
        def neutral(self):
            with log.open("a") as f: f.write("neutral\\n")
        def shutdown(self):
            with log.open("a") as f: f.write("shutdown throttle\\n")

    class Camera:
        def __init__(self): self.n = 0
        def run(self):
            self.n += 1
            return self.n
        def shutdown(self):
            with log.open("a") as f: f.write("shutdown camera\\n")

    V = Vehicle()
    V.add(Camera(), outputs=["x"])
    V.add(Throttle(), inputs=["x"])
    sys.exit(run(V, Config.defaults(DRIVE_LOOP_HZ=100)))
""")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_signal_stops_safely_with_nonzero_exit(tmp_path, sig):
    log = tmp_path / "log.txt"
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(log)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "running"
    time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=20)
    expected = 130 if sig == signal.SIGINT else 128 + sig
    assert proc.returncode == expected, err
    assert log.read_text().splitlines() == ["neutral", "shutdown throttle", "shutdown camera"]
    if sig != signal.SIGINT:
        assert f"stopped by {signal.Signals(sig).name}" in err


def _ignore_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # what a shell does to a job started with `&`


def test_sigint_stops_a_car_that_inherited_it_ignored(tmp_path):
    """A script's ``manage.py drive &`` starts with SIGINT ignored; ``kill -INT`` must still stop it."""
    log = tmp_path / "log.txt"
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(log)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_ignore_sigint)
    assert proc.stdout.readline().strip() == "running"
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert log.read_text().splitlines() == ["neutral", "shutdown throttle", "shutdown camera"]
