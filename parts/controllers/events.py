"""Gamepad events shared by every backend, and decoding of the Linux joystick (joydev) ABI.

A Linux ``/dev/input/jsN`` device delivers 8-byte ``struct js_event`` records (``<IhBB``: time in
ms, value, type, number). ``number`` is an index; the kernel codes of the axes and buttons
(ABS_*, BTN_*) come from the JSIOCGAXMAP / JSIOCGBTNMAP ioctls. Layouts are keyed by kernel code,
so a pad maps the same way whatever the index order of its driver.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

JS_EVENT_BUTTON = 0x01
JS_EVENT_AXIS = 0x02
JS_EVENT_INIT = 0x80
JS_EVENT_SIZE = 8
_JS_FORMAT = "<IhBB"

#: full scale of a joydev axis value (values run -AXIS_MAX..+AXIS_MAX)
AXIS_MAX = 32767

# ioctl request numbers, _IOC(READ=2, 'j'=0x6a, nr, size) (linux/joystick.h)
JSIOCGVERSION = 0x80046A01
JSIOCGAXES = 0x80016A11
JSIOCGBUTTONS = 0x80016A12
NAME_LEN = 128
JSIOCGNAME = 0x80006A13 | (NAME_LEN << 16)
JSIOCGAXMAP = 0x80406A32  # u8[64] (ABS_CNT)
JSIOCGBTNMAP = 0x84006A34  # u16[512] (KEY_MAX - BTN_MISC + 1)
ABS_CNT = 64
KEY_MAP_LEN = 512

AXIS = "axis"
BUTTON = "button"


class DeviceLost(OSError):
    """The gamepad went away (unplugged, Bluetooth dropped, end of a recorded stream)."""


@dataclass(frozen=True)
class PadEvent:
    """One change of one control, in kernel terms.

    ``kind`` is ``"axis"`` or ``"button"``; ``code`` the kernel ABS/BTN code (or the backend's own
    number where there is none); ``value`` -32767..32767 for axes, 0/1 for buttons; ``init`` marks
    the synthetic events that report the current state right after opening (rest positions).
    """

    kind: str
    code: int
    value: int
    init: bool = False
    time_ms: int = 0


@dataclass(frozen=True)
class Caps:
    """What a joystick device reports about itself (or what a layout assumes when it cannot ask)."""

    name: str
    axis_codes: tuple[int, ...] = field(default_factory=tuple)
    button_codes: tuple[int, ...] = field(default_factory=tuple)

    def axis_code(self, index: int) -> int:
        """Kernel code of axis ``index``; indices past the known map get 0x1000 + index."""
        return self.axis_codes[index] if index < len(self.axis_codes) else 0x1000 + index

    def button_code(self, index: int) -> int:
        """Kernel code of button ``index``; indices past the known map get 0x1000 + index."""
        return self.button_codes[index] if index < len(self.button_codes) else 0x1000 + index


def parse_events(data: bytes, caps: Caps) -> tuple[list[PadEvent], bytes]:
    """Decode whole 8-byte events from ``data``; return them and the incomplete tail.

    Index numbers are translated to kernel codes with ``caps``. Events of unknown type are skipped.
    """
    events: list[PadEvent] = []
    whole = len(data) - len(data) % JS_EVENT_SIZE
    for offset in range(0, whole, JS_EVENT_SIZE):
        t, value, etype, number = struct.unpack_from(_JS_FORMAT, data, offset)
        init = bool(etype & JS_EVENT_INIT)
        base = etype & ~JS_EVENT_INIT
        if base == JS_EVENT_AXIS:
            events.append(PadEvent(AXIS, caps.axis_code(number), value, init, t))
        elif base == JS_EVENT_BUTTON:
            events.append(PadEvent(BUTTON, caps.button_code(number), 1 if value else 0, init, t))
    return events, data[whole:]


def parse_code(value: int | str) -> int:
    """A kernel code from a layout file: an int, or a string in decimal or ``0x`` hex."""
    if isinstance(value, bool):
        raise TypeError(f"control code {value!r} must be an int or a '0x...' string, not a bool")
    if isinstance(value, int):
        return value
    if isinstance(value, str):
        try:
            return int(value, 0)
        except ValueError:
            pass
    raise ValueError(f"control code {value!r} is not a number; write e.g. 304 or \"0x130\"")
