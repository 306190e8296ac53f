"""Fixtures of the simulator tests: a coarse texture keeps track generation fast."""

from __future__ import annotations

import pytest

from vehicle.config import Config


@pytest.fixture
def cfg() -> Config:
    """Default settings with a 2 cm texture (tests do not need 1 cm detail)."""
    return Config.defaults(SIM_TEXTURE_RES=0.02, SIM_REALTIME=False)


@pytest.fixture
def world() -> dict:
    """load_world() keyword arguments matching the cfg fixture."""
    return {"res": 0.02}
