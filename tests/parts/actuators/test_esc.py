"""Slew-rate limiter and reverse double-tap state machine (pure, clock passed in)."""

from __future__ import annotations

import pytest

from parts.actuators.esc import ReverseState, ReverseStateMachine, SlewLimiter


def test_slew_limits_growth_only():
    s = SlewLimiter(4.0)
    out = [s.step(1.0, t) for t in (0.0, 0.0625, 0.125, 0.1875, 0.25, 0.3125)]
    assert out == [0.0, 0.25, 0.5, 0.75, 1.0, 1.0]
    assert s.step(0.2, 0.375) == 0.2  # releasing is immediate
    assert s.step(-1.0, 0.4375) == -0.25  # through zero at once, then ramps in reverse
    s.reset()
    assert s.step(0.5, 10.0) == 0.0


def test_slew_off_passes_through():
    s = SlewLimiter(None)
    assert [s.step(v, t) for v, t in ((1.0, 0.0), (-1.0, 0.01))] == [1.0, -1.0]


@pytest.mark.parametrize("rate", [0, -1.0, float("inf"), True])
def test_slew_rate_must_be_positive(rate):
    with pytest.raises(ValueError, match="THROTTLE_SLEW_RATE"):
        SlewLimiter(rate)


def test_double_tap_sequence_and_states():
    sm = ReverseStateMachine("double_tap", brake_s=0.25, neutral_s=0.125)
    trace = []
    for i, cmd in enumerate([0.5, -0.5, -0.5, -0.5, -0.5, -0.5, -0.5, -0.25]):
        trace.append((sm.step(cmd, i * 0.125), sm.state))
    assert trace == [
        (0.5, ReverseState.DRIVE),
        (-0.5, ReverseState.BRAKE),  # t=0.125: first reverse pulse brakes
        (-0.5, ReverseState.BRAKE),
        (0.0, ReverseState.PAUSE),  # t=0.375: neutral so the ESC will accept reverse
        (-0.5, ReverseState.REVERSE),  # t=0.5: reverse engaged
        (-0.5, ReverseState.REVERSE),
        (-0.5, ReverseState.REVERSE),
        (-0.25, ReverseState.REVERSE),
    ]


def test_double_tap_aborts_on_forward_and_restarts():
    sm = ReverseStateMachine("double_tap", brake_s=0.125, neutral_s=0.125)
    assert sm.step(-1.0, 0.0) == -1.0 and sm.state is ReverseState.BRAKE
    assert sm.step(0.0, 0.0625) == 0.0 and sm.state is ReverseState.DRIVE
    assert sm.step(-1.0, 0.125) == -1.0 and sm.state is ReverseState.BRAKE  # brake again, not reverse
    sm.reset()
    assert sm.state is ReverseState.DRIVE


def test_direct_mode_passes_everything():
    sm = ReverseStateMachine("direct")
    assert [sm.step(v, 0.0) for v in (0.5, -1.0, -0.5)] == [0.5, -1.0, -0.5]


@pytest.mark.parametrize(("args", "message"), [
    (("sometimes",), "ESC_REVERSE_MODE"), (("double_tap", -0.1), "ESC_REVERSE_BRAKE_S"),
    (("double_tap", 0.1, 9), "ESC_REVERSE_NEUTRAL_S")])
def test_reverse_settings_are_checked(args, message):
    with pytest.raises(ValueError, match=message):
        ReverseStateMachine(*args)
