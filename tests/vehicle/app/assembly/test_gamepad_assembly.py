"""add_gamepad: layout and reader from the config, wired into a Vehicle."""

from __future__ import annotations

import json

import pytest

from parts.controllers.events import AXIS_MAX
from parts.controllers.gamepad import Gamepad
from parts.controllers.layouts import load_layout
from vehicle import Vehicle
from vehicle.app.assembly.gamepad import add_gamepad, load_gamepad_layout
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import UserError

GAMEPAD_OUTPUTS = Gamepad.OUTPUTS


def test_add_gamepad_reads_a_recording_file_in_a_vehicle(tmp_path, stream_for):
    layout = load_layout("ps4")
    s = stream_for(layout)
    (tmp_path / "pad.js").write_bytes(s.init_burst() + s.axis("left_stick_x", AXIS_MAX)
                                      + s.axis("right_stick_y", -AXIS_MAX))
    cfg = Config.defaults(CAR_PATH=str(tmp_path), CONTROLLER_TYPE="ps4", JOYSTICK_DEVICE_FILE="pad.js",
                          JOYSTICK_MAX_THROTTLE=0.3, JOYSTICK_STEERING_SCALE=0.5)
    V = Vehicle(clock=SimulatedClock())
    part = add_gamepad(V, cfg)
    assert V.parts[0].outputs == tuple(GAMEPAD_OUTPUTS) and V.parts[0].threaded
    assert part.reader.path == str(tmp_path / "pad.js")
    out = part.run()  # non-threaded: opens and reads what the recording holds now
    assert out.angle == pytest.approx(0.5) and out.throttle == pytest.approx(0.3)
    part.shutdown()


def test_custom_mapping_and_binding_overrides(tmp_path):
    data = load_layout("xbox").to_json()
    data["name"] = "mine"
    (tmp_path / "js.json").write_text(json.dumps(data))
    cfg = Config.defaults(CAR_PATH=str(tmp_path), CONTROLLER_TYPE="custom", JOYSTICK_MAPPING_PATH="js.json",
                          JOYSTICK_BINDINGS={"estop": "b", "record_toggle": ""})
    layout = load_gamepad_layout(cfg)
    assert layout.name == "mine" and layout.bindings["estop"] == "b"
    assert "record_toggle" not in layout.bindings
    with pytest.raises(UserError, match="vehicle createjs"):
        load_gamepad_layout(cfg.replace(JOYSTICK_MAPPING_PATH="missing.json"))
    with pytest.raises(UserError, match="not a button"):
        load_gamepad_layout(Config.defaults(JOYSTICK_BINDINGS={"estop": "nope"}))


def test_bad_joystick_settings_are_user_errors():
    from vehicle.errors import VehicleError

    with pytest.raises(VehicleError, match="JOYSTICK_MAX_THROTTLE"):  # the config refuses it already
        add_gamepad(Vehicle(), Config.defaults(JOYSTICK_MAX_THROTTLE=2.0))


def test_renamed_outputs_for_an_arbiter(tmp_path):
    V = Vehicle()
    keys = [f"js/{k.split('/')[-1]}" for k in GAMEPAD_OUTPUTS]
    add_gamepad(V, Config.defaults(JOYSTICK_DEVICE_FILE=str(tmp_path / "none")), outputs=keys)
    assert V.parts[0].outputs == tuple(keys)
    with pytest.raises(ValueError, match="needs 7 keys"):
        add_gamepad(V, Config.defaults(), outputs=["a"])


def test_the_pads_link_is_published_for_the_web_page(tmp_path, stream_for):
    # issue 21 (item 18): the page shows whether the car's gamepad is connected
    from parts.controllers.gamepad import GamepadStatus

    layout = load_layout("ps4")
    (tmp_path / "pad.js").write_bytes(stream_for(layout).init_burst())
    V = Vehicle(clock=SimulatedClock())
    part = add_gamepad(V, Config.defaults(CAR_PATH=str(tmp_path), CONTROLLER_TYPE="ps4", JOYSTICK_DEVICE_FILE="pad.js"))
    status = V.parts[1].part
    assert isinstance(status, GamepadStatus) and V.parts[1].outputs == ("js/status",)
    assert status.run() == "lost"  # not opened yet
    part.run()
    assert status.run() == "connected"
    part.logic.silent = True  # what the silence timeout sets
    assert status.run() == "silent"
    part.shutdown()
    assert status.run() == "lost"
