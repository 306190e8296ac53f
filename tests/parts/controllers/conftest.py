"""The gamepad tests' clock; the stream and pipe fixtures are in tests/fixtures/gamepads.py."""

from __future__ import annotations

import pytest
from fixtures.gamepads import FakeClock


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()
