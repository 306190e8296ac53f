"""``vehicle sim serve``: the built-in simulator behind the Donkey protocol, as a command."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys

from fixtures.load import scaled

from parts.bridges.donkey_client import DonkeySim


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_sim_serve_serves_until_ctrl_c(tmp_path):
    port = free_port()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    proc = subprocess.Popen([sys.executable, "-m", "vehicle", "sim", "serve", "--port", str(port), "--tracks", "3,4",
                             "--car", str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    try:
        sim = DonkeySim(port=port, scene="track_4", synchronous=True, connect_timeout_s=scaled(60))
        try:
            outs = [dict(zip(DonkeySim.OUTPUTS, sim.run(0.0, 0.5, False), strict=True)) for _ in range(10)]
        finally:
            sim.shutdown()
        assert outs[-1]["sim/speed"] > 0 and outs[-1]["cam/image_array"].shape == (120, 160, 3)
        assert "track_3" in sim.scene_names and "generated_track" in sim.scene_names
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=scaled(30))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert f"Donkey-protocol simulator on 127.0.0.1:{port} (tracks 3,4)" in out


def test_sim_serve_rejects_a_bad_port(tmp_path, capsys):
    from vehicle.app.cli import main

    assert main(["sim", "serve", "--port", "70000", "--car", str(tmp_path)]) == 2
    assert "--port 70000: give a TCP port in 1..65535" in capsys.readouterr().err
