"""InvenSense MPU6050 / MPU-6500 / MPU9250 accelerometer + gyroscope over I2C (smbus2).

Register facts from the datasheets (MPU-6000/6050 register map rev 4.2; MPU-6500 register map
rev 2.1; MPU-9250 register map rev 1.6), the same on every chip of :data:`CHIPS`: WHO_AM_I 0x75
names the chip; PWR_MGMT_1 0x6B powers up with SLEEP (bit 6) set, the driver writes 0x01 (awake,
clock from the gyro's PLL); CONFIG 0x1A bits 2:0 = DLPF_CFG; GYRO_CONFIG 0x1B bits 4:3 = FS_SEL
(±250/500/1000/2000 °/s: 131/65.5/32.8/16.4 LSB per °/s); ACCEL_CONFIG 0x1C bits 4:3 = AFS_SEL
(±2/4/8/16 g: 16384/8192/4096/2048 LSB per g); ACCEL_XOUT_H 0x3B starts 14 bytes, big-endian
signed 16-bit: accel X, Y, Z, temperature, gyro X, Y, Z. Only the temperature's scale differs:
raw/340 + 36.53 °C (MPU6050), (raw - 21)/333.87 + 21 °C (MPU-6500 and the MPU-9250/9255 built on it).
Boards sold as "MPU6050" often carry an MPU-6500: the driver accepts every chip of the table,
whatever IMU_SENSOR says, and logs which one it found.
"""

from __future__ import annotations

import contextlib
import logging
import math
import struct
import time
from collections.abc import Callable, Mapping
from typing import Any, ClassVar, NamedTuple

from parts.sensors.freshness import SensorPart
from vehicle.config import check_settings
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

WHO_AM_I = 0x75
PWR_MGMT_1 = 0x6B
CONFIG = 0x1A
GYRO_CONFIG = 0x1B
ACCEL_CONFIG = 0x1C
ACCEL_XOUT_H = 0x3B


class Chip(NamedTuple):
    """A register-compatible chip: its name and temperature scale, °C = (raw - offset) / lsb + at."""

    name: str
    temp_lsb: float  # LSB per °C
    temp_offset: float  # raw reading at ``temp_at``
    temp_at: float  # °C


#: the chips this driver reads, by WHO_AM_I (datasheets above; the MPU-6000 and the MPU-9150's
#: accel/gyro die read 0x68 like the MPU6050)
CHIPS: dict[int, Chip] = {
    0x68: Chip("MPU-6050", 340.0, 0.0, 36.53),
    0x70: Chip("MPU-6500", 333.87, 21.0, 21.0),
    0x71: Chip("MPU-9250", 333.87, 21.0, 21.0),
    0x73: Chip("MPU-9255", 333.87, 21.0, 21.0),
}
#: IMU_SENSOR values (DonkeyCar's names); every one reads any chip of CHIPS
SENSORS: tuple[str, ...] = ("mpu6050", "mpu9250")
#: full-scale ranges: g -> AFS_SEL, °/s -> FS_SEL
ACCEL_RANGES: dict[int, int] = {2: 0, 4: 1, 8: 2, 16: 3}
GYRO_RANGES: dict[int, int] = {250: 0, 500: 1, 1000: 2, 2000: 3}
#: sensitivity by full scale (datasheet): LSB per g, LSB per °/s
ACCEL_LSB: dict[int, float] = {2: 16384.0, 4: 8192.0, 8: 4096.0, 16: 2048.0}
GYRO_LSB: dict[int, float] = {250: 131.0, 500: 65.5, 1000: 32.8, 2000: 16.4}
G = 9.80665  # m/s^2 per g


class IMUError(VehicleError):
    """The IMU is missing or is another chip (the message names bus, address and what to check)."""


class MPU6050:
    """Driver of a chip of :data:`CHIPS` (accelerometer and gyroscope; the MPU9250's magnetometer is
    a separate chip behind it and not read). :attr:`chip` names the chip found at open.

    Args:
        busnum: I2C bus (1 on a Raspberry Pi's header).
        address: 0x68 (AD0 low) or 0x69 (AD0 high) (IMU_ADDRESS).
        sensor: "mpu6050" or "mpu9250" (IMU_SENSOR; either reads any chip of :data:`CHIPS`).
        accel_range: ±g full scale (2, 4, 8, 16).
        gyro_range: ±°/s full scale (250, 500, 1000, 2000).
        dlpf: digital low-pass filter setting 0-6 (IMU_DLP_CONFIG).
        bus_factory: ``factory(busnum)`` -> an smbus2.SMBus-like object (tests: a register fake).
    """

    def __init__(self, busnum: int = 1, address: int = 0x68, *, sensor: str = "mpu6050", accel_range: int = 2,
                 gyro_range: int = 250, dlpf: int = 0, bus_factory: Callable[[int], Any] | None = None) -> None:
        sensor = sensor.lower()
        if sensor not in SENSORS:
            raise IMUError(f"IMU_SENSOR {sensor!r}: use 'mpu6050' or 'mpu9250'")
        check_settings(IMU_I2C_BUSNUM=busnum, IMU_ADDRESS=address, IMU_ACCEL_RANGE=accel_range,
                       IMU_GYRO_RANGE=gyro_range, IMU_DLP_CONFIG=dlpf)
        self.busnum, self.address, self.sensor = busnum, address, sensor
        self.accel_range, self.gyro_range, self.dlpf = accel_range, gyro_range, dlpf
        self._factory = bus_factory
        self._bus: Any = None
        self.temperature: float | None = None  # °C at the latest read
        self.chip: str | None = None  # the chip WHO_AM_I named at open ("MPU-6500")
        self._temp = CHIPS[0x68]

    def _where(self) -> str:
        return f"IMU ({self.chip or self.sensor}) at I2C bus {self.busnum} address 0x{self.address:02X}"

    def open(self) -> None:
        """Check WHO_AM_I, wake the chip and set the ranges and filter."""
        factory = self._factory
        if factory is None:
            import smbus2  # noqa: PLC0415 - hardware library, imported only when a part starts

            factory = smbus2.SMBus
        try:
            self._bus = factory(self.busnum)
            who = self._bus.read_byte_data(self.address, WHO_AM_I)
        except OSError as exc:
            raise IMUError(f"{self._where()}: no answer ({exc}); check the wiring (SDA, SCL, 3.3 V, GND), "
                           "IMU_ADDRESS (0x68, or 0x69 with AD0 high) and `i2cdetect -y 1`") from exc
        chip = CHIPS.get(who)
        if chip is None:
            known = ", ".join(f"0x{v:02X} {c.name}" for v, c in CHIPS.items())
            raise IMUError(f"{self._where()}: WHO_AM_I reads 0x{who:02X}, not a chip this driver reads ({known}); "
                           "check IMU_ADDRESS (`i2cdetect -y 1`: another device may answer there)")
        self.chip, self._temp = chip.name, chip
        logger.info("IMU: %s (WHO_AM_I 0x%02X) at I2C bus %d address 0x%02X", chip.name, who, self.busnum,
                    self.address)
        self._bus.write_byte_data(self.address, PWR_MGMT_1, 0x01)
        time.sleep(0.01)  # the PLL settles (datasheet: gyro start-up 30 ms typical; first reads may lag)
        self._bus.write_byte_data(self.address, CONFIG, self.dlpf)
        self._bus.write_byte_data(self.address, GYRO_CONFIG, GYRO_RANGES[self.gyro_range] << 3)
        self._bus.write_byte_data(self.address, ACCEL_CONFIG, ACCEL_RANGES[self.accel_range] << 3)

    def read(self) -> tuple[float, float, float, float, float, float]:
        """(ax, ay, az) in m/s^2 and (gx, gy, gz) in rad/s; the temperature goes to :attr:`temperature`."""
        data = bytes(self._bus.read_i2c_block_data(self.address, ACCEL_XOUT_H, 14))
        ax, ay, az, temp, gx, gy, gz = struct.unpack(">7h", data)
        a_scale = G / ACCEL_LSB[self.accel_range]
        g_scale = math.radians(1.0 / GYRO_LSB[self.gyro_range])
        chip = self._temp
        self.temperature = (temp - chip.temp_offset) / chip.temp_lsb + chip.temp_at
        return ax * a_scale, ay * a_scale, az * a_scale, gx * g_scale, gy * g_scale, gz * g_scale

    def close(self) -> None:
        """Put the chip to sleep and release the bus."""
        if self._bus is not None:
            with contextlib.suppress(OSError):
                self._bus.write_byte_data(self.address, PWR_MGMT_1, 0x40)
            self._bus.close()
            self._bus = None


class IMU(SensorPart):
    """Part: ``imu/acl_x, imu/acl_y, imu/acl_z`` (m/s^2), ``imu/gyr_x, imu/gyr_y, imu/gyr_z`` (rad/s)
    and ``imu/ok``, DonkeyCar's keys. Add it threaded (an I2C read takes about a millisecond).

    Args:
        device: an :class:`MPU6050` (or anything with open/read/close giving six floats).
        max_age: seconds without a reading after which the values read None.
        period: seconds between readings when threaded.
    """

    OUTPUTS: ClassVar[tuple[str, ...]] = ("imu/acl_x", "imu/acl_y", "imu/acl_z", "imu/gyr_x", "imu/gyr_y",
                                          "imu/gyr_z", "imu/ok")
    RECORDED: ClassVar[Mapping[str, str]] = dict.fromkeys(OUTPUTS[:6], "float")

    def __init__(self, device: Any, *, max_age: float = 0.5, period: float = 0.01,
                 clock: Callable[[], float] = time.monotonic) -> None:
        check_settings(IMU_MAX_AGE_S=max_age)
        super().__init__(max_age, clock)
        self.device = device
        self.period = period

    @classmethod
    def from_config(cls, cfg: Any, clock: Callable[[], float] | None = None) -> IMU:
        """IMU_SENSOR at IMU_I2C_BUSNUM (None: 1) / IMU_ADDRESS, IMU_ACCEL_RANGE, IMU_GYRO_RANGE,
        IMU_DLP_CONFIG, IMU_MAX_AGE_S."""
        bus = 1 if cfg.IMU_I2C_BUSNUM is None else cfg.IMU_I2C_BUSNUM
        device = MPU6050(bus, cfg.IMU_ADDRESS, sensor=cfg.IMU_SENSOR, accel_range=cfg.IMU_ACCEL_RANGE,
                         gyro_range=cfg.IMU_GYRO_RANGE, dlpf=cfg.IMU_DLP_CONFIG)
        return cls(device, max_age=cfg.IMU_MAX_AGE_S, clock=clock or time.monotonic)

    def open(self) -> None:
        self.device.open()

    def read(self) -> tuple[object, ...] | None:
        try:
            return tuple(self.device.read())
        except OSError:  # a glitch on the bus: no reading this time (staleness shows a lasting fault)
            return None

    def close(self) -> None:
        self.device.close()

    def where(self) -> str:
        """The I2C bus and address."""
        return f"at bus {self.device.busnum} 0x{self.device.address:02X}"

    def describe(self, values: tuple[object, ...]) -> tuple[bool, str]:
        """Acceleration (with its magnitude: 9.8 at rest), turn rates and the chip's temperature."""
        ok, text = super().describe(values)
        if not ok:
            return ok, text
        ax, ay, az, gx, gy, gz = (float(v) for v in values[:6])  # type: ignore[arg-type]
        temp = self.device.temperature
        return True, (f"{self.where()}: acc ({ax:.2f}, {ay:.2f}, {az:.2f}) m/s^2 |a| {math.hypot(ax, ay, az):.2f}, "
                      f"gyro ({gx:.3f}, {gy:.3f}, {gz:.3f}) rad/s" + (f", {temp:.1f} °C" if temp is not None else ""))
