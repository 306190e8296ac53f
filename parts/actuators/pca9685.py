"""PCA9685 16-channel 12-bit PWM driver on an SMBus, written at register level.

The driver talks to any object with smbus2's method names (``read_byte_data``,
``write_byte_data``, ``write_i2c_block_data``, ``read_i2c_block_data``, ``write_byte``,
``close``). It gets that object from a *bus factory* ``factory(busnum) -> bus``; the default
factory imports smbus2 and opens ``/dev/i2c-<busnum>``, and tests or the ``MOCK`` drivetrain pass
the register-model fake of :mod:`parts.actuators.fake_pca9685` instead, so the same code runs.

Nothing touches the bus until :meth:`PCA9685.open`, which probes the chip and initialises it
(Adafruit-compatible: mode registers, sleep, prescale from the 25 MHz clock, wake, restart). Every
failure is a :class:`PCA9685Error` naming the bus and the address with a wiring hint.

>>> prescale_for(60)
101
"""

from __future__ import annotations

import errno
import glob
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

# -- registers (NXP PCA9685 datasheet, section 7.3) -------------------------------------------------
MODE1 = 0x00
MODE2 = 0x01
LED0_ON_L = 0x06  # LEDn block = 0x06 + 4n: ON_L, ON_H, OFF_L, OFF_H
ALL_LED_ON_L = 0xFA
ALL_LED_OFF_H = 0xFD
PRE_SCALE = 0xFE

# MODE1 bits
RESTART = 0x80
AI = 0x20  # register auto-increment
SLEEP = 0x10  # oscillator off; PRE_SCALE is writable only in this state
ALLCALL = 0x01
# MODE2: OUTDRV (totem-pole), OCH = 0 (outputs change on STOP), OUTNE = 00 (LOW when OE is high)
MODE2_DEFAULT = 0x04
# ON_H / OFF_H bit 4: full-ON / full-OFF
FULL_BIT = 0x10

OSC_HZ = 25_000_000  # internal oscillator, nominal (boards differ by a few %)
PRESCALE_MIN, PRESCALE_MAX = 3, 255  # PRE_SCALE register limits (datasheet 7.3.5)
MAX_TICK = 4095  # the 12-bit counter: a pulse is 0-4095 ticks of 1/4096 period
#: pulse widths servos and ESCs can be sent, µs (the RC standard is 1000-2000; some servos need a
#: little more travel). `vehicle calibrate`, the drivetrain part and the config refuse others.
PULSE_MIN_US, PULSE_MAX_US = 500.0, 2500.0
CHANNELS = 16
#: bus when PCA9685_I2C_BUSNUM is None: header pins 3/5 on a Raspberry Pi and a Jetson Nano
DEFAULT_BUS = 1
WAKE_DELAY_S = 0.005  # datasheet: >= 500 µs for the oscillator; Adafruit waits 5 ms
GENERAL_CALL = 0x00
SWRST_BYTE = 0x06
_RETRY_ERRNOS = (errno.EIO, errno.EREMOTEIO)


class SMBusLike(Protocol):
    """The subset of ``smbus2.SMBus`` the driver uses."""

    def read_byte_data(self, i2c_addr: int, register: int) -> int: ...
    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None: ...
    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]: ...
    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int]) -> None: ...
    def write_byte(self, i2c_addr: int, value: int) -> None: ...
    def close(self) -> None: ...


BusFactory = Callable[[int], SMBusLike]


class PCA9685Error(VehicleError, RuntimeError):
    """A PCA9685 or its I2C bus failed; the message names bus and address and says what to check."""

    def __init__(self, message: str, *, bus: int, address: int, errno_: int | None = None) -> None:
        super().__init__(message)
        self.bus = bus
        self.address = address
        self.errno = errno_


class PCA9685NotFound(PCA9685Error):
    """The bus does not exist, cannot be opened, or no PCA9685 answers at the address."""


class I2CBusError(PCA9685Error):
    """A transfer failed while the chip was in use (noise, brown-out, stuck bus)."""


def smbus2_factory(busnum: int) -> SMBusLike:
    """The production bus factory: ``smbus2.SMBus(busnum)`` (smbus2 is imported only here)."""
    import smbus2  # noqa: PLC0415 - hardware library, imported only when a real bus opens

    return smbus2.SMBus(busnum)


def pwm_timing(freq_hz: float, osc_hz: float = OSC_HZ) -> tuple[int, float, float]:
    """``(prescale, real frequency in Hz, µs per tick)`` of a PCA9685 asked for ``freq_hz``, the
    prescale unchecked (rounded like both Adafruit libraries: 60 Hz -> 101, 59.84 Hz, 4.08 µs)."""
    prescale = int(osc_hz / (4096.0 * freq_hz) + 0.5) - 1
    real = actual_frequency(prescale, osc_hz)
    return prescale, real, 1e6 / real / 4096.0


def pulse_tick_range(tick_us: float) -> tuple[int, int]:
    """The ticks that make a pulse of PULSE_MIN_US to PULSE_MAX_US at ``tick_us`` µs per tick."""
    return math.ceil(PULSE_MIN_US / tick_us), min(MAX_TICK, math.floor(PULSE_MAX_US / tick_us))


def busnum(cfg: Any) -> int:
    """PCA9685_I2C_BUSNUM, with None meaning :data:`DEFAULT_BUS`."""
    return DEFAULT_BUS if cfg.PCA9685_I2C_BUSNUM is None else cfg.PCA9685_I2C_BUSNUM


def prescale_for(frequency: float, osc_hz: float = OSC_HZ) -> int:
    """PRE_SCALE for ``frequency`` Hz, rounded like both Adafruit libraries (60 Hz -> 101)."""
    if not frequency > 0:
        raise ValueError(f"PWM frequency must be > 0 Hz, got {frequency!r}")
    prescale = pwm_timing(frequency, osc_hz)[0]
    if not PRESCALE_MIN <= prescale <= PRESCALE_MAX:
        lo = osc_hz / 4096 / (PRESCALE_MAX + 1)
        hi = osc_hz / 4096 / (PRESCALE_MIN + 1)
        raise ValueError(f"PWM frequency {frequency} Hz is outside what the PCA9685 can make "
                         f"({lo:.0f}-{hi:.0f} Hz); servos and ESCs want 50-60 Hz (PWM_FREQ).")
    return prescale


def actual_frequency(prescale: int, osc_hz: float = OSC_HZ) -> float:
    """The frequency the chip really runs at for a prescale (60 Hz asks give 59.838 Hz)."""
    return osc_hz / 4096.0 / (prescale + 1)


def _existing_buses() -> str:
    found = sorted(glob.glob("/dev/i2c-*"))
    return ", ".join(found) if found else "none"


def describe_error(exc: OSError, bus: int, address: int, doing: str) -> PCA9685Error:
    """Turn an OSError from the bus into a PCA9685Error with the fix in its message."""
    where = f"PCA9685 at 0x{address:02X} on I2C bus {bus} (/dev/i2c-{bus})"
    code = exc.errno
    if isinstance(exc, FileNotFoundError) or code == errno.ENOENT:
        return PCA9685NotFound(
            f"I2C bus /dev/i2c-{bus} not found while {doing} the {where}. Enable I2C (Raspberry Pi: "
            "`sudo raspi-config` -> Interface Options -> I2C; Jetson: pins 3/5 = bus 1, 27/28 = bus 0) "
            f"or set PCA9685_I2C_BUSNUM to the bus the board is wired to (buses present: "
            f"{_existing_buses()}).", bus=bus, address=address, errno_=code)
    if isinstance(exc, PermissionError) or code == errno.EACCES:
        return PCA9685NotFound(
            f"No permission to open /dev/i2c-{bus} for the {where}. Add your user to the i2c group "
            "(`sudo usermod -aG i2c $USER`) and log in again.", bus=bus, address=address, errno_=code)
    if code in (errno.EREMOTEIO, errno.ENXIO):
        return PCA9685NotFound(
            f"No answer from the {where} while {doing} (errno {code}: no ACK). Check the SDA, SCL, GND "
            f"and VCC wires, the board's power and its A0-A5 address jumpers; run `i2cdetect -y {bus}` "
            "(a PCA9685 shows 40 and 70) and set PCA9685_I2C_ADDR / PCA9685_I2C_BUSNUM to what it shows.",
            bus=bus, address=address, errno_=code)
    if code == errno.ENOTTY:
        return PCA9685NotFound(f"/dev/i2c-{bus} is not an I2C adapter (while {doing} the {where}); "
                               "check PCA9685_I2C_BUSNUM.", bus=bus, address=address, errno_=code)
    if code == errno.EBUSY:
        return PCA9685NotFound(
            f"Address 0x{address:02X} on /dev/i2c-{bus} is claimed by a kernel driver; remove the "
            "overlay that binds it (e.g. dtoverlay=i2c-pwm-pca9685a) and reboot.",
            bus=bus, address=address, errno_=code)
    if code == errno.ETIMEDOUT:
        return I2CBusError(f"I2C bus {bus} timed out while {doing} the {where}; power-cycle the board "
                           "and check the wiring.", bus=bus, address=address, errno_=code)
    return I2CBusError(f"I2C error while {doing} the {where}: {exc}. Check pull-ups and cable length, "
                       "and power the servos from a separate BEC (servo current brown-outs show up as "
                       "bus errors).", bus=bus, address=address, errno_=code)


class PCA9685:
    """One PCA9685 chip: frequency, per-channel pulses (12-bit ticks), full-off.

    Args:
        busnum: I2C bus number (``/dev/i2c-<busnum>``).
        address: 7-bit I2C address (0x40 with no jumpers bridged).
        frequency: PWM frequency in Hz (servos/ESCs: 50-60; DonkeyCar calibrations assume 60).
        osc_hz: oscillator frequency; measure and set it if your board runs a few % off.
        bus_factory: ``factory(busnum)`` returning an SMBus-like object; default smbus2.
        sleep: the delay function (tests may pass a recording one).

    Thread safety: every bus transfer holds one lock, so parts in different threads may share
    a driver.
    """

    def __init__(self, busnum: int = 1, address: int = 0x40, frequency: float = 60.0, *,
                 osc_hz: float = OSC_HZ, bus_factory: BusFactory | None = None,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        if not isinstance(busnum, int) or isinstance(busnum, bool) or busnum < 0:
            raise ValueError(f"I2C bus number must be an int >= 0, got {busnum!r}")
        if not isinstance(address, int) or isinstance(address, bool) or not 0x03 <= address <= 0x77:
            raise ValueError(f"I2C address must be a 7-bit address 0x03-0x77, got {address!r} "
                             "(a PCA9685 is 0x40-0x7F minus 0x70; the default board is 0x40)")
        self.busnum = busnum
        self.address = address
        self.osc_hz = float(osc_hz)
        self.prescale = prescale_for(frequency, self.osc_hz)  # validates before any I/O
        self.requested_frequency = float(frequency)
        self._factory = bus_factory or smbus2_factory
        self._sleep = sleep
        self._bus: SMBusLike | None = None
        self._lock = threading.RLock()

    @classmethod
    def from_config(cls, cfg: Any, bus_factory: BusFactory | None = None) -> PCA9685:
        """The board of the car's settings (PCA9685_I2C_BUSNUM, _ADDR, PWM_FREQ, PCA9685_OSC_HZ),
        not opened yet."""
        return cls(busnum(cfg), cfg.PCA9685_I2C_ADDR, cfg.PWM_FREQ, osc_hz=cfg.PCA9685_OSC_HZ,
                   bus_factory=bus_factory)

    # -- life cycle ---------------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        """Whether the bus is open and the chip initialised."""
        return self._bus is not None

    @property
    def frequency(self) -> float:
        """The real PWM frequency in Hz (prescale-quantised)."""
        return actual_frequency(self.prescale, self.osc_hz)

    @property
    def tick_us(self) -> float:
        """Duration of one of the 4096 ticks of a period, in µs."""
        return 1e6 / self.frequency / 4096.0

    def open(self) -> PCA9685:
        """Open the bus, probe the chip and initialise it; errors name bus and address.

        Raises:
            PCA9685NotFound: no bus, no permission, nothing answers, or not a PCA9685.
            I2CBusError: a transfer failed half-way.
        """
        with self._lock:
            if self._bus is not None:
                return self
            try:
                bus = self._factory(self.busnum)
            except OSError as exc:
                raise describe_error(exc, self.busnum, self.address, "opening") from exc
            self._bus = bus
            try:
                self._initialise()
            except BaseException:
                self._bus = None
                _close_quietly(bus)
                raise
        logger.info("PCA9685 at 0x%02X on bus %d: prescale %d, %.3f Hz", self.address, self.busnum,
                    self.prescale, self.frequency)
        return self

    def _initialise(self) -> None:
        # 1. probe: the first transfer is a read, so an absent chip fails before anything is written
        mode1 = self._read(MODE1, "probing")
        old_prescale = self._read(PRE_SCALE, "probing")
        if old_prescale < PRESCALE_MIN:
            raise PCA9685NotFound(
                f"The device at 0x{self.address:02X} on I2C bus {self.busnum} answers but is not a "
                f"PCA9685 (PRE_SCALE reads {old_prescale}, a PCA9685 never reads below 3); check "
                f"PCA9685_I2C_ADDR with `i2cdetect -y {self.busnum}`.", bus=self.busnum,
                address=self.address)
        logger.debug("probe: MODE1=0x%02X PRE_SCALE=%d", mode1, old_prescale)
        # 2. known output mode: totem-pole, outputs change on STOP (4-byte writes are atomic)
        self._write(MODE2, MODE2_DEFAULT, "initialising")
        if old_prescale != self.prescale or mode1 & SLEEP:
            # 3.-5. prescale is writable only asleep. Skipped when the chip already runs at our
            # prescale (a restarted program): sleeping cuts the running pulse short (runt pulse).
            self._set_prescale()
        else:
            self._write(MODE1, AI | ALLCALL, "initialising")
            self._sleep(WAKE_DELAY_S)
        # 6. restart the PWM channels (both Adafruit libraries write RESTART after waking)
        self._write(MODE1, RESTART | AI | ALLCALL, "initialising")
        now = self._read(PRE_SCALE, "checking")
        if now != self.prescale:
            raise PCA9685NotFound(
                f"The device at 0x{self.address:02X} on I2C bus {self.busnum} did not take the "
                f"prescale (wrote {self.prescale}, reads {now}): not a PCA9685, or a second device "
                f"answers at that address; check with `i2cdetect -y {self.busnum}`.",
                bus=self.busnum, address=self.address)

    def _set_prescale(self) -> None:
        self._write(MODE1, SLEEP | AI | ALLCALL, "initialising")
        self._write(PRE_SCALE, self.prescale, "initialising")
        self._write(MODE1, AI | ALLCALL, "initialising")
        self._sleep(WAKE_DELAY_S)  # oscillator start-up before RESTART

    def close(self) -> None:
        """Close the bus. The outputs keep their last setting: write neutral or full-off first."""
        with self._lock:
            bus, self._bus = self._bus, None
        if bus is not None:
            _close_quietly(bus)

    def __enter__(self) -> PCA9685:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- channels -----------------------------------------------------------------------------
    def set_ticks(self, channel: int, off: int, on: int = 0) -> None:
        """Output HIGH from tick ``on`` to tick ``off`` of each period (pulse = off - on ticks).

        One 4-byte auto-increment block write, so the channel never passes through an
        intermediate state.
        """
        _check_channel(channel)
        for name, value in (("off", off), ("on", on)):
            if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= 4095:
                raise ValueError(f"{name} tick must be an int 0-4095, got {value!r}")
        if off == on:
            raise ValueError(f"on == off ({on}) is not a valid PWM setting; use set_full_off()")
        self._write_block(LED0_ON_L + 4 * channel, [on & 0xFF, on >> 8, off & 0xFF, off >> 8])

    def set_full_off(self, channel: int) -> None:
        """Hold one channel LOW (no pulses: most ESCs then stop, servos go limp)."""
        _check_channel(channel)
        self._write_block(LED0_ON_L + 4 * channel, [0, 0, 0, FULL_BIT])

    def set_full_on(self, channel: int) -> None:
        """Hold one channel HIGH (a digital output, or 100 % duty for a motor driver's input)."""
        _check_channel(channel)
        # full-ON is bit 4 of ON_H; OFF_H's full-OFF bit must be clear (it wins, datasheet 7.3.3)
        self._write_block(LED0_ON_L + 4 * channel, [0, FULL_BIT, 0, 0])

    def all_off(self) -> None:
        """Hold every channel LOW with one write to ALL_LED_OFF_H."""
        self._write_block(ALL_LED_ON_L, [0, 0, 0, FULL_BIT])

    def read_channel(self, channel: int) -> tuple[int, int]:
        """The raw (ON, OFF) 13-bit register values of a channel (bit 12 = full-on / full-off)."""
        _check_channel(channel)
        with self._lock:
            data = self._read_block(LED0_ON_L + 4 * channel, 4, "reading")
        return data[0] | data[1] << 8, data[2] | data[3] << 8

    def software_reset(self) -> None:
        """SWRST (general call 0x00, byte 0x06): resets *every* PCA9685 on the bus to power-on state."""
        bus = self._require_bus()
        with self._lock:
            try:
                bus.write_byte(GENERAL_CALL, SWRST_BYTE)
            except OSError as exc:
                raise describe_error(exc, self.busnum, self.address, "resetting") from exc

    def us_to_ticks(self, pulse_us: float) -> int:
        """Round a pulse width in µs to ticks at the actual frequency (1500 µs at 60 Hz -> 368)."""
        return round(pulse_us / self.tick_us)

    def ticks_to_us(self, ticks: int) -> float:
        """Pulse width in µs of ``ticks`` at the actual frequency (370 at 60 Hz -> 1509.6 µs)."""
        return ticks * self.tick_us

    # -- bus access ---------------------------------------------------------------------------
    def _require_bus(self) -> SMBusLike:
        bus = self._bus
        if bus is None:
            raise RuntimeError(f"PCA9685 0x{self.address:02X} on bus {self.busnum} is not open; "
                               "call open() first")
        return bus

    def _read(self, register: int, doing: str) -> int:
        bus = self._require_bus()
        try:
            return int(bus.read_byte_data(self.address, register))
        except OSError as exc:
            raise describe_error(exc, self.busnum, self.address, doing) from exc

    def _read_block(self, register: int, n: int, doing: str) -> list[int]:
        bus = self._require_bus()
        try:
            return [int(b) for b in bus.read_i2c_block_data(self.address, register, n)]
        except OSError as exc:
            raise describe_error(exc, self.busnum, self.address, doing) from exc

    def _write(self, register: int, value: int, doing: str) -> None:
        bus = self._require_bus()
        try:
            bus.write_byte_data(self.address, register, value)
        except OSError as exc:
            raise describe_error(exc, self.busnum, self.address, doing) from exc

    def _write_block(self, register: int, data: list[int]) -> None:
        """A block write with one bounded retry for EIO/EREMOTEIO (noise), then an error."""
        with self._lock:
            bus = self._require_bus()
            try:
                bus.write_i2c_block_data(self.address, register, data)
                return
            except OSError as exc:
                if exc.errno not in _RETRY_ERRNOS:
                    raise describe_error(exc, self.busnum, self.address, "writing to") from exc
                logger.warning("PCA9685 0x%02X: write to register 0x%02X failed (%s); retrying once",
                               self.address, register, exc)
            try:
                bus.write_i2c_block_data(self.address, register, data)
            except OSError as exc:
                raise describe_error(exc, self.busnum, self.address, "writing to") from exc


def _check_channel(channel: int) -> None:
    if not isinstance(channel, int) or isinstance(channel, bool) or not 0 <= channel < CHANNELS:
        raise ValueError(f"PCA9685 channel must be an int 0-15, got {channel!r}")


def _close_quietly(bus: Any) -> None:
    try:
        bus.close()
    except OSError as exc:  # closing must not hide the error that made us close
        logger.warning("closing the I2C bus failed: %s", exc)
