"""The Robo HAT MM1 drivetrain against a fake MM1 on a pty that parses lines as its firmware does."""

from __future__ import annotations

import pytest
from fixtures.fake_mm1 import FakeMM1

from parts.actuators.drivetrain import DrivetrainError
from parts.actuators.mm1 import RoboHatMM1

SAFE = dict(arm_s=0.0, watchdog_s=None, sleep=lambda s: None)


@pytest.fixture
def mm1():
    with FakeMM1() as device:
        yield device


def test_pulses_follow_donkeycars_mapping():
    part = RoboHatMM1("/dev/null", steering_mid=1520, max_forward=1900, stopped=1500, max_reverse=1100)
    assert part.pulses(0.0, 0.0) == (1520, 1500)
    assert part.pulses(-1.0, 1.0) == (2000, 1900)
    assert part.pulses(1.0, -1.0) == (1000, 1100)
    assert part.pulses(0.5, 0.5) == (1260, 1700)


def test_drives_and_returns_to_neutral(mm1):
    part = RoboHatMM1(mm1.port, **SAFE).open()
    part.run(0.0, 0.0)
    part.run(-1.0, 0.5)
    assert mm1.wait_for(lambda: mm1.output == (2000, 1750))
    part.neutral()
    assert mm1.wait_for(lambda: mm1.output == (1500, 1500))
    part.run(0.0, 0.0)  # after neutral the throttle waits for a command at neutral
    for _ in range(300):  # the board's RC lines keep coming; the part never chokes on them
        part.run(0.2, 0.1)
    assert mm1.wait_for(lambda: mm1.output == (1400, 1550))
    part.shutdown()
    assert mm1.wait_for(lambda: mm1.output == (1500, 1500))
    assert mm1.rejected == []


def test_bad_pulses_are_refused():
    with pytest.raises(ValueError, match="MM1_MAX_FORWARD must be a pulse in µs, an int 1000-2000, got 2100"):
        RoboHatMM1("/dev/ttyS0", max_forward=2100)
    with pytest.raises(ValueError, match="MM1_STOPPED_PWM .1000. must lie strictly between"):
        RoboHatMM1("/dev/ttyS0", stopped=1000)


def test_a_pulled_cable_is_one_line_on_shutdown(mm1):
    part = RoboHatMM1(mm1.port, **SAFE).open()
    part.run(0.0, 0.0)
    mm1.stop()  # the board's end of the pty is gone: the cable is pulled
    with pytest.raises(DrivetrainError, match=r"^MM1_SERIAL_PORT = '.*': the serial link failed .*RC receiver$") as e:
        part.shutdown()
    assert "\n" not in str(e.value)
