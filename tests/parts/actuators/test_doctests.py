"""The examples in the actuator modules' docstrings run and give what they show."""

from __future__ import annotations

import doctest
import importlib

import pytest


@pytest.mark.parametrize("name", ["parts.actuators.pca9685", "parts.actuators.pwm", "parts.actuators.esc",
                                  "parts.actuators.fake_pca9685", "fixtures.fake_i2c_dev",
                                  "parts.actuators.pins", "parts.actuators.motors",
                                  "parts.actuators.vesc_protocol"])
def test_docstring_examples(name):
    result = doctest.testmod(importlib.import_module(name))
    assert result.attempted > 0 and result.failed == 0
