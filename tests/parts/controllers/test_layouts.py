"""Controller layouts as data: built-ins load and validate, errors say what to fix."""

from __future__ import annotations

import json

import pytest

from parts.controllers.layouts import (
    ACTIONS,
    LayoutError,
    builtin_layouts,
    layout_from_json,
    load_layout,
)

REQUIRED = {"ps3", "ps4", "xbox", "xbox_bt", "f710", "generic", "pygame"}


def test_every_required_layout_ships():
    assert REQUIRED <= set(builtin_layouts())


@pytest.mark.parametrize("name", sorted(REQUIRED))
def test_builtin_layout_is_complete(name):
    layout = load_layout(name)
    assert layout.name == name
    assert set(layout.bindings) == set(ACTIONS) - {"throttle_forward", "throttle_reverse"}
    assert not layout.axes[layout.bindings["steering"]].trigger
    assert not layout.axes[layout.bindings["throttle"]].trigger
    # the fallback caps cover every control the layout names (so a FIFO stream decodes)
    for ctl in layout.axes.values():
        assert ctl.code in layout.caps.axis_codes
    for ctl in layout.buttons.values():
        codes = layout.caps.axis_codes if ctl.axis else layout.caps.button_codes
        assert ctl.code in codes or layout.backend == "pygame"


def test_xbox_usb_and_bluetooth_put_the_right_stick_on_different_codes():
    usb, bt = load_layout("xbox"), load_layout("xbox_bt")
    assert usb.axes["right_stick_y"].code == 4  # ABS_RY on xpad
    assert bt.axes["right_stick_y"].code == 5  # ABS_RZ on hid-generic
    assert usb.axes["rt"].trigger and usb.axes["rt"].code == 5
    assert bt.axes["rt"].code == 9  # ABS_GAS


def test_sony_triangle_is_btn_north():
    assert load_layout("ps4").buttons["triangle"].code == 0x133
    assert load_layout("ps3").buttons["dpad_up"].code == 0x220


def test_aliases_and_unknown_names():
    assert load_layout("xbox_one").name == "xbox"
    with pytest.raises(LayoutError, match="Did you mean 'ps4'"):
        load_layout("ps5")


def test_missing_custom_mapping_points_to_createjs(tmp_path):
    with pytest.raises(LayoutError, match="vehicle createjs"):
        load_layout(tmp_path / "nope.json")


def test_bad_json_and_bad_bindings_are_reported(tmp_path):
    bad = tmp_path / "pad.json"
    bad.write_text("{not json")
    with pytest.raises(LayoutError, match="cannot read"):
        load_layout(bad)
    data = load_layout("ps4").to_json()
    data["bindings"]["estop"] = "nosuchbutton"
    with pytest.raises(LayoutError, match="not a button"):
        layout_from_json(data)
    data = load_layout("ps4").to_json()
    data["bindings"]["steering"] = "l2"
    with pytest.raises(LayoutError, match="trigger"):
        layout_from_json(data)
    data = load_layout("ps4").to_json()
    data["bindings"]["launch"] = "cross"
    with pytest.raises(LayoutError, match="unknown action 'launch'"):
        layout_from_json(data)
    data = load_layout("ps4").to_json()
    del data["bindings"]["estop"]
    with pytest.raises(LayoutError, match="emergency stop"):
        layout_from_json(data)


def test_json_roundtrip_and_rebinding(tmp_path):
    ps4 = load_layout("ps4")
    path = tmp_path / "copy.json"
    path.write_text(json.dumps(ps4.to_json()))
    again = load_layout(path)
    assert again.axes == ps4.axes and again.buttons == ps4.buttons and again.bindings == ps4.bindings
    assert again.caps.button_codes == ps4.caps.button_codes
    rebound = ps4.with_bindings({"estop": "square", "behavior_next": ""})
    assert rebound.bindings["estop"] == "square" and "behavior_next" not in rebound.bindings
    with pytest.raises(LayoutError, match="not a button"):
        ps4.with_bindings({"estop": "left_stick_x"})
