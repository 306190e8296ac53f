"""Fixtures for gamepad tests: recorded js_event streams built from a layout, fed through pipes."""

from __future__ import annotations

import os

import pytest

from parts.controllers.events import AXIS, AXIS_MAX, BUTTON, pack_event
from parts.controllers.layouts import Layout
from parts.controllers.linux_js import LinuxJoystick
from parts.controllers.logic import GamepadLogic, GamepadOutput


class FakeClock:
    """Monotonic seconds that only move when told."""

    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


class Stream:
    """Builds js_event bytes for a layout, by control name, with the layout's index order."""

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self.caps = layout.caps

    def axis_index(self, code: int) -> int:
        return self.caps.axis_codes.index(code)

    def button_index(self, code: int) -> int:
        return self.caps.button_codes.index(code)

    def init_burst(self, **held: int) -> bytes:
        """INIT events like joydev sends on open: every button, then every axis at rest.

        Triggers rest at -32767; ``held`` gives other raw values by axis control name.
        """
        trig = {a.code for a in self.layout.axes.values() if a.trigger}
        held_codes = {self.layout.axes[n].code: v for n, v in held.items()}
        out = b"".join(pack_event(BUTTON, i, 0, init=True) for i in range(len(self.caps.button_codes)))
        for i, code in enumerate(self.caps.axis_codes):
            rest = held_codes.get(code, -AXIS_MAX if code in trig else 0)
            out += pack_event(AXIS, i, rest, init=True)
        return out

    def axis(self, control: str, value: int) -> bytes:
        return pack_event(AXIS, self.axis_index(self.layout.axes[control].code), value)

    def press(self, control: str, release: bool = True) -> bytes:
        """Press (and release) a button control, or move an axis-half control past half travel."""
        ctl = self.layout.buttons[control]
        if ctl.axis:
            i = self.axis_index(ctl.code)
            out = pack_event(AXIS, i, ctl.direction * AXIS_MAX)
            return out + (pack_event(AXIS, i, 0) if release else b"")
        i = self.button_index(ctl.code)
        return pack_event(BUTTON, i, 1) + (pack_event(BUTTON, i, 0) if release else b"")


class PipePad:
    """A LinuxJoystick reading a pipe, and the logic it feeds; ``send`` writes and applies events."""

    def __init__(self, layout: Layout, **settings) -> None:
        from parts.controllers.logic import GamepadSettings

        self.clock = FakeClock()
        self.stream = Stream(layout)
        self.r, self.w = os.pipe()
        self.reader = LinuxJoystick(fd=self.r, fallback_caps=layout.caps)
        self.reader.open()
        self.logic = GamepadLogic(layout, GamepadSettings(**settings), self.clock)
        self.logic.on_connect()

    def send(self, data: bytes) -> GamepadOutput:
        os.write(self.w, data)
        while True:
            events = self.reader.read(0.0)
            if not events:
                break
            self.logic.feed(events)
        return self.logic.output()

    def close_writer(self) -> None:
        if self.w is not None:
            os.close(self.w)
            self.w = None

    def close(self) -> None:
        self.close_writer()
        self.reader.close()


@pytest.fixture
def pipe_pad():
    pads: list[PipePad] = []

    def make(layout: Layout, **settings) -> PipePad:
        pad = PipePad(layout, **settings)
        pads.append(pad)
        return pad

    yield make
    for pad in pads:
        pad.close()


@pytest.fixture
def stream_for():
    """The Stream builder class: ``stream_for(layout).press("a")``."""
    return Stream


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()
