"""Fixtures shared by every test folder."""

from __future__ import annotations

import os

import pytest

# fixtures shared by several folders (tests/ is on sys.path: this conftest.py lives there);
# fixtures.browser: Playwright driving Debian's chromium, for any test folder
pytest_plugins = ("fixtures.sim", "fixtures.pilots", "fixtures.tubs", "fixtures.gamepads", "fixtures.browser")

# pygame parts must never try to open a window in tests.
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """Two cores are shared by parallel tests: keep torch (if it is loaded) to one thread."""
    import sys

    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)
    yield
