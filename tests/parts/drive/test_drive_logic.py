"""Behaviour state, recording rules, throttle filter and camera watchdog."""

from __future__ import annotations

import logging

import pytest

from parts.drive.behavior import BehaviorState
from parts.drive.recording import RecordingRules
from parts.drive.safety import CameraWatchdog
from parts.drive.throttle_filter import ThrottleFilter


def test_behavior_one_hot_as_in_the_thesis():
    b = BehaviorState(["Left_Lane", "Right_Lane"])
    assert b.run() == (0, "Left_Lane", [1.0, 0.0])
    assert b.run(1) == (1, "Right_Lane", [0.0, 1.0])
    assert b.run(1) == (0, "Left_Lane", [1.0, 0.0])  # wraps
    assert b.run(-1) == (1, "Right_Lane", [0.0, 1.0])
    assert b.run(0) == b.run(None) == (1, "Right_Lane", [0.0, 1.0])


def test_behavior_set_state_and_errors():
    b = BehaviorState(["a", "b", "c"], initial="c")
    assert b.run()[0] == 2
    b.decrement_state()
    assert b.run()[1] == "b"
    with pytest.raises(ValueError, match="unknown behaviour 'd'"):
        b.set_state("d")
    with pytest.raises(ValueError, match="0..2"):
        b.set_state(3)
    with pytest.raises(ValueError, match="BEHAVIOR_LIST is empty"):
        BehaviorState([])
    with pytest.raises(ValueError, match="duplicate"):
        BehaviorState(["a", "a"])


@pytest.mark.parametrize(("auto", "ai", "mode", "recording", "throttle", "estop", "expected"), [
    (True, False, "user", False, 0.3, None, True),  # auto-record on throttle
    (True, False, "user", True, 0.0, None, False),  # released: stops, whatever was asked
    (True, False, "user", False, -0.2, None, True),  # reversing counts too
    (True, False, "user", False, 0.005, None, False),  # within the dead zone
    (False, False, "user", True, 0.0, None, True),  # manual toggle honoured
    (False, False, "local", True, 0.5, None, False),  # no recording in autopilot
    (True, False, "local_angle", False, 0.5, None, False),
    (False, True, "local", True, 0.5, None, True),  # RECORD_DURING_AI
    (True, True, "local", False, 0.5, None, True),
    (True, False, "user", True, 0.5, True, False),  # e-stop stops recording
])
def test_recording_rules(auto, ai, mode, recording, throttle, estop, expected):
    assert RecordingRules(auto, ai, 0.01).run(mode, recording, throttle, estop) is expected


def test_throttle_filter_double_tap_like_donkeycar():
    f = ThrottleFilter()
    seq = [0.5, -0.5, -0.5, -0.5, 0.0, -0.3, -0.3, 0.2, None]
    assert [f.run(t) for t in seq] == [0.5, -0.5, 0.0, -0.5, 0.0, -0.3, 0.0, 0.2, None]


def test_camera_watchdog_disengages_and_stays_tripped_until_user_mode(caplog):
    w = CameraWatchdog()
    assert w.run(True, "local", 0.4) == ("local", 0.4)
    with caplog.at_level(logging.ERROR):
        assert w.run(False, "local", 0.4) == ("user", 0.0)
    assert "pilot disengaged" in caplog.text
    assert w.run(True, "local", 0.4) == ("user", 0.0)  # frames back: the pilot does not re-engage
    assert w.run(False, "user", 0.3) == ("user", 0.3)  # the human may drive without a camera
    assert w.run(True, "local_angle", 0.2) == ("local_angle", 0.2)  # reset by user mode
