#!/usr/bin/env python3
"""Set everything up in .venv and run the demo or the tests (standard library only).

    python3 bootstrap.py demo     # record with the expert, train, evaluate on unseen tracks
    python3 bootstrap.py test     # lint and run the whole test suite

Needs Python 3.11+ and pip. The first run creates .venv and installs the project with every
extra; torch is pinned to the CPU build 2.13.0 (an unpinned torch would pull gigabytes of CUDA
packages). Later runs reinstall only when pyproject.toml changed.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
STAMP = VENV / ".installed"
TORCH = "torch==2.13.0"


def sh(*cmd: str | Path, env: dict[str, str] | None = None) -> None:
    print("+", " ".join(str(c) for c in cmd), flush=True)
    subprocess.run([str(c) for c in cmd], check=True, cwd=ROOT, env=env)


def setup() -> None:
    """Create .venv and install the project unless pyproject.toml is unchanged since last time."""
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    if STAMP.exists() and STAMP.read_text() == digest:
        return
    if not (BIN / "python").exists():
        sh(sys.executable, "-m", "venv", VENV)
    pip = (BIN / "python", "-m", "pip", "install", "--quiet", "--disable-pip-version-check")
    sh(*pip, "--upgrade", "pip")
    sh(*pip, TORCH)
    sh(*pip, "-e", ".[all,dev]")
    STAMP.write_text(digest)


def install_browser() -> None:
    """Debian's chromium for the web page tests, where apt can be used; else they are skipped."""
    if shutil.which("chromium") or shutil.which("chromium-browser"):
        return
    if os.name != "posix" or os.geteuid() != 0 or not shutil.which("apt-get"):
        print("chromium not found: the browser tests will be skipped", flush=True)
        return
    try:
        sh("apt-get", "update", "-qq")
        sh("apt-get", "install", "-y", "-qq", "chromium",
           env={**os.environ, "DEBIAN_FRONTEND": "noninteractive"})
    except subprocess.CalledProcessError:
        print("could not install chromium: the browser tests will be skipped", flush=True)


def main(argv: list[str]) -> int:
    if len(argv) != 1 or argv[0] not in ("demo", "test"):
        print(__doc__)
        return 2
    setup()
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy"}
    try:
        if argv[0] == "demo":
            sh(BIN / "vehicle", "demo", env=env)
        else:
            install_browser()
            sh(BIN / "ruff", "check", "vehicle", "parts", "training", "templates", "tests", "bench", "bootstrap.py")
            # in parallel, one worker per core; a test file stays on one worker (its module
            # fixtures are built once, its tests share their files and servers in order)
            sh(BIN / "python", "-m", "pytest", "-q", "-n", "auto", "--dist", "loadfile", env=env)
    except subprocess.CalledProcessError as exc:
        return exit_status(exc.returncode)
    except KeyboardInterrupt:
        return 130
    return 0


def exit_status(returncode: int) -> int:
    """The command's exit status as a shell reports it: pytest's own (1 failed tests, 2
    interrupted, 3 internal error, 4 usage error, 5 no tests), 128 + N for a child killed by signal N."""
    if returncode < 0:
        return 128 - returncode
    return returncode or 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
