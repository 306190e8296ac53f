"""Decoding of the joydev event format and the capability queries (with their fallback)."""

from __future__ import annotations

import array
import errno
import os
import time

import pytest
from fixtures.gamepads import pack_event

from parts.controllers import linux_js
from parts.controllers.events import (
    AXIS,
    BUTTON,
    JSIOCGAXES,
    JSIOCGAXMAP,
    JSIOCGBTNMAP,
    JSIOCGBUTTONS,
    JSIOCGNAME,
    Caps,
    DeviceLost,
    PadEvent,
    parse_code,
    parse_events,
)
from parts.controllers.linux_js import LinuxJoystick, query_caps

CAPS = Caps("pad", (0, 1, 2, 3, 4, 5, 16, 17), (0x130, 0x131, 0x133))


def test_ioctl_numbers_match_linux_joystick_h():
    assert JSIOCGAXES == 0x80016A11
    assert JSIOCGBUTTONS == 0x80016A12
    assert JSIOCGAXMAP == 0x80406A32
    assert JSIOCGBTNMAP == 0x84006A34
    assert JSIOCGNAME & 0xFFFF == 0x6A13 and JSIOCGNAME >> 16 == 0x8000 | 128


def test_parse_translates_indices_to_kernel_codes_and_keeps_the_tail():
    data = (pack_event(BUTTON, 1, 1, time_ms=5) + pack_event(AXIS, 6, -32767, init=True)
            + pack_event(AXIS, 2, 16384))
    events, tail = parse_events(data + b"\x01\x02\x03", CAPS)
    assert events == [PadEvent(BUTTON, 0x131, 1, False, 5), PadEvent(AXIS, 16, -32767, True, 0),
                      PadEvent(AXIS, 2, 16384, False, 0)]
    assert tail == b"\x01\x02\x03"


def test_event_layout_is_8_bytes_IhBB():
    raw = pack_event(AXIS, 3, -2, init=True, time_ms=0x01020304)
    assert raw == bytes([4, 3, 2, 1, 0xFE, 0xFF, 0x82, 3])


def test_unknown_indices_get_synthetic_codes_and_autorepeat_is_a_press():
    events, _ = parse_events(pack_event(AXIS, 9, 7) + pack_event(BUTTON, 5, 2), CAPS)
    assert events == [PadEvent(AXIS, 0x1009, 7), PadEvent(BUTTON, 0x1005, 1)]


@pytest.mark.parametrize(("text", "code"), [(304, 304), ("0x130", 0x130), ("17", 17)])
def test_parse_code(text, code):
    assert parse_code(text) == code


def test_parse_code_rejects_garbage():
    with pytest.raises(ValueError, match="not a number"):
        parse_code("BTN_A")
    with pytest.raises(TypeError):
        parse_code(True)


def test_pipe_answers_enotty_so_the_fallback_caps_are_used():
    r, w = os.pipe()
    try:
        assert query_caps(r, CAPS) is CAPS
    finally:
        os.close(r)
        os.close(w)


def test_query_caps_reads_name_counts_and_maps(monkeypatch):
    def fake_ioctl(fd, request, buf):
        if request == JSIOCGNAME:
            name = b"Fake X-Box pad\0\0"
            buf[: len(name)] = array.array("B", name)
        elif request == JSIOCGAXES:
            buf[0] = 3
        elif request == JSIOCGBUTTONS:
            buf[0] = 2
        elif request == JSIOCGAXMAP:
            buf[:3] = array.array("B", [0, 1, 5])
        elif request == JSIOCGBTNMAP:
            buf[:2] = array.array("H", [0x130, 0x13B])
        else:
            raise OSError(errno.ENOTTY, "bad request")
        return 0

    import fcntl

    monkeypatch.setattr(fcntl, "ioctl", fake_ioctl)
    caps = query_caps(0, CAPS)
    assert caps == Caps("Fake X-Box pad", (0, 1, 5), (0x130, 0x13B))


def test_query_caps_reports_unplug_as_device_lost(monkeypatch):
    import fcntl

    def gone(fd, request, buf):
        raise OSError(errno.ENODEV, "No such device")

    monkeypatch.setattr(fcntl, "ioctl", gone)
    with pytest.raises(DeviceLost):
        query_caps(0, CAPS)


def test_reader_over_a_pipe_decodes_and_reports_eof_as_lost():
    r, w = os.pipe()
    js = LinuxJoystick(fd=r, fallback_caps=CAPS)
    assert js.open() == CAPS
    assert not js.reconnectable
    os.write(w, pack_event(BUTTON, 2, 1)[:5])
    assert js.read(0.05) == []  # half an event: kept for the next read
    os.write(w, pack_event(BUTTON, 2, 1)[5:])
    assert js.read(0.05) == [PadEvent(BUTTON, 0x133, 1)]
    assert js.read(0.0) == []
    os.close(w)
    with pytest.raises(DeviceLost, match="end of stream"):
        js.read(0.05)
    js.close()


def test_reader_over_a_fifo(tmp_path):
    fifo = tmp_path / "js0"
    os.mkfifo(fifo)
    js = LinuxJoystick(str(fifo), fallback_caps=CAPS)
    js.open()  # does not wait for a writer
    assert js.reconnectable
    assert js.read(0.01) == []  # no writer yet: nothing, not EOF
    with open(fifo, "wb", buffering=0) as writer:
        writer.write(pack_event(AXIS, 0, 32767, init=True))
        assert js.read(0.5) == [PadEvent(AXIS, 0, 32767, True)]
    with pytest.raises(DeviceLost):
        js.read(0.5)
    js.close()


def test_missing_device_error_names_path_and_fix(tmp_path):
    js = LinuxJoystick(str(tmp_path / "js9"))
    with pytest.raises(FileNotFoundError, match="JOYSTICK_DEVICE_FILE"):
        js.open()


def test_recording_file_is_replayed_at_its_recorded_pace(tmp_path):
    rec = tmp_path / "drive.js"
    rec.write_bytes(pack_event(AXIS, 0, 100, init=True, time_ms=1000)
                    + pack_event(AXIS, 0, 200, time_ms=1000) + pack_event(AXIS, 0, 300, time_ms=1150))
    js = LinuxJoystick(str(rec), fallback_caps=CAPS)
    js.open()
    assert not js.reconnectable
    first = js.read(0.0)
    assert [e.value for e in first] == [100, 200]
    later: list[PadEvent] = []
    deadline = time.monotonic() + 5
    while not later and time.monotonic() < deadline:
        later = js.read(0.05)
    assert [e.value for e in later] == [300]
    with pytest.raises(DeviceLost, match="end of the recorded"):
        js.read(0.0)


def test_reader_needs_a_path_or_fd():
    with pytest.raises(ValueError, match="/dev/input/js0"):
        linux_js.LinuxJoystick()
