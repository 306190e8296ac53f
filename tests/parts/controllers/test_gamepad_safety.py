"""Safety of the gamepad: triggers at rest, lost and silent pads, e-stop, the threaded part."""

from __future__ import annotations

import logging
import os
import time

import pytest

from parts.controllers.events import AXIS_MAX
from parts.controllers.gamepad import Gamepad
from parts.controllers.layouts import load_layout
from parts.controllers.linux_js import LinuxJoystick
from parts.controllers.logic import GamepadSettings


def test_trigger_bound_to_throttle_reads_zero_at_rest(pipe_pad):
    layout = load_layout("xbox").with_bindings({"throttle": "", "throttle_forward": "rt",
                                                "throttle_reverse": "lt"})
    pad = pipe_pad(layout, max_throttle=1.0)
    s = pad.stream
    assert pad.send(s.init_burst()).throttle == 0.0  # both triggers at -32767
    assert pad.send(s.axis("rt", AXIS_MAX)).throttle == pytest.approx(1.0)
    assert pad.send(s.axis("rt", 0)).throttle == pytest.approx(0.5)
    assert pad.send(s.axis("rt", -AXIS_MAX)).throttle == 0.0
    assert pad.send(s.axis("lt", AXIS_MAX)).throttle == pytest.approx(-1.0)


def test_trigger_in_a_stick_slot_never_means_throttle(pipe_pad, caplog):
    # DonkeyCar's trap: a layout that calls RT (ABS_RZ, resting at -32767) a stick, bound to throttle
    layout = load_layout("generic").with_bindings({"throttle": "axis_5"})
    pad = pipe_pad(layout, max_throttle=1.0)
    s = pad.stream
    raw_rest = s.init_burst(axis_5=-AXIS_MAX)
    with caplog.at_level(logging.ERROR):
        assert pad.send(raw_rest).throttle == 0.0
    assert "rests at -32767" in caplog.text and "trigger" in caplog.text
    assert pad.send(s.axis("axis_5", 0)).throttle == 0.0
    assert pad.send(s.axis("axis_5", AXIS_MAX)).throttle == 0.0


def test_disconnect_means_throttle_zero_and_user_mode(pipe_pad):
    layout = load_layout("ps4")
    pad = pipe_pad(layout, max_throttle=1.0)
    s = pad.stream
    pad.send(s.init_burst() + s.press("share") + s.press("share"))
    out = pad.send(s.axis("right_stick_y", -AXIS_MAX))
    assert out.mode == "local" and out.throttle == pytest.approx(1.0)
    pad.close_writer()
    from parts.controllers.events import DeviceLost

    with pytest.raises(DeviceLost):
        pad.reader.read(0.1)
    pad.logic.on_disconnect()
    out = pad.logic.output()
    assert (out.throttle, out.mode, out.recording) == (0.0, "user", False)


def test_silent_pad_means_throttle_zero_and_user_mode(pipe_pad, caplog):
    layout = load_layout("xbox")
    pad = pipe_pad(layout, max_throttle=1.0, silence_timeout_s=2.0)
    s = pad.stream
    pad.send(s.init_burst() + s.press("a"))
    out = pad.send(s.axis("right_stick_y", -AXIS_MAX))
    assert out.throttle == 1.0 and out.mode == "local_angle"
    pad.clock.t += 1.0
    assert pad.logic.output().throttle == 1.0  # a held stick for 1 s is fine
    pad.clock.t += 1.5
    with caplog.at_level(logging.ERROR):
        out = pad.logic.output()
    assert (out.throttle, out.mode) == (0.0, "user")
    assert "silent" in caplog.text
    # the pad talks again with the stick still forward: not armed until released
    assert pad.send(s.axis("right_stick_y", -AXIS_MAX + 1)).throttle == 0.0
    assert pad.send(s.axis("right_stick_y", 0)).throttle == 0.0
    assert pad.send(s.axis("right_stick_y", -AXIS_MAX)).throttle == 1.0


def test_silence_with_zero_throttle_is_not_a_fault(pipe_pad):
    pad = pipe_pad(load_layout("xbox"))
    out = pad.send(pad.stream.init_burst() + pad.stream.press("a"))
    pad.clock.t += 60
    assert pad.logic.output().mode == "local_angle"
    assert out.throttle == 0.0


def test_estop_latches_blocks_mode_and_releases(pipe_pad):
    layout = load_layout("f710")
    pad = pipe_pad(layout, max_throttle=1.0)
    s = pad.stream
    pad.send(s.init_burst())
    pad.send(s.axis("right_stick_y", -AXIS_MAX))
    out = pad.send(s.press("a"))  # F710: A = e-stop
    assert (out.estop, out.throttle) == (True, 0.0)
    assert pad.send(s.press("start")).mode == "user"  # mode toggle refused while latched
    assert pad.send(s.press("back")).throttle == 0.0  # constant throttle refused
    out = pad.send(s.press("a"))
    assert out.estop is False and out.throttle == 0.0  # released, but the stick must come back first
    pad.send(s.axis("right_stick_y", 0))
    assert pad.send(s.axis("right_stick_y", -AXIS_MAX)).throttle == 1.0


def test_settings_are_validated():
    with pytest.raises(ValueError, match="JOYSTICK_MAX_THROTTLE"):
        GamepadSettings(max_throttle=1.5)
    with pytest.raises(ValueError, match="JOYSTICK_THROTTLE_DIR"):
        GamepadSettings(throttle_dir=0.5)


def _wait_for(pred, timeout=5.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = pred()
        if value:
            return value
        time.sleep(0.01)
    raise AssertionError("condition not reached")


def test_threaded_part_over_a_fifo_survives_loss_and_reconnects(tmp_path, caplog, stream_for):
    layout = load_layout("ps3")
    s = stream_for(layout)
    fifo = tmp_path / "js0"
    os.mkfifo(fifo)
    part = Gamepad(LinuxJoystick(str(fifo), fallback_caps=layout.caps), layout,
                   GamepadSettings(max_throttle=0.8), retry_s=0.05, read_timeout_s=0.02)
    caplog.set_level(logging.ERROR)
    part.start()
    try:
        with open(fifo, "wb", buffering=0) as w:
            w.write(s.init_burst() + s.axis("right_stick_y", -AXIS_MAX) + s.press("select"))
            out = _wait_for(lambda: (o := part.run_threaded()).throttle and o)
            assert out.throttle == pytest.approx(0.8) and out.mode == "local_angle"
        out = _wait_for(lambda: (o := part.run_threaded()).throttle == 0.0 and o)
        assert out.mode == "user"
        assert "gamepad lost" in caplog.text
        with open(fifo, "wb", buffering=0) as w:  # the pad comes back (re-opened by the part)
            w.write(s.init_burst() + s.axis("left_stick_x", AXIS_MAX))
            out = _wait_for(lambda: (o := part.run_threaded()).angle == 1.0 and o)
            assert out.throttle == 0.0
    finally:
        part.shutdown()
    assert not part.running


def test_missing_pad_gives_neutral_and_one_error(tmp_path, caplog):
    layout = load_layout("xbox")
    part = Gamepad(LinuxJoystick(str(tmp_path / "js0"), fallback_caps=layout.caps), layout,
                   retry_s=0.01, read_timeout_s=0.01)
    with caplog.at_level(logging.ERROR):
        for _ in range(3):
            out = part.run()
            time.sleep(0.02)
    assert (out.angle, out.throttle, out.mode, out.recording) == (0.0, 0.0, "user", False)
    assert caplog.text.count("no joystick at") == 1
    part.shutdown()


def test_non_threaded_run_replays_a_recording(tmp_path, stream_for):
    layout = load_layout("xbox")
    s = stream_for(layout)
    rec = tmp_path / "pad.js"
    rec.write_bytes(s.init_burst() + s.axis("left_stick_x", -AXIS_MAX) + s.press("b"))
    part = Gamepad(LinuxJoystick(str(rec), fallback_caps=layout.caps), layout,
                   GamepadSettings(auto_record_on_throttle=False))
    out = part.run()
    assert out.angle == -1.0 and out.recording is True
    out = part.run()  # end of the recording: lost, neutral, and no reconnect attempts
    assert (out.angle, out.throttle, out.mode) == (0.0, 0.0, "user")
    part.shutdown()


def test_an_off_silence_timeout_is_said_at_start(caplog):
    from parts.controllers.logic import GamepadLogic

    layout = load_layout("xbox")
    with caplog.at_level(logging.WARNING):
        GamepadLogic(layout, GamepadSettings(silence_timeout_s=2.0))
    assert "JOYSTICK_SILENCE_TIMEOUT_S" not in caplog.text
    with caplog.at_level(logging.WARNING):
        GamepadLogic(layout, GamepadSettings(silence_timeout_s=None))
    assert "JOYSTICK_SILENCE_TIMEOUT_S = None" in caplog.text and "Bluetooth" in caplog.text
