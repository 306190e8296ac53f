"""The PCA9685 driver against the register model: init trace, pulses, errors, real smbus2 path."""

from __future__ import annotations

import errno
import subprocess
import sys

import pytest
from fixtures.fake_i2c_dev import real_smbus2_on

from parts.actuators.fake_pca9685 import OFF, FakeI2C, Transfer
from parts.actuators.pca9685 import (
    PCA9685,
    I2CBusError,
    PCA9685NotFound,
    actual_frequency,
    prescale_for,
)


@pytest.mark.parametrize(("freq", "prescale", "actual"), [
    (24, 253, 24.030), (50, 121, 50.029), (60, 101, 59.838), (100, 60, 100.058), (200, 30, 196.888),
    (1526, 3, 1525.879)])
def test_prescale_matches_adafruit(freq, prescale, actual):
    assert prescale_for(freq) == prescale
    assert actual_frequency(prescale) == pytest.approx(actual, abs=1e-3)


@pytest.mark.parametrize("freq", [0, -60, 10, 2000])
def test_impossible_frequency_is_refused_before_any_io(freq):
    with pytest.raises(ValueError, match="PWM_FREQ|must be > 0"):
        PCA9685(1, 0x40, freq, bus_factory=lambda n: pytest.fail("bus opened"))


def test_init_trace_from_power_on(driver, board):
    ops = [(t.op, t.register, t.data) for t in board.trace]
    assert ops == [
        ("r", 0x00, (0x11,)),  # probe MODE1: power-on value, asleep
        ("r", 0xFE, (30,)),  # probe PRE_SCALE: power-on 200 Hz
        ("w", 0x01, (0x04,)),  # MODE2: totem-pole, outputs change on STOP
        ("w", 0x00, (0x31,)),  # sleep + auto-increment + ALLCALL
        ("w", 0xFE, (101,)),  # prescale for 60 Hz
        ("w", 0x00, (0x21,)),  # wake
        ("w", 0x00, (0xA1,)),  # restart
        ("r", 0xFE, (101,)),  # the chip took it
    ]
    assert board.prescale == 101
    assert board.frequency() == pytest.approx(59.838, abs=1e-3)
    assert board.regs[0x00] & 0x20  # auto-increment on
    assert not board.sleeping
    assert board.violations == []
    wake, restart = board.trace[5].t, board.trace[6].t
    assert restart - wake >= 0.0005  # oscillator start-up delay honoured


def test_reopen_of_a_running_chip_does_not_sleep_it(i2c, board, driver):
    driver.set_ticks(0, 370)
    driver.close()
    board.trace.clear()
    PCA9685(1, 0x40, 60, bus_factory=i2c.smbus).open()
    writes = [(t.register, t.data) for t in board.trace if t.op == "w"]
    assert all(not data[0] & 0x10 for reg, data in writes if reg == 0x00)  # never SLEEP
    assert board.pulses(0) == [OFF, 370]  # the running pulse was never interrupted


def test_one_block_write_per_channel_update(driver, board):
    board.trace.clear()
    driver.set_ticks(1, 375)
    assert board.trace == [Transfer(board.trace[0].t, "w", 0x0A, (0, 0, 119, 1))]
    assert board.pulse_us(1) == pytest.approx(1530.0, abs=0.1)
    assert driver.read_channel(1) == (0, 375)


def test_full_off_and_all_off(driver, board):
    driver.set_ticks(0, 370)
    driver.set_ticks(1, 375)
    driver.set_full_off(0)
    assert board.pulses(0) == [OFF, 370, OFF]
    assert board.output(1) == 375
    driver.all_off()
    assert board.output(1) == OFF
    assert board.channel(1).full_off


def test_tick_conversions(driver):
    assert driver.us_to_ticks(1500) == 368
    assert driver.us_to_ticks(1000) == 245
    assert driver.ticks_to_us(370) == pytest.approx(1509.6, abs=0.1)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"channel": 16, "off": 300}, "channel must be an int 0-15"),
    ({"channel": 0, "off": 4096}, "off tick must be an int 0-4095"),
    ({"channel": 0, "off": 300.0}, "off tick must be an int"),
    ({"channel": 0, "off": 0}, "not a valid PWM setting"),
])
def test_bad_channel_values_are_refused(driver, board, kwargs, message):
    with pytest.raises(ValueError, match=message):
        driver.set_ticks(**kwargs)
    assert board.pulses(0) == [OFF]


def test_constructor_touches_no_hardware_and_smbus2_is_imported_lazily():
    PCA9685(1, 0x40, 60, bus_factory=lambda n: pytest.fail("constructor opened the bus"))
    code = ("import sys, parts.actuators.pca9685, parts.actuators.pwm, vehicle.app.assembly.drivetrain; "
            "print('smbus2' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_missing_bus_names_bus_and_address():
    with pytest.raises(PCA9685NotFound) as info:
        PCA9685(3, 0x40, bus_factory=FakeI2C().smbus).open()
    msg = str(info.value)
    assert "/dev/i2c-3 not found" in msg and "0x40" in msg and "PCA9685_I2C_BUSNUM" in msg
    assert info.value.bus == 3 and info.value.address == 0x40 and info.value.errno == errno.ENOENT


def test_wrong_address_says_run_i2cdetect(i2c, board):
    with pytest.raises(PCA9685NotFound) as info:
        PCA9685(1, 0x41, bus_factory=i2c.smbus).open()
    msg = str(info.value)
    assert "0x41 on I2C bus 1" in msg and "`i2cdetect -y 1`" in msg and "errno 121" in msg
    assert board.trace == []  # the right board was never touched


def test_bus_without_devices_fails_at_open_not_at_first_command():
    i2c = FakeI2C()
    i2c.add_bus(0)
    pca = PCA9685(0, 0x40, bus_factory=i2c.smbus)
    with pytest.raises(PCA9685NotFound, match=r"No answer from the PCA9685 at 0x40 on I2C bus 0.*i2cdetect -y 0"):
        pca.open()
    assert not pca.is_open
    assert i2c.opened[0].closed  # the bus is released after a failed probe


def test_permission_denied_says_i2c_group():
    def denied(n):
        raise PermissionError(errno.EACCES, "Permission denied", f"/dev/i2c-{n}")
    with pytest.raises(PCA9685NotFound, match="usermod -aG i2c"):
        PCA9685(1, 0x40, bus_factory=denied).open()


def test_device_that_is_not_a_pca9685(i2c):
    board = i2c.add_board(1, 0x40)
    board.regs[0xFE] = 0  # a PCA9685 never reads a prescale below 3
    with pytest.raises(PCA9685NotFound, match="not a PCA9685"):
        PCA9685(1, 0x40, bus_factory=i2c.smbus).open()


def test_bus_errors_retry_once_then_fail(i2c, board, driver, monkeypatch):
    bus = i2c.opened[0]
    real = bus.write_i2c_block_data
    failures = iter([OSError(errno.EIO, "I/O error")])

    def flaky(addr, reg, data, force=None):
        err = next(failures, None)
        if err:
            raise err
        real(addr, reg, data)
    monkeypatch.setattr(bus, "write_i2c_block_data", flaky)
    driver.set_ticks(0, 400)  # one EIO: retried
    assert board.output(0) == 400

    def dead(addr, reg, data, force=None):
        raise OSError(errno.EIO, "I/O error")
    monkeypatch.setattr(bus, "write_i2c_block_data", dead)
    with pytest.raises(I2CBusError, match="separate BEC"):
        driver.set_ticks(0, 410)


def test_software_reset_resets_the_chip(driver, board):
    driver.set_ticks(0, 400)
    driver.software_reset()
    assert board.sleeping and board.prescale == 30 and board.output(0) == OFF


def test_real_smbus2_code_path_runs_on_the_model(i2c, board):
    pytest.importorskip("smbus2")
    with real_smbus2_on(i2c):
        pca = PCA9685(1, 0x40, 60).open()  # default factory: smbus2.SMBus
        pca.set_ticks(1, 375)
        pca.set_ticks(0, 370)
        assert pca.read_channel(1) == (0, 375)
        pca.close()
        with pytest.raises(PCA9685NotFound, match="i2cdetect -y 1"):
            PCA9685(1, 0x44).open()
        with pytest.raises(PCA9685NotFound, match="/dev/i2c-7 not found"):
            PCA9685(7, 0x40).open()
    assert board.prescale == 101
    assert board.pulses(1) == [OFF, 375] and board.pulses(0) == [OFF, 370]
    assert [(t.op, t.data) for t in board.trace if t.register == 0x0A] == [("w", (0, 0, 119, 1)), ("r", (0, 0, 119, 1))]
