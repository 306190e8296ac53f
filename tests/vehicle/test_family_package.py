"""A new kind of sensor from a package of its own (docs/examples/car_sonar, contributing.md's
worked example): built as a wheel and installed apart from the project, it is found through the
``vehicle.families`` entry points, recorded by a drive and checked by ``vehicle hw check``, with no
line of the project edited. The code blocks of contributing.md are the package's files."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
import textwrap
import threading
import tty
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "car_sonar"
GUIDE = ROOT / "docs" / "contributing.md"


class MaxSonarDevice:
    """The rangefinder's TX line on a pty: "R" + millimetres + CR, every 50 ms (it says 0850)."""

    def __init__(self, mm: int = 850) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self.line = f"R{mm:04d}\r".encode()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._talk, daemon=True)
        self._thread.start()

    def _talk(self) -> None:
        os.set_blocking(self._master, False)  # a full buffer (nobody reading yet) drops readings
        while not self._stop.wait(0.05):
            with contextlib.suppress(BlockingIOError):
                os.write(self._master, self.line)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        os.close(self._master)
        os.close(self._slave)


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The example package, built and installed (no dependencies: they are this environment's) into
    a folder of its own, as `pip install` puts a published package beside the project."""
    pytest.importorskip("setuptools", minversion="77", reason="the dev extra installs setuptools (pip install -e "
                        ".[dev])")
    src = tmp_path_factory.mktemp("src") / "car_sonar"
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "build"))
    target = tmp_path_factory.mktemp("site")
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--disable-pip-version-check", "--no-deps",
                           "--no-build-isolation", "--no-index", "--target", str(target), str(src)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (target / "car_sonar" / "sonar.py").is_file()
    return target


def _run(site: Path, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT)])}
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, cwd=cwd, timeout=120)


DRIVE = textwrap.dedent("""
    import sys
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.config import load_config
    from parts.tub.tub import Tub

    cfg = load_config(car_path=sys.argv[1])
    V = Vehicle()
    assembly.add_camera(V, cfg)
    assembly.add_sensors(V, cfg)
    V.mem.update({"recording": True, "user/angle": 0.0, "user/throttle": 0.0, "user/mode": "user"})  # the controller's
    writer = assembly.add_tub_writer(V, cfg)
    V.start(rate_hz=20, max_loop_count=30)
    with Tub(writer.path, read_only=True) as tub:
        records = [r for _, r in tub.records()]
        print(tub.inputs)
        print(sorted({r.get("sonar/distance") for r in records} - {None}))
""")


def test_an_installed_sensor_package_is_recorded_and_checked(installed, tmp_path):
    device = MaxSonarDevice(850)
    try:
        car = tmp_path / "car"
        car.mkdir()
        (car / "myconfig.py").write_text(f"HAVE_SONAR = True\nSONAR_SERIAL = {device.path!r}\nCAMERA_TYPE = 'MOCK'\n"
                                         "AUTO_CREATE_NEW_TUB = True\n")
        check = _run(installed, "-m", "vehicle", "hw", "check", "--car", str(car), cwd=tmp_path)
        assert check.returncode == 0, check.stdout + check.stderr
        assert check.stdout.strip() == f"sonar  MAXSONAR on {device.path}: nearest object 0.85 m ahead"
        drive = _run(installed, "-c", DRIVE, str(car), cwd=tmp_path)
        assert drive.returncode == 0, drive.stderr[-3000:]
        inputs, seen = drive.stdout.strip().splitlines()[-2:]
        assert "'sonar/distance'" in inputs and "sonar/ok" not in inputs  # what RECORDED says, no more
        assert seen == "[0.85]"
        # the package's settings are validated like the project's: a value out of its declared range
        (car / "myconfig.py").write_text("HAVE_SONAR = True\nSONAR_MAX_AGE_S = 9.0\n")
        bad = _run(installed, "-m", "vehicle", "hw", "check", "--car", str(car), cwd=tmp_path)
        assert bad.returncode != 0 and "SONAR_MAX_AGE_S" in bad.stderr and "Traceback" not in bad.stderr
    finally:
        device.close()


def test_without_the_package_the_kind_is_unknown(tmp_path):
    car = tmp_path / "car"
    car.mkdir()
    (car / "myconfig.py").write_text("HAVE_SONAR = True\n")
    run = _run(tmp_path, "-m", "vehicle", "hw", "check", "--car", str(car), cwd=tmp_path)
    assert run.returncode != 0 and "unknown setting HAVE_SONAR" in run.stderr, run.stderr


def test_contributing_shows_the_example_package_file_by_file():
    """Every file of the example package appears whole in contributing.md, under its path."""
    guide = GUIDE.read_text()
    blocks = dict(re.findall(r"^`(docs/examples/car_sonar/[\w/.]+)`:\n\n```\w*\n(.*?)^```$", guide, re.M | re.S))
    files = {str(p.relative_to(ROOT)): p.read_text() for p in sorted(EXAMPLE.rglob("*"))
             if p.is_file() and "__pycache__" not in p.parts}
    assert set(blocks) == set(files), "contributing.md shows other files than docs/examples/car_sonar holds"
    for path, text in files.items():
        assert blocks[path] == text, f"contributing.md's copy of {path} differs from the file"
