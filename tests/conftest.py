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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """pytest-timeout's hang guard (``timeout`` in pyproject.toml, for a quiet machine) scaled by
    the machine's load when the run starts, like every other wait (fixtures.load): at load 10 on
    2 cores a test takes about five times as long, and must not be called hung for it."""
    from fixtures.load import load_factor

    base = config.getini("timeout")  # pytest-timeout's ini setting
    if not base or load_factor() <= 1.0:
        return
    for item in items:
        if item.get_closest_marker("timeout") is None:
            item.add_marker(pytest.mark.timeout(float(base) * load_factor()))
