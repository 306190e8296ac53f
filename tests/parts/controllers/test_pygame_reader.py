"""The pygame reader: real pygame event queue (dummy video driver), a fake Joystick object."""

from __future__ import annotations

import pytest

pygame = pytest.importorskip("pygame")

from parts.controllers.events import AXIS, AXIS_MAX, BUTTON, DeviceLost, PadEvent  # noqa: E402
from parts.controllers.gamepad import Gamepad  # noqa: E402
from parts.controllers.layouts import load_layout  # noqa: E402
from parts.controllers.logic import GamepadSettings  # noqa: E402
from parts.controllers.pygame_js import PygameJoystick, init_pygame_headless  # noqa: E402


class FakeJoystick:
    """Same methods as pygame.joystick.Joystick: 6 axes (triggers at -1), 11 buttons, 1 hat."""

    def __init__(self, index: int) -> None:
        self.index = index
        self.axes = [0.0, 0.0, -1.0, 0.0, 0.0, -1.0]
        self.quit_called = False

    def init(self):
        pass

    def get_instance_id(self):
        return 7

    def get_name(self):
        return "Fake SDL pad"

    def get_numaxes(self):
        return 6

    def get_numbuttons(self):
        return 11

    def get_numhats(self):
        return 1

    def get_axis(self, i):
        return self.axes[i]

    def get_button(self, i):
        return 0

    def get_hat(self, i):
        return (0, 0)

    def quit(self):
        self.quit_called = True


def post(kind, **attrs):
    pygame.event.post(pygame.event.Event(kind, **attrs))


@pytest.fixture
def reader():
    init_pygame_headless()
    pygame.event.clear()
    r = PygameJoystick(0, joystick_factory=FakeJoystick)
    yield r
    r.close()
    pygame.event.clear()


def test_open_reports_state_as_init_events(reader):
    caps = reader.open()
    assert caps.name == "Fake SDL pad"
    assert caps.axis_codes == (0, 1, 2, 3, 4, 5, 16, 17)
    events = reader.read(0.0)
    assert PadEvent(AXIS, 2, -AXIS_MAX, True) in events
    assert PadEvent(AXIS, 17, 0, True) in events
    assert sum(e.kind == BUTTON for e in events) == 11 and all(e.init for e in events)


def test_events_are_translated_and_filtered_by_instance(reader):
    reader.open()
    reader.read(0.0)
    post(pygame.JOYAXISMOTION, instance_id=7, axis=4, value=-0.5)
    post(pygame.JOYAXISMOTION, instance_id=8, axis=4, value=1.0)  # another pad: ignored
    post(pygame.JOYBUTTONDOWN, instance_id=7, button=3)
    post(pygame.JOYHATMOTION, instance_id=7, hat=0, value=(1, 1))  # right + up
    assert reader.read(0.2) == [PadEvent(AXIS, 4, -16384), PadEvent(BUTTON, 3, 1),
                                PadEvent(AXIS, 16, AXIS_MAX), PadEvent(AXIS, 17, -AXIS_MAX)]
    assert reader.read(0.01) == []


def test_removed_pad_is_device_lost(reader):
    reader.open()
    post(pygame.JOYDEVICEREMOVED, instance_id=7)
    with pytest.raises(DeviceLost):
        reader.read(0.2)


def test_gamepad_part_with_pygame_layout(reader):
    layout = load_layout("pygame")
    part = Gamepad(reader, layout, GamepadSettings(max_throttle=1.0))
    out = part.run()
    assert (out.throttle, out.mode) == (0.0, "user")  # triggers at -1 are at rest
    post(pygame.JOYAXISMOTION, instance_id=7, axis=4, value=-1.0)  # right stick up
    post(pygame.JOYAXISMOTION, instance_id=7, axis=0, value=0.5)
    post(pygame.JOYBUTTONDOWN, instance_id=7, button=0)  # A: mode toggle
    post(pygame.JOYHATMOTION, instance_id=7, hat=0, value=(1, 0))  # D-pad right: next behaviour
    out = part.run()
    assert out.throttle == pytest.approx(1.0) and out.angle == pytest.approx(0.5, abs=1e-4)
    assert out.mode == "local_angle" and out.behavior_step == 1
    post(pygame.JOYDEVICEREMOVED, instance_id=7)
    out = part.run()
    assert (out.throttle, out.mode) == (0.0, "user")
    part.shutdown()


def test_no_pad_is_file_not_found():
    init_pygame_headless()
    r = PygameJoystick(5)
    with pytest.raises(FileNotFoundError, match="no gamepad 5"):
        r.open()
