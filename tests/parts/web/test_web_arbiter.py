"""ControllerArbiter: which of the gamepad and the web page drives."""

from __future__ import annotations

import pytest

from parts.web.arbiter import ControllerArbiter


def step(arb, pad=(0.0, 0.0), web=(0.0, 0.0), pad_mode="user", web_mode="user",
         pad_rec=False, web_rec=False, pad_estop=False, web_estop=False):
    out = arb.run(*pad, pad_mode, pad_rec, pad_estop, *web, web_mode, web_rec, web_estop)
    return dict(zip(ControllerArbiter.OUTPUTS, out, strict=True))


def test_gamepad_priority():
    arb = ControllerArbiter("gamepad")
    assert step(arb, web=(0.2, 0.3))["controller/active"] == "web"
    out = step(arb, pad=(-0.5, 0.4), web=(0.2, 0.3))
    assert (out["user/angle"], out["user/throttle"], out["controller/active"]) == (-0.5, 0.4, "gamepad")
    out = step(arb, pad=(0.0, 0.0), web=(0.2, 0.3))  # pad back to centre: the page drives again
    assert (out["user/angle"], out["user/throttle"]) == (0.2, 0.3)


def test_web_priority():
    arb = ControllerArbiter("web")
    assert step(arb, pad=(0.5, 0.5))["user/throttle"] == 0.5
    out = step(arb, pad=(0.5, 0.5), web=(-0.1, 0.2))
    assert (out["user/angle"], out["controller/active"]) == (-0.1, "web")


def test_latest_priority_follows_the_source_that_moved_last():
    arb = ControllerArbiter("latest")
    assert step(arb, pad=(0.5, 0.5))["controller/active"] == "gamepad"
    assert step(arb, pad=(0.5, 0.5), web=(0.1, 0.1))["controller/active"] == "web"
    assert step(arb, pad=(0.5, 0.5), web=(0.1, 0.1))["controller/active"] == "web"  # held
    out = step(arb, pad=(0.6, 0.5), web=(0.1, 0.1))
    assert (out["controller/active"], out["user/angle"]) == ("gamepad", 0.6)


def test_mode_and_recording_latest_change_wins():
    arb = ControllerArbiter("gamepad")
    assert step(arb)["user/mode"] == "user"
    assert step(arb, web_mode="local")["user/mode"] == "local"
    assert step(arb, web_mode="local")["user/mode"] == "local"  # the pad's unchanged "user" does not undo it
    assert step(arb, web_mode="local", pad_mode="local_angle")["user/mode"] == "local_angle"
    assert step(arb, pad_rec=True)["recording"] is True
    assert step(arb, pad_rec=True, web_rec=True)["recording"] is True
    assert step(arb, pad_rec=True, web_rec=False)["recording"] is False


def test_estop_from_either_source_holds():
    arb = ControllerArbiter("gamepad")
    out = step(arb, pad=(0.0, 0.9), web_estop=True)
    assert out["estop"] is True and out["user/throttle"] == 0.0
    assert step(arb, pad=(0.0, 0.9), pad_estop=True)["estop"] is True
    assert step(arb, pad=(0.0, 0.9))["user/throttle"] == 0.9


def test_bad_priority():
    with pytest.raises(ValueError, match="CONTROLLER_PRIORITY"):
        ControllerArbiter("joystick")
