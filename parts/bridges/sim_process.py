"""Launch the Donkey simulator executable and wait for its port, as DonkeyCar does (DONKEY_SIM_PATH).

DonkeyCar starts the Unity simulator itself when ``DONKEY_SIM_PATH`` names its executable
(gym-donkeycar's launcher: ``EXE --port PORT --host HOST -logFile unitylog.txt``), and connects when
the simulator listens. :class:`SimulatorProcess` is that launcher as a part: added before the
Donkey bridge, it starts the executable when the vehicle starts, waits until the port accepts a
connection (or the executable exits, or the time is up), watches the process while the car drives
(one log line if it dies) and ends it on shutdown.
"""

from __future__ import annotations

import logging
import socket
import subprocess
import time
from pathlib import Path
from typing import Any

from parts.bridges.errors import BridgeError
from vehicle.part import ThreadedPart

logger = logging.getLogger(__name__)


def port_open(host: str, port: int, timeout_s: float = 0.5) -> bool:
    """Whether a TCP connection to ``host:port`` is accepted now."""
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            return True
    except OSError:
        return False


class SimulatorProcess(ThreadedPart):
    """Part: the simulator executable at ``path``, started on ``start()``, ended on ``shutdown()``.

    Args:
        path: the executable (DONKEY_SIM_PATH).
        host, port: where it listens (SIM_HOST, SIM_PORT); passed as ``--host``/``--port``.
        timeout_s: seconds to wait for the port (DONKEY_SIM_START_TIMEOUT; Unity takes 5-30 s).
        log_file: the simulator's own log (``-logFile``), next to the car's other logs.
    """

    period = 1.0  # seconds between two looks at the process

    def __init__(self, path: str | Path, host: str, port: int, *, timeout_s: float = 60.0,
                 log_file: str | Path = "unitylog.txt") -> None:
        super().__init__()
        self.path = Path(path).expanduser()
        self.host, self.port = host, int(port)
        self.timeout_s = float(timeout_s)
        self.log_file = Path(log_file)
        self.process: subprocess.Popen[bytes] | None = None
        self._exit_reported = False

    @property
    def command(self) -> list[str]:
        """The command line, gym-donkeycar's."""
        return [str(self.path), "--port", str(self.port), "--host", self.host, "-logFile", str(self.log_file)]

    def start(self) -> SimulatorProcess:
        """Launch and wait until the port accepts a connection.

        Raises:
            BridgeError: the executable is missing or not runnable, exits first, or the port stays
                closed for ``timeout_s`` (the message names DONKEY_SIM_PATH and what to check).
        """
        if self.process is None:
            if port_open(self.host, self.port):
                raise BridgeError(f"something already listens on {self.host}:{self.port}: close it, or set "
                                  "DONKEY_SIM_PATH = 'remote' to use the simulator that runs there")
            if not self.path.is_file():
                raise BridgeError(f"DONKEY_SIM_PATH {self.path}: no such file; give the simulator's executable "
                                  "(donkey_sim.x86_64, DonkeySimWin/donkey_sim.exe, donkey_sim.app/Contents/MacOS/"
                                  "donkey_sim) or 'remote'")
            self.log_file.parent.mkdir(parents=True, exist_ok=True)
            try:
                self.process = subprocess.Popen(self.command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                                stderr=subprocess.DEVNULL, start_new_session=True)
            except OSError as exc:
                raise BridgeError(f"DONKEY_SIM_PATH {self.path} cannot be started ({exc.strerror}): make it "
                                  "executable (chmod +x)") from exc
            logger.info("started the Donkey simulator (process %d): %s", self.process.pid, " ".join(self.command))
            self._wait_for_port()
        return super().start()

    def _wait_for_port(self) -> None:
        assert self.process is not None
        deadline = time.monotonic() + self.timeout_s
        while not port_open(self.host, self.port):
            code = self.process.poll()
            if code is not None:
                self.process = None
                raise BridgeError(f"the Donkey simulator {self.path} exited with code {code} before it listened "
                                  f"on port {self.port}; its log: {self.log_file}")
            if time.monotonic() >= deadline:
                self.close()
                raise BridgeError(f"the Donkey simulator {self.path} did not listen on {self.host}:{self.port} "
                                  f"within {self.timeout_s:g} s (DONKEY_SIM_START_TIMEOUT); its log: {self.log_file}")
            time.sleep(0.2)
        logger.info("the Donkey simulator listens on %s:%d", self.host, self.port)

    def poll(self) -> Any:
        """The process's exit code once it has exited (logged once), else NOTHING."""
        code = self.process.poll() if self.process is not None else None
        if code is not None and not self._exit_reported:
            self._exit_reported = True
            logger.error("the Donkey simulator exited (code %d) while the car was driving; its log: %s",
                         code, self.log_file)
        return self.NOTHING if code is None else code

    def close(self) -> None:
        """End the simulator: SIGTERM, then SIGKILL after 5 s."""
        process, self.process = self.process, None
        if process is None or process.poll() is not None:
            return
        process.terminate()
        try:
            process.wait(5.0)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5.0)
        logger.info("ended the Donkey simulator (process %d)", process.pid)
