"""The register model behaves like the datasheet, so tests against it mean something."""

from __future__ import annotations

import errno

import pytest

from parts.actuators.fake_pca9685 import OFF, ON, FakeI2C, PCA9685Model, read_trace_file


@pytest.fixture
def model():
    return PCA9685Model()


def test_power_on_values(model):
    assert model.regs[0x00] == 0x11 and model.regs[0x01] == 0x04 and model.prescale == 30
    assert model.read(0x05) == [0xE0]  # ALLCALLADR = 0x70 << 1
    assert all(model.channel(ch).full_off for ch in range(16))
    assert all(model.output(ch) == OFF for ch in range(16))


def test_prescale_is_written_only_while_asleep(model):
    model.write(0x00, [0x21])  # awake
    model.write(0xFE, [101])
    assert model.prescale == 30
    model.write(0x00, [0x31])  # asleep
    model.write(0xFE, [101])
    assert model.prescale == 101


def test_without_auto_increment_every_byte_lands_in_one_register(model):
    model.write(0x00, [0x01])  # awake, AI = 0
    model.write(0x06, [0, 0, 0x72, 0x01])
    assert list(model.regs[0x06:0x0A]) == [0x01, 0x00, 0x00, 0x10]  # only LED0_ON_L changed
    assert model.output(0) == OFF


def test_auto_increment_and_wrap(model):
    model.write(0x00, [0x21])
    model.write(0x06, [0, 0, 0x72, 0x01])
    assert model.output(0) == 370
    model.write(0x44, [0x34, 0x12, 0x25])  # LED15_OFF_L, LED15_OFF_H, then wraps to MODE1
    assert model.regs[0x44] == 0x34 and model.regs[0x45] == 0x12 and model.regs[0x00] == 0x25


def test_reserved_registers_are_not_acknowledged(model):
    for register in (0x46, 0x80, 0xF9, 0xFF):
        with pytest.raises(OSError) as info:
            model.write(register, [1])
        assert info.value.errno == errno.EREMOTEIO
        with pytest.raises(OSError):
            model.read(register)


def test_all_led_fans_out_and_reads_zero(model):
    model.write(0x00, [0x21])
    model.write(0xFA, [0, 0, 0x2C, 0x01])  # every channel 300 ticks
    assert [model.output(ch) for ch in range(16)] == [300] * 16
    assert model.read(0xFA, 4) == [0, 0, 0, 0]
    model.write(0xFD, [0x10])
    assert all(model.output(ch) == OFF for ch in range(16))


def test_full_off_wins_over_full_on(model):
    model.write(0x00, [0x21])
    model.write(0x06, [0, 0x10, 0, 0])
    assert model.output(0) == ON
    model.write(0x06, [0, 0x10, 0, 0x10])
    assert model.output(0) == OFF
    assert model.channel(0).full_on and model.channel(0).full_off


def test_sleep_with_active_channels_sets_restart_and_stops_pulses(model):
    model.write(0x00, [0x21])
    model.write(0x06, [0, 0, 0x72, 0x01])
    model.write(0x00, [0x31])  # sleep while channel 0 runs
    assert model.regs[0x00] & 0x80 and model.output(0) == OFF
    model.write(0x00, [0x21])  # wake, no restart yet: still no pulses
    assert model.output(0) == OFF
    model.write(0x00, [0x21])  # writing 0 to RESTART has no effect
    assert model.regs[0x00] & 0x80
    model.write(0x00, [0xA1])  # RESTART, too soon after waking
    assert model.output(0) == 370 and not model.regs[0x00] & 0x80
    assert model.violations and "500 µs" in model.violations[0]
    assert model.pulses(0) == [OFF, 370, OFF, 370]


def test_single_byte_updates_pass_through_intermediate_outputs(model):
    """Why the driver writes 4 bytes at once: byte-wise 250 -> 260 ticks glitches."""
    model.write(0x00, [0x21])
    model.write(0x06, [0, 0, 250, 0])
    for i, value in enumerate([0, 0, 260 & 0xFF, 260 >> 8]):
        model.write(0x06 + i, [value])
    assert model.pulses(0) == [OFF, 250, 4, 260]


def test_fake_smbus_behaves_like_smbus2():
    i2c = FakeI2C()
    board = i2c.add_board(1, 0x40)
    with pytest.raises(FileNotFoundError):
        i2c.smbus(0)
    bus = i2c.smbus(1)
    with pytest.raises(OSError) as info:
        bus.read_byte_data(0x41, 0)
    assert info.value.errno == errno.EREMOTEIO
    with pytest.raises(TypeError):
        bus.write_byte_data(0x40, 0x01, 4.0)
    bus.write_byte_data(0x40, 0x01, 0x104)  # ctypes truncates to 0x04
    assert board.regs[0x01] == 0x04
    with pytest.raises(ValueError, match="32 bytes"):
        bus.write_i2c_block_data(0x40, 0x06, [0] * 33)
    bus.write_byte(0x00, 0x06)  # SWRST through the general call
    assert board.regs[0x00] == 0x11
    bus.close()
    with pytest.raises(OSError):
        bus.read_byte_data(0x40, 0)


def test_trace_file_records_output_changes(tmp_path):
    path = tmp_path / "trace.txt"
    model = PCA9685Model(trace_path=str(path))
    model.write(0x00, [0x21])
    model.write(0x06, [0, 0, 0x72, 0x01])
    model.write(0x06, [0, 0, 0, 0x10])
    assert read_trace_file(path) == {0: [370, OFF]}
