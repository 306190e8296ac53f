"""The VESC drivetrain against a fake VESC on a pty (real pyserial, real tty): bytes on the wire are
checked by the fake's own framing and CRC; speed comes back from its COMM_GET_VALUES replies."""

from __future__ import annotations

import math

import pytest
from fixtures.fake_vesc import FakeVESC, crc16_xmodem_bitwise

from parts.actuators import vesc_protocol as vp
from parts.actuators.drivetrain import DrivetrainError
from parts.actuators.vesc import VESC

SAFE = dict(watchdog_s=None, sleep=lambda s: None)


@pytest.fixture
def vesc():
    with FakeVESC() as device:
        yield device


def drive_until(part, device, predicate, angle=0.0, throttle=0.0, tries=200):
    """Run the part until the fake has seen what ``predicate`` wants (the serial link is async)."""
    for _ in range(tries):
        out = part.run(angle, throttle)
        if device.wait_for(predicate, timeout=0.05):
            return out
    raise AssertionError("the fake VESC never saw it")


def test_crc_and_framing_match_the_protocol():
    assert vp.crc16_xmodem(b"123456789") == 0x31C3 == crc16_xmodem_bitwise(b"123456789")
    assert vp.get_values() == bytes([0x02, 0x01, 0x04, 0x40, 0x84, 0x03])
    long = vp.encode_packet(bytes(300))
    assert long[:3] == bytes([0x03, 0x01, 0x2C]) and long[-1] == 0x03 and len(long) == 306
    reader = vp.PacketReader()
    noisy = b"\x00\xff" + vp.set_rpm(1000)[:-1] + b"\x04" + long + vp.set_duty(0.5)
    assert list(reader.feed(noisy[:7])) == []
    got = list(reader.feed(noisy[7:]))
    assert got == [bytes(300), bytes([5]) + (50_000).to_bytes(4, "big")]
    assert reader.errors >= 1  # the packet with the bad terminator was dropped


def test_duty_mode_drives_and_steers(vesc):
    part = VESC(vesc.port, mode="duty", max_duty=0.2, brake_current=4.0, **SAFE).open()
    assert vesc.wait_for(lambda: vesc.last("brake") == 4.0)  # neutral at open: braking current
    assert vesc.last("servo") == 0.5
    part.run(0.0, 0.5)  # a throttle held at start does not pass before a command at neutral
    part.run(0.0, 0.0)
    drive_until(part, vesc, lambda: vesc.last("duty") == 0.1, angle=1.0, throttle=0.5)
    assert vesc.last("servo") == 1.0
    part.neutral()
    assert vesc.wait_for(lambda: vesc.motor_commands()[-1] == ("brake", 4.0))
    part.shutdown()
    assert vesc.crc_errors == 0 and vesc.framing_errors == 0


@pytest.mark.parametrize(("mode", "name", "expected"), [("current", "current", -2.5), ("rpm", "rpm", -2500)])
def test_current_and_rpm_modes(vesc, mode, name, expected):
    part = VESC(vesc.port, mode=mode, max_current=10.0, max_erpm=10000, **SAFE).open()
    part.run(0.0, 0.0)
    drive_until(part, vesc, lambda: vesc.last(name) == expected, throttle=-0.25)
    part.shutdown()


def test_zero_brake_current_releases_the_motor(vesc):
    part = VESC(vesc.port, brake_current=0.0, **SAFE).open()
    assert vesc.wait_for(lambda: vesc.last("current") == 0.0)
    assert vesc.last("brake") is None
    part.shutdown()


def test_measured_speed_from_erpm(vesc, clock):
    # 4-pole motor, 10:1 gearing, 5 cm wheels: 2 m/s is 2 / (2 pi 0.05) * 60 * 10 * 2 ERPM
    wheel_rpm = 2.0 / (2 * math.pi * 0.05) * 60
    vesc.erpm = round(wheel_rpm * 10 * 2)
    part = VESC(vesc.port, motor_poles=4, gear_ratio=10.0, wheel_radius=0.05, stale_s=0.5, clock=clock,
                **SAFE).open()
    assert part.OUTPUTS == ("enc/speed",)
    assert part.speed() is None  # nothing received yet
    part.run(0.0, 0.0)  # sends the first GET_VALUES request
    assert vesc.wait_for(lambda: vesc.replies >= 1)
    speed = None
    for _ in range(200):  # the reply is on its way through the pty
        speed = part.run(0.0, 0.0)
        if speed is not None:
            break
        vesc.wait_for(lambda: False, timeout=0.01)
    assert speed == pytest.approx(2.0, rel=1e-3)
    assert part.values.v_in == pytest.approx(11.1)
    vesc.answering = False
    # a reply asked for by the loop above may still be in the pty: it arrives stamped with the
    # advanced clock and is fresh for one more stale_s. With no new replies, the speed goes stale.
    results = []
    for _ in range(50):
        clock.advance(0.6)
        results.append(part.run(0.0, 0.0))
        if results[-1] is None:
            break
        vesc.wait_for(lambda: False, timeout=0.01)
    assert results[-1] is None  # stale: no reply for longer than stale_s
    assert all(r == pytest.approx(2.0, rel=1e-3) for r in results[:-1])  # only late replies before it
    clock.advance(0.6)
    assert part.run(0.0, 0.0) is None
    part.shutdown()


def test_no_gear_ratio_no_speed_output(vesc):
    part = VESC(vesc.port, **SAFE)
    assert part.OUTPUTS == ()
    part.open()
    assert part.run(0.0, 0.0) is None
    part.shutdown()


def test_a_missing_port_is_one_line_naming_the_setting(tmp_path):
    part = VESC(str(tmp_path / "ttyACM9"), **SAFE)
    with pytest.raises(DrivetrainError, match=r"^VESC_SERIAL_PORT = '.*ttyACM9': cannot open the serial port") as info:
        part.open()
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"mode": "torque"}, "VESC_CONTROL_MODE"),
    ({"max_duty": 1.5}, "VESC_MAX_SPEED_PERCENT"),
    ({"motor_poles": 3}, "VESC_MOTOR_POLES"),
    ({"gear_ratio": 0}, "VESC_GEAR_RATIO"),
])
def test_bad_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        VESC("/dev/null", **kwargs)


def test_speed_reaches_the_vehicle_memory_as_enc_speed(vesc):
    """In a car built from settings alone, the VESC part writes enc/speed for the parts after it."""
    from vehicle import Vehicle
    from vehicle.app.assembly.drivetrain import add_drivetrain
    from vehicle.config import Config

    vesc.erpm = -round(1.5 / (2 * math.pi * 0.04) * 60 * 7.0 * 1)  # 1.5 m/s backwards, 2-pole motor
    seen = []
    V = Vehicle()
    V.add(lambda: (0.0, 0.0), outputs=["angle", "throttle"])
    cfg = Config.defaults(DRIVE_TRAIN_TYPE="VESC", VESC_SERIAL_PORT=vesc.port, VESC_MOTOR_POLES=2,
                          VESC_GEAR_RATIO=7.0, WHEEL_RADIUS=0.04)
    add_drivetrain(V, cfg)

    def watch(speed):
        seen.append(speed)
        if speed is not None:
            V.stop()

    V.add(watch, inputs=["enc/speed"])
    V.start(rate_hz=100, max_loop_count=500)
    assert seen[-1] == pytest.approx(-1.5, rel=1e-3)


def _receive_values(part, vesc):
    """Drive at neutral until a GET_VALUES reply (the fake's ERPM) has reached the part."""
    for _ in range(200):
        part.run(0.0, 0.0)
        if part.values is not None and part.values.erpm == vesc.erpm:
            return
        vesc.wait_for(lambda: False, timeout=0.01)
    raise AssertionError("no GET_VALUES reply reached the part")


def test_a_missing_throttle_sends_the_brake_current_not_duty_zero(vesc):
    part = VESC(vesc.port, mode="duty", max_duty=0.2, brake_current=4.0, **SAFE).open()
    part.run(0.0, 0.0)
    drive_until(part, vesc, lambda: vesc.last("duty") == 0.1, throttle=0.5)
    drive_until(part, vesc, lambda: vesc.motor_commands()[-1] == ("brake", 4.0), angle=0.5, throttle=math.nan)
    assert vesc.last("servo") == 0.75  # the steering still follows
    part.shutdown()


def test_a_negative_throttle_while_rolling_forward_is_a_brake_current(vesc):
    """The obstacle stop brakes with a negative throttle while the car rolls: on a VESC that is
    COMM_SET_CURRENT_BRAKE (|throttle| x VESC_MAX_CURRENT), not reverse duty."""
    vesc.erpm = 3000
    part = VESC(vesc.port, mode="duty", max_duty=0.2, max_current=10.0, **SAFE).open()
    _receive_values(part, vesc)
    drive_until(part, vesc, lambda: vesc.motor_commands()[-1] == ("brake", 6.0), throttle=-0.6)
    assert not [c for c in vesc.motor_commands() if c[0] == "duty" and c[1] < 0]
    vesc.erpm = 0  # standing: a negative throttle is reverse again
    _receive_values(part, vesc)
    drive_until(part, vesc, lambda: vesc.last("duty") == pytest.approx(-0.12), throttle=-0.6)
    part.shutdown()


def test_a_pulled_cable_is_one_line_on_run_and_on_shutdown(vesc):
    """USB unplugged while driving: writing and draining the tty fail with EIO (pyserial's
    SerialException, termios.error); each is one DrivetrainError naming the setting, and the port
    is still closed."""
    part = VESC(vesc.port, **SAFE).open()
    part.run(0.0, 0.0)
    vesc.stop()  # the device end of the pty is gone: the cable is pulled
    with pytest.raises(DrivetrainError, match=r"^VESC_SERIAL_PORT = '.*': the serial link failed") as info:
        part.run(0.0, 0.0)
    assert "\n" not in str(info.value)
    with pytest.raises(DrivetrainError, match=r"^VESC_SERIAL_PORT = '.*': the serial link failed") as info:
        part.shutdown()
    assert "\n" not in str(info.value) and "VESC's own timeout" in str(info.value)
    assert part._serial is None
    part.shutdown()  # idempotent: nothing left to fail


@pytest.mark.parametrize("firmware", [(2, 18), (3, 32)])
def test_firmware_older_than_3_33_is_refused_at_open_in_one_line(firmware):
    """Before 3.33 COMM_GET_VALUES starts with seven temperatures: read with the current layout,
    ERPM 6000 came out as 1,715.7 m/s (and could pass for 'rolling forward')."""
    with FakeVESC(erpm=6000, firmware=firmware) as device:
        part = VESC(device.port, gear_ratio=10.0, **SAFE)
        version = f"{firmware[0]}.{firmware[1]:02d}"
        with pytest.raises(DrivetrainError, match=rf"^VESC_SERIAL_PORT = '.*': VESC firmware {version} .*3\.33") as e:
            part.open()
        assert "\n" not in str(e.value)
        assert device.motor_commands() == []  # refused before any motor command
        assert part._serial is None


def test_a_vesc_that_never_answers_its_firmware_version_is_one_line():
    with FakeVESC(firmware=None) as device:
        part = VESC(device.port, **SAFE)
        part.fw_reply_s = 0.2
        with pytest.raises(DrivetrainError, match=r"^VESC_SERIAL_PORT = '.*': no answer to COMM_FW_VERSION") as e:
            part.open()
        assert "\n" not in str(e.value) and "VESC_BAUDRATE" in str(e.value)


def test_the_firmware_version_is_read_at_open(vesc):
    part = VESC(vesc.port, **SAFE).open()
    assert part.firmware == (5, 2) and "firmware 5.02" in part.describe()
    assert vesc.commands[0] == ("fw_version", None)
    part.shutdown()


def test_a_physically_impossible_speed_is_stale_not_a_reading(vesc, clock):
    """A reply whose ERPM means far beyond any RC car (a mis-framed or foreign layout) is dropped:
    the speed stays None and the motor does not count as rolling forward."""
    vesc.erpm = 1_500_000
    part = VESC(vesc.port, gear_ratio=10.0, clock=clock, **SAFE).open()
    for _ in range(20):
        assert part.run(0.0, 0.0) is None
        vesc.wait_for(lambda: False, timeout=0.01)
    assert vesc.replies >= 5 and part.values is None and not part._rolling_forward()
    vesc.erpm = 3000  # a plausible reading is taken again
    _receive_values(part, vesc)
    assert part.run(0.0, 0.0) == pytest.approx(3000 / 2 / 10 / 60 * 2 * math.pi * 0.0315)
    part.shutdown()
