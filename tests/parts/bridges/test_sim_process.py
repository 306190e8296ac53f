"""DONKEY_SIM_PATH: the Donkey simulator's executable started by the car, as DonkeyCar does, tested
with stand-in executables (one that only listens, one that fails, one that runs `vehicle sim serve`)."""

from __future__ import annotations

import json
import os
import socket
import sys
from pathlib import Path

import pytest

from parts.bridges.errors import BridgeError
from parts.bridges.sim_process import SimulatorProcess, port_open

LISTENER = """\
import json, socket, sys, time
args = sys.argv[1:]
json.dump(args, open({argv_file!r}, "w"))
port, host = int(args[args.index("--port") + 1]), args[args.index("--host") + 1]
time.sleep(0.3)  # a simulator takes a while before it listens
s = socket.socket(); s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1); s.bind((host, port)); s.listen()
while True:
    s.accept()[0].close()
"""

SERVE = """\
import os, sys
args = sys.argv[1:]
port, host = args[args.index("--port") + 1], args[args.index("--host") + 1]
os.execv(sys.executable, [sys.executable, "-m", "vehicle.app.cli", "sim", "serve", "--port", port, "--host", host])
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _executable(path: Path, body: str) -> Path:
    path.write_text(f"#!{sys.executable}\n{body}")
    path.chmod(0o755)
    return path


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}").exists() and "Z" not in Path(f"/proc/{pid}/stat").read_text().split()[2]


def test_the_simulator_is_started_with_gym_donkeycars_arguments_and_ended(tmp_path):
    port = _free_port()
    argv_file = tmp_path / "argv.json"
    exe = _executable(tmp_path / "donkey_sim.x86_64", LISTENER.format(argv_file=str(argv_file)))
    part = SimulatorProcess(exe, "127.0.0.1", port, timeout_s=30, log_file=tmp_path / "logs" / "unitylog.txt")
    part.start()
    try:
        assert port_open("127.0.0.1", port)  # start() returned only once the port listens
        assert json.loads(argv_file.read_text()) == ["--port", str(port), "--host", "127.0.0.1", "-logFile",
                                                     str(tmp_path / "logs" / "unitylog.txt")]
        pid = part.process.pid
        assert _alive(pid)
    finally:
        part.shutdown()
    assert not _alive(pid) and not port_open("127.0.0.1", port)


def test_a_simulator_that_exits_or_never_listens_is_one_clear_error(tmp_path):
    port = _free_port()
    failing = _executable(tmp_path / "crash", "import sys; sys.exit(3)")
    with pytest.raises(BridgeError, match=r"exited with code 3 before it listened on port \d+; its log: "):
        SimulatorProcess(failing, "127.0.0.1", port, timeout_s=30, log_file=tmp_path / "u.txt").start()
    silent = _executable(tmp_path / "silent", "import time; time.sleep(60)")
    part = SimulatorProcess(silent, "127.0.0.1", port, timeout_s=1, log_file=tmp_path / "u.txt")
    with pytest.raises(BridgeError, match="did not listen on 127.0.0.1:.* within 1 s .DONKEY_SIM_START_TIMEOUT"):
        part.start()
    assert part.process is None  # the silent one was ended
    with pytest.raises(BridgeError, match="DONKEY_SIM_PATH .*/nowhere: no such file"):
        SimulatorProcess(tmp_path / "nowhere", "127.0.0.1", port).start()
    plain = tmp_path / "not_executable"
    plain.write_text("data")
    with pytest.raises(BridgeError, match=r"cannot be started \(Permission denied\): make it executable \(chmod"):
        SimulatorProcess(plain, "127.0.0.1", port).start()


def test_a_car_with_donkey_sim_path_starts_the_simulator_drives_it_and_ends_it(tmp_path, monkeypatch):
    """The stand-in runs `vehicle sim serve`: a simulator speaking the Donkey protocol."""
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.config import Config

    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(Path.cwd()), os.environ.get("PYTHONPATH", "")]))
    port = _free_port()
    exe = _executable(tmp_path / "donkey_sim", SERVE)
    cfg = Config.defaults(CAR_PATH=str(tmp_path), SIM_TYPE="donkey", DONKEY_SIM_PATH=str(exe), SIM_PORT=port,
                          DONKEY_GYM_ENV_NAME="generated_track", DONKEY_SIM_START_TIMEOUT=120,
                          SIM_CONNECT_TIMEOUT_S=60)
    V = Vehicle()
    sim = assembly.add_simulator(V, cfg)
    frames: list[int] = []
    V.add(lambda image: frames.append(image is not None), inputs=["cam/image_array"])
    V.add(lambda: (0.0, 0.3), outputs=["angle", "throttle"])
    launcher = next(e.part for e in V.parts if isinstance(e.part, SimulatorProcess))
    V.start(rate_hz=20, max_loop_count=40)
    assert sim.telemetry_count > 0 and any(frames)  # it drove the launched simulator
    assert launcher.process is None and not port_open("127.0.0.1", port)  # and ended it on stop
