"""The MPU6050/MPU9250 driver against a register-level model of the chip."""

from __future__ import annotations

import math

import pytest
from sensor_fakes import FakeSMBus, MPU6050Model

from parts.sensors.imu import IMU, MPU6050, IMUError


def _driver(model: MPU6050Model, address: int = 0x68, **kw) -> MPU6050:
    bus = FakeSMBus({address: model})
    return MPU6050(1, address, bus_factory=lambda n: bus, **kw)


def test_open_wakes_the_chip_and_sets_ranges() -> None:
    model = MPU6050Model()
    imu = _driver(model, accel_range=8, gyro_range=1000, dlpf=3)
    imu.open()
    assert model.regs[0x6B] & 0x40 == 0  # SLEEP cleared
    assert model.regs[0x1C] == 2 << 3 and model.regs[0x1B] == 2 << 3 and model.regs[0x1A] == 3
    imu.close()
    assert model.regs[0x6B] & 0x40  # asleep again


@pytest.mark.parametrize(("accel_range", "gyro_range"), [(2, 250), (16, 2000)])
def test_readings_in_si_units(accel_range: int, gyro_range: int) -> None:
    model = MPU6050Model()
    model.accel_g = (0.5, -0.25, 1.0)
    model.gyro_dps = (10.0, -90.0, 180.0)
    model.temp_raw = -521  # (-521 / 340) + 36.53 = 35.0 °C
    imu = _driver(model, accel_range=accel_range, gyro_range=gyro_range)
    imu.open()
    ax, ay, az, gx, gy, gz = imu.read()
    lsb_g = 32768 / accel_range / 9.80665  # LSB per m/s^2
    assert (ax, ay, az) == pytest.approx((0.5 * 9.80665, -0.25 * 9.80665, 9.80665), abs=1 / lsb_g)
    tol = math.radians(gyro_range / 32768) * 2
    assert (gx, gy, gz) == pytest.approx((math.radians(10), math.radians(-90), math.radians(180)), abs=tol)
    assert imu.temperature == pytest.approx(35.0, abs=0.01)


@pytest.mark.parametrize(("who", "chip", "temp_raw"), [
    (0x68, "MPU-6050", -521),  # raw / 340 + 36.53 (MPU-6000/6050 register map 4.18)
    (0x70, "MPU-6500", round((35.0 - 21) * 333.87) + 21),  # (raw - 21) / 333.87 + 21 (MPU-6500 map 4.23)
    (0x71, "MPU-9250", round((35.0 - 21) * 333.87) + 21),
    (0x73, "MPU-9255", round((35.0 - 21) * 333.87) + 21),
])
@pytest.mark.parametrize("sensor", ["mpu6050", "mpu9250"])
def test_register_compatible_chips_are_accepted_and_named(who, chip, temp_raw, sensor, caplog) -> None:
    """Boards sold as "MPU6050" often carry an MPU-6500: any chip of the family opens, whatever
    IMU_SENSOR says, and the log names the chip found."""
    model = MPU6050Model(who)
    model.accel_g = (0.0, 0.0, 1.0)
    model.temp_raw = temp_raw
    imu = _driver(model, sensor=sensor)
    with caplog.at_level("INFO", logger="parts.sensors.imu"):
        imu.open()
    assert imu.chip == chip
    assert f"{chip} (WHO_AM_I 0x{who:02X})" in caplog.text
    assert imu.read()[2] == pytest.approx(9.80665, abs=0.01)
    assert imu.temperature == pytest.approx(35.0, abs=0.01)
    imu.close()


def test_unknown_chip_and_missing_chip_are_named() -> None:
    with pytest.raises(IMUError, match=r"WHO_AM_I reads 0x12.*0x68 MPU-6050.*0x70 MPU-6500") as e:
        _driver(MPU6050Model(0x12)).open()
    assert "\n" not in str(e.value)
    model = MPU6050Model(0x71)
    bus = FakeSMBus({0x68: model})
    with pytest.raises(IMUError, match="0x69.*no answer"):
        MPU6050(1, 0x69, sensor="mpu9250", bus_factory=lambda n: bus).open()


def test_imu_part_keys_and_staleness() -> None:
    model = MPU6050Model()
    model.accel_g = (0.0, 0.0, 1.0)
    clock = [0.0]
    part = IMU(_driver(model), max_age=0.1, clock=lambda: clock[0])
    assert part.OUTPUTS[-1] == "imu/ok" and part.OUTPUTS[0] == "imu/acl_x"
    out = part.run()
    assert out[-1] is True and out[2] == pytest.approx(9.80665, abs=0.01)
    part.device._bus.devices.clear()  # the chip drops off the bus: reads fail
    clock[0] = 0.05
    assert part.run()[-1] is True  # the last reading is fresh enough
    clock[0] = 0.2
    assert part.run() == (None,) * 6 + (False,)
    part.shutdown()
