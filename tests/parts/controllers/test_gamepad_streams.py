"""Recorded event streams for every layout, through a pipe, decoded into drive commands."""

from __future__ import annotations

import pytest

from parts.controllers.events import AXIS_MAX
from parts.controllers.layouts import load_layout

LINUX_LAYOUTS = ["ps3", "ps4", "xbox", "xbox_bt", "f710", "generic"]


@pytest.mark.parametrize("name", LINUX_LAYOUTS)
def test_stream_drives_steers_and_stops(pipe_pad, name):
    layout = load_layout(name)
    pad = pipe_pad(layout, max_throttle=0.5)
    s = pad.stream
    out = pad.send(s.init_burst())
    assert (out.angle, out.throttle, out.mode, out.estop) == (0.0, 0.0, "user", False)
    out = pad.send(s.axis(layout.bindings["steering"], AXIS_MAX))
    assert out.angle == 1.0
    out = pad.send(s.axis(layout.bindings["steering"], -16384))
    assert out.angle == pytest.approx(-0.5, abs=1e-3)
    out = pad.send(s.axis(layout.bindings["throttle"], -AXIS_MAX))  # stick up = forward
    assert out.throttle == pytest.approx(0.5)
    assert out.recording  # AUTO_RECORD_ON_THROTTLE
    out = pad.send(s.press(layout.bindings["mode_toggle"]))
    assert out.mode == "local_angle"
    out = pad.send(s.press(layout.bindings["estop"]))
    assert (out.throttle, out.mode, out.estop, out.recording) == (0.0, "user", True, False)


@pytest.mark.parametrize("name", LINUX_LAYOUTS)
def test_every_button_action_of_the_layout(pipe_pad, name):
    layout = load_layout(name)
    pad = pipe_pad(layout, max_throttle=0.5, throttle_step=0.1, auto_record_on_throttle=False)
    s = pad.stream
    pad.send(s.init_burst())
    b = layout.bindings
    assert pad.send(s.press(b["throttle_up"])).throttle == 0.0
    assert pad.logic.max_throttle == pytest.approx(0.6)
    pad.send(s.press(b["throttle_down"]) + s.press(b["throttle_down"]))
    assert pad.logic.max_throttle == pytest.approx(0.4)
    out = pad.send(s.press(b["erase_records"]))
    assert out.erase is True
    assert pad.logic.output().erase is False  # one loop only: a rising edge
    assert pad.send(s.press(b["behavior_next"])).behavior_step == 1
    assert pad.send(s.press(b["behavior_prev"]) + s.press(b["behavior_prev"])).behavior_step == -2
    assert pad.send(s.press(b["record_toggle"])).recording is True
    assert pad.send(s.press(b["record_toggle"])).recording is False
    out = pad.send(s.press(b["constant_throttle"]))
    assert out.throttle == pytest.approx(0.4)
    assert pad.send(s.press(b["constant_throttle"])).throttle == 0.0
    modes = [pad.send(s.press(b["mode_toggle"])).mode for _ in range(3)]
    assert modes == ["local_angle", "local", "user"]


def test_held_button_at_connect_is_not_a_press(pipe_pad):
    layout = load_layout("ps4")
    pad = pipe_pad(layout)
    s = pad.stream
    from fixtures.gamepads import pack_event

    from parts.controllers.events import BUTTON

    share = s.button_index(layout.buttons["share"].code)
    out = pad.send(pack_event(BUTTON, share, 1, init=True) + s.init_burst()[8:])
    assert out.mode == "user"


def test_overflow_init_resend_mid_stream_keeps_state(pipe_pad):
    layout = load_layout("xbox")
    pad = pipe_pad(layout, max_throttle=1.0)
    s = pad.stream
    pad.send(s.init_burst())
    pad.send(s.axis("right_stick_y", -AXIS_MAX))
    out = pad.send(s.init_burst(right_stick_y=-AXIS_MAX))  # joydev re-sends INIT after overflow
    assert out.throttle == pytest.approx(1.0)
    assert out.mode == "user"


def test_stick_held_at_connect_is_not_armed_until_released(pipe_pad):
    layout = load_layout("ps4")
    pad = pipe_pad(layout, max_throttle=1.0)
    s = pad.stream
    out = pad.send(s.init_burst(right_stick_y=-12000))
    assert out.throttle == 0.0
    assert pad.send(s.axis("right_stick_y", -20000)).throttle == 0.0
    assert pad.send(s.axis("right_stick_y", 0)).throttle == 0.0
    assert pad.send(s.axis("right_stick_y", -AXIS_MAX)).throttle == pytest.approx(1.0)
