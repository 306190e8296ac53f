"""The createjs wizard, driven by events written in answer to its prompts, plus stdin for skips."""

from __future__ import annotations

import io
import json
import os

import pytest
from fixtures.gamepads import pack_event

from parts.controllers.events import AXIS, AXIS_MAX, BUTTON
from parts.controllers.layouts import load_layout
from parts.controllers.linux_js import LinuxJoystick
from parts.controllers.mapping_wizard import CreateJsWizard, WizardError, save_layout

CAPS = load_layout("generic").caps  # axes 0 1 2 3 4 5 16 17, buttons 0x130 0x131 0x133 ...


def init_burst() -> bytes:
    out = b"".join(pack_event(BUTTON, i, 0, init=True) for i in range(len(CAPS.button_codes)))
    for i, code in enumerate(CAPS.axis_codes):
        out += pack_event(AXIS, i, -AXIS_MAX if code in (2, 5) else 0, init=True)
    return out


def move(index: int, value: int, back: int = 0) -> bytes:
    return pack_event(AXIS, index, value) + pack_event(AXIS, index, back)


def tap(index: int) -> bytes:
    return pack_event(BUTTON, index, 1) + pack_event(BUTTON, index, 0)


class ScriptedUser:
    """Stands for the user: answers each prompt (the wizard's output) by moving controls or Enter."""

    def __init__(self, pad_fd: int, stdin_fd: int, answers: dict[str, list[bytes | str]]) -> None:
        self.pad_fd, self.stdin_fd = pad_fd, stdin_fd
        self.answers = answers
        self.text = io.StringIO()

    def write(self, text: str) -> int:
        self.text.write(text)
        for key, queue in self.answers.items():
            if key in text and queue:
                answer = queue.pop(0)
                if isinstance(answer, str):
                    os.write(self.stdin_fd, answer.encode())
                else:
                    os.write(self.pad_fd, answer)
                break
        return len(text)

    def flush(self) -> None:
        pass


@pytest.fixture
def session():
    pad_r, pad_w = os.pipe()
    in_r, in_w = os.pipe()
    stdin = os.fdopen(in_r, "r")
    os.write(pad_w, init_burst())
    yield pad_w, in_w, LinuxJoystick(fd=pad_r, fallback_caps=CAPS), stdin
    stdin.close()
    for fd in (pad_w, in_w):
        os.close(fd)


def test_wizard_maps_sticks_buttons_dpad_and_triggers(session, tmp_path, pipe_pad):
    pad_w, in_w, reader, stdin = session
    user = ScriptedUser(pad_w, in_w, {
        "STEERING": [move(3, AXIS_MAX)],  # right stick x to the right
        "Push the THROTTLE": [move(1, -AXIS_MAX)],  # left stick up
        "EMERGENCY": ["\n"],  # Enter cannot skip a required step...
        "this one is needed": [tap(2)],
        "DRIVE MODE": [tap(0)],
        "RECORD": ["\n"],
        "ERASE": [tap(0), tap(1)],  # A is taken by the mode toggle: asked again
        "MAX THROTTLE UP": [move(7, -AXIS_MAX)],  # D-pad up (hat y negative)
        "MAX THROTTLE DOWN": [move(7, AXIS_MAX)],
        "CONSTANT": ["\n"],
        "NEXT BEHAVIOUR": [move(5, AXIS_MAX, -AXIS_MAX)],  # right trigger
        "PREVIOUS BEHAVIOUR": ["\n"],
    })
    layout = CreateJsWizard(reader, user, stdin, step_timeout_s=5, settle_s=0.05).run()
    text = user.text.getvalue()
    assert "this one is needed" in text and "already used for mode_toggle" in text
    assert layout.axes["steering"].code == 3 and not layout.axes["steering"].invert
    assert layout.axes["throttle"].code == 1 and not layout.axes["throttle"].invert
    assert layout.buttons["estop"].code == 0x133 and not layout.buttons["estop"].axis
    assert layout.buttons["erase_records"].code == 0x131
    up, down = layout.buttons["throttle_up"], layout.buttons["throttle_down"]
    assert (up.axis, up.code, up.direction) == (True, 17, -1)
    assert (down.axis, down.code, down.direction) == (True, 17, 1)
    assert (layout.buttons["behavior_next"].code, layout.buttons["behavior_next"].direction) == (5, 1)
    assert "record_toggle" not in layout.bindings and "constant_throttle" not in layout.bindings

    # the written file drives the car like a built-in layout
    path = save_layout(layout, tmp_path / "cfg" / "pad.json")
    loaded = load_layout(path)
    pad = pipe_pad(loaded, max_throttle=1.0)
    pad.send(init_burst())
    out = pad.send(pack_event(AXIS, 3, AXIS_MAX) + pack_event(AXIS, 1, -AXIS_MAX))
    assert (out.angle, out.throttle) == (1.0, 1.0)
    assert pad.send(tap(2)).estop is True


def test_inverted_stick_and_trigger_throttle(session):
    pad_w, in_w, reader, stdin = session
    user = ScriptedUser(pad_w, in_w, {
        "STEERING": [move(0, -AXIS_MAX)],  # this pad reports right as negative
        "Push the THROTTLE": [move(5, AXIS_MAX, -AXIS_MAX)],  # forward trigger
        "REVERSE": [move(2, AXIS_MAX, -AXIS_MAX)],
        "EMERGENCY": [tap(3)],
        "Press the button for": ["\n"] * 8,
    })
    layout = CreateJsWizard(reader, user, stdin, step_timeout_s=5, settle_s=0.05).run()
    assert layout.axes["steering"].invert is True
    assert layout.axes["throttle_forward"] == layout.axes["throttle_forward"].__class__(5, True, False)
    assert layout.axes["throttle_reverse"].code == 2
    assert "throttle" not in layout.bindings
    assert set(layout.bindings) == {"steering", "throttle_forward", "throttle_reverse", "estop"}


def test_a_button_for_steering_is_refused_and_nothing_moving_is_an_error(session):
    pad_w, in_w, reader, stdin = session
    user = ScriptedUser(pad_w, in_w, {"STEERING": [tap(0)]})
    with pytest.raises(WizardError, match="nothing moved"):
        CreateJsWizard(reader, user, stdin, step_timeout_s=0.3, settle_s=0.05).run()
    assert "needs a stick or trigger" in user.text.getvalue()


def cli(argv: list[str]) -> int:
    """Run `vehicle createjs` like vehicle.app.cli.main, without importing every other command."""
    import argparse

    from vehicle.app.cli import COMMAND_MODULES
    from vehicle.app.commands import createjs
    from vehicle.errors import UserError

    assert "vehicle.app.commands.createjs" in COMMAND_MODULES
    parser = argparse.ArgumentParser(prog="vehicle")
    createjs.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except UserError as exc:
        print(f"error: {exc}", file=__import__("sys").stderr)
        return 2


def test_cli_writes_the_mapping_from_a_recorded_session(tmp_path, monkeypatch, capsys):

    rec = tmp_path / "session.js"
    rec.write_bytes(init_burst() + move(0, AXIS_MAX) + move(4, -AXIS_MAX)
                    + b"".join(tap(i) for i in range(9)))
    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    out = tmp_path / "mapping.json"
    assert cli(["createjs", "--device", str(rec), "--out", str(out), "--timeout", "2",
                "--car", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert 'CONTROLLER_TYPE = "custom"' in printed and str(out) in printed
    data = json.loads(out.read_text())
    assert data["axes"]["steering"]["code"] == 0 and data["axes"]["throttle"]["code"] == 4
    assert data["buttons"]["estop"] == "0x130" and data["buttons"]["behavior_prev"] == "0x13c"
    assert load_layout(out).bindings["mode_toggle"] == "mode_toggle"


def test_cli_without_a_pad_is_a_user_error(tmp_path, capsys):
    assert cli(["createjs", "--device", str(tmp_path / "js7"), "--car", str(tmp_path)]) == 2
    assert "no joystick at" in capsys.readouterr().err
