"""Protocol validation, the control slot and the dead-man rule with a fake clock, pairing helpers."""

from __future__ import annotations

import pytest

from parts.web import pairing, protocol
from parts.web.state import ControlState, Telemetry


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_parse_drive_accepts_the_range_and_ints():
    assert protocol.parse_drive({"angle": -1, "throttle": 1}) == (-1.0, 1.0)
    assert protocol.parse_drive({"angle": 0.25, "throttle": -0.5}) == (0.25, -0.5)
    with pytest.raises(protocol.ProtocolError, match=r"angle=1.01 is outside \[-1, 1\]"):
        protocol.parse_drive({"angle": 1.01, "throttle": 0})
    with pytest.raises(protocol.ProtocolError, match="missing 'throttle'"):
        protocol.parse_drive({"angle": 0})


def test_parse_settings_returns_only_given_fields():
    models = ["a.pt"]
    assert protocol.parse_settings({"mode": "local"}, models=models, max_speed_limit=5) == {"mode": "local"}
    got = protocol.parse_settings({"speed_limit": 2, "model": "a.pt", "recording": False},
                                  models=models, max_speed_limit=5)
    assert got == {"speed_limit": 2.0, "model": "a.pt", "recording": False}
    with pytest.raises(protocol.ProtocolError, match="outside"):
        protocol.parse_settings({"speed_limit": 5.5}, models=models, max_speed_limit=5)
    with pytest.raises(protocol.ProtocolError, match="unknown field"):
        protocol.parse_settings({"mode": "user", "x": 1}, models=models, max_speed_limit=5)
    assert protocol.parse_estop({"on": True}) is True


def test_deadman_with_a_fake_clock():
    clock = FakeClock()
    s = ControlState(deadman_s=0.5, max_throttle=1.0, clock=clock)
    assert s.connect("a") == "driver"
    s.drive(0.3, 0.8)
    clock.t += 0.49
    out = s.outputs()
    assert out.user_throttle() == pytest.approx(0.8) and out.angle == pytest.approx(0.3)
    clock.t += 0.02  # 0.51 s since the last message
    out = s.outputs()
    assert out.user_throttle() == 0.0 and out.angle == 0.0 and out.mode == "user"
    assert s.deadman_trips == 1
    clock.t += 10  # tripped once, not again and again
    s.outputs()
    assert s.deadman_trips == 1


def test_deadman_guards_a_pilot_mode_and_constant_throttle():
    clock = FakeClock()
    s = ControlState(deadman_s=0.5, clock=clock)
    s.connect("a")
    s.apply({"mode": "local"})
    clock.t += 0.6
    assert s.outputs().mode == "user"
    s.apply({"constant_throttle": True, "max_throttle": 0.4})
    assert s.outputs().user_throttle() == pytest.approx(0.4)
    clock.t += 0.6
    out = s.outputs()
    assert out.user_throttle() == 0.0 and out.constant_throttle is False


def test_a_neutral_silent_driver_is_not_a_deadman_trip():
    clock = FakeClock()
    s = ControlState(deadman_s=0.5, clock=clock)
    s.connect("a")
    s.drive(0.5, 0.0)  # steering only, no throttle
    clock.t += 5
    assert s.outputs().angle == pytest.approx(0.5)
    assert s.deadman_trips == 0


def test_mode_set_elsewhere_is_followed_unless_the_page_just_changed_it():
    s = ControlState(clock=FakeClock())
    s.connect("a")
    s.report(Telemetry(mode="local_angle", recording=True))  # e.g. the gamepad switched
    out = s.outputs()
    assert out.mode == "local_angle" and out.recording is True
    s.apply({"mode": "user"})
    s.report(Telemetry(mode="local_angle"))  # the loop has not seen the page's change yet
    assert s.outputs().mode == "user"


def test_roles_and_take_control():
    s = ControlState(clock=FakeClock())
    assert s.connect("a") == "driver" and s.connect("b") == "viewer"
    s.drive(0.5, 0.5)
    assert s.take_control("b") == "a"
    assert s.role("a") == "viewer" and s.role("b") == "driver"
    assert s.outputs().throttle == 0.0
    assert s.disconnect("b") is True and s.role("a") == "viewer"
    assert s.connect("c") == "driver"  # the free seat goes to the next browser


def test_bad_arguments_say_what_is_wrong():
    with pytest.raises(ValueError, match="deadman_s"):
        ControlState(deadman_s=0)
    with pytest.raises(ValueError, match="init_mode"):
        ControlState(init_mode="auto")
    with pytest.raises(ValueError, match="max_throttle"):
        ControlState(max_throttle=1.5)


def test_pairing_helpers():
    assert pairing.is_loopback("127.0.0.1") and pairing.is_loopback("localhost")
    assert pairing.is_loopback("::1")
    assert not pairing.is_loopback("0.0.0.0") and not pairing.is_loopback("192.168.1.20")
    assert pairing.resolve_token("127.0.0.1", None) is None
    assert pairing.resolve_token("127.0.0.1", "my-secret-1") == "my-secret-1"
    assert pairing.token_ok(None, None)
    assert pairing.token_ok("abcdefgh", {"token": "abcdefgh"})
    assert not pairing.token_ok("abcdefgh", {"token": "abcdefgX"})
    assert not pairing.token_ok("abcdefgh", {"token": 12345678})
    assert not pairing.token_ok("abcdefgh", "abcdefgh")
    assert pairing.page_url("192.168.1.20", 8887, "tok") == "http://192.168.1.20:8887/?token=tok"
    assert pairing.page_url("127.0.0.1", 8887, None) == "http://127.0.0.1:8887/"


def test_terminal_qr_when_qrcode_is_installed():
    qr = pairing.terminal_qr("http://192.168.1.20:8887/?token=abc")
    try:
        import qrcode  # noqa: F401
    except ImportError:
        assert qr is None
    else:
        lines = qr.splitlines()
        assert len(lines) > 10 and len({len(line) for line in lines}) == 1
