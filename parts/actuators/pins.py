"""Output pins for drivetrains: PWM and digital (TTL) outputs on a PCA9685 or on the Pi's GPIO.

A pin is named by DonkeyCar's pin specifier string, accepted as DonkeyCar writes it:

- ``"PCA9685.<bus>:<hex address>.<channel>"``: a channel of a PCA9685 (``"PCA9685.1:40.1"``);
- ``"RPI_GPIO.BOARD.<n>"`` / ``"RPI_GPIO.BCM.<n>"``: a header pin by board position or Broadcom
  GPIO number (one pin, two names: BOARD 33 is BCM 13, see :data:`HEADER_GPIO`), driven through
  gpiozero (lgpio, RPi.GPIO or native, whatever gpiozero picks on the machine, or
  ``GPIOZERO_PIN_FACTORY``);
- ``"PIGPIO.BCM.<n>"``: a GPIO driven through the pigpio daemon (gpiozero's pigpio factory).

:class:`PinSet` makes the pins of one drivetrain and owns what they share: one PCA9685 driver
per board (all its channels run at one frequency) and the gpiozero pin factories. Nothing is
imported or opened until :meth:`PinSet.open`.

Both kinds of output take a duty cycle in [0, 1]. PWM outputs also take 12-bit *ticks*
(1/4096 of a period at the pin's frequency), the unit of DonkeyCar's ``*_PWM`` calibrations.

>>> parse_pin("PCA9685.1:40.13")
PinSpec(provider='PCA9685', number=13, scheme=None, bus=1, address=64)
>>> parse_pin("RPI_GPIO.BOARD.33").gpio_name
'BOARD33'
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from parts.actuators.drivetrain import DrivetrainError
from parts.gpio import gpio_errors
from vehicle.config import check_settings

if TYPE_CHECKING:
    from parts.actuators.pca9685 import PCA9685, BusFactory

logger = logging.getLogger(__name__)

TICKS = 4096  # ticks per PWM period, the PCA9685's resolution and DonkeyCar's pulse unit
PROVIDERS = ("PCA9685", "RPI_GPIO", "PIGPIO")
#: the 40-pin header (every Raspberry Pi since the B+, and the Jetson's in BOARD numbering): header
#: pin -> BCM GPIO number; the other pins are power and ground (:data:`HEADER_SUPPLY`)
HEADER_GPIO: dict[int, int] = {
    3: 2, 5: 3, 7: 4, 8: 14, 10: 15, 11: 17, 12: 18, 13: 27, 15: 22, 16: 23, 18: 24, 19: 10, 21: 9, 22: 25,
    23: 11, 24: 8, 26: 7, 27: 0, 28: 1, 29: 5, 31: 6, 32: 12, 33: 13, 35: 19, 36: 16, 37: 26, 38: 20, 40: 21,
}
HEADER_SUPPLY: dict[int, str] = {1: "3.3 V power", 17: "3.3 V power", 2: "5 V power", 4: "5 V power",
                                 **{n: "ground" for n in (6, 9, 14, 20, 25, 30, 34, 39)}}
SPEC_HELP = ('"PCA9685.<bus>:<hex address>.<channel 0-15>" (e.g. "PCA9685.1:40.1"), '
             '"RPI_GPIO.BOARD.<pin>" / "RPI_GPIO.BCM.<gpio>" (e.g. "RPI_GPIO.BOARD.33") or '
             '"PIGPIO.BCM.<gpio>" (e.g. "PIGPIO.BCM.13")')


@dataclass(frozen=True)
class PinSpec:
    """A parsed pin specifier (see the module docstring)."""

    provider: str
    number: int  # PCA9685 channel, or the pin number in ``scheme``
    scheme: str | None = None  # "BOARD" or "BCM" for GPIO pins
    bus: int | None = None  # PCA9685 only
    address: int | None = None

    @property
    def gpio_name(self) -> str:
        """The pin as gpiozero names it (``BOARD33``, ``BCM13``)."""
        return f"{self.scheme}{self.number}"

    @property
    def physical(self) -> str:
        """What the spec drives, whatever it is called: ``GPIO13`` for RPI_GPIO.BOARD.33,
        RPI_GPIO.BCM.13 and PIGPIO.BCM.13 alike; the specifier itself for a PCA9685 channel."""
        if self.provider == "PCA9685":
            return str(self)
        return f"GPIO{HEADER_GPIO[self.number] if self.scheme == 'BOARD' else self.number}"

    def where(self) -> str:
        """The pin in both numberings, for messages: ``header pin 33, GPIO13``."""
        if self.provider == "PCA9685":
            return f"channel {self.number} of the PCA9685 at bus {self.bus} address 0x{self.address:02X}"
        bcm = int(self.physical[4:])
        header = next((n for n, g in HEADER_GPIO.items() if g == bcm), None)
        return f"header pin {header}, GPIO{bcm}" if header is not None else f"GPIO{bcm}, not on the header"

    @property
    def board(self) -> tuple[int, int] | None:
        """(bus, address) of a PCA9685 pin, else None."""
        return (self.bus, self.address) if self.provider == "PCA9685" else None  # type: ignore[return-value]

    def __str__(self) -> str:
        if self.provider == "PCA9685":
            return f"PCA9685.{self.bus}:{self.address:02X}.{self.number}"
        return f"{self.provider}.{self.scheme}.{self.number}"


def parse_pin(spec: object, setting: str = "pin") -> PinSpec:
    """Parse a DonkeyCar pin specifier; ValueError naming ``setting`` when it is not one."""
    def bad(why: str) -> ValueError:
        return ValueError(f"{setting} = {spec!r}: {why}; write it as {SPEC_HELP}")

    if not isinstance(spec, str):
        raise bad("a pin specifier is a string")
    parts = spec.strip().split(".")
    provider = parts[0].upper()
    if provider not in PROVIDERS:
        raise bad(f"unknown pin provider {parts[0]!r} (one of {', '.join(PROVIDERS)})")
    if len(parts) != 3:
        raise bad("expected three parts separated by dots")
    if provider == "PCA9685":
        m = re.fullmatch(r"(\d+):(?:0[xX])?([0-9a-fA-F]{1,2})", parts[1])
        if m is None or not parts[2].isdigit():
            raise bad("PCA9685 pins are <bus>:<hex address>.<channel>")
        bus, address, channel = int(m.group(1)), int(m.group(2), 16), int(parts[2])
        if not 0x03 <= address <= 0x77:
            raise bad(f"I2C address 0x{address:02X} is outside 0x03-0x77")
        if not 0 <= channel <= 15:
            raise bad(f"channel {channel} is outside 0-15")
        return PinSpec("PCA9685", channel, None, bus, address)
    scheme = parts[1].upper()
    if scheme not in ("BOARD", "BCM"):
        raise bad(f"pin numbering {parts[1]!r} must be BOARD or BCM")
    if provider == "PIGPIO" and scheme != "BCM":
        raise bad("pigpio numbers pins by BCM only")
    if not parts[2].isdigit():
        raise bad(f"pin number {parts[2]!r} is not a number")
    number = int(parts[2])
    if scheme == "BOARD" and number in HEADER_SUPPLY:
        raise bad(f"header pin {number} is {HEADER_SUPPLY[number]}, not a GPIO")
    if scheme == "BOARD" and number not in HEADER_GPIO:
        raise bad(f"header pin {number} is not on the 40-pin header (1-40)")
    return PinSpec(provider, number, scheme)


class OutputPin(Protocol):
    """A digital output: ``set(on)``; ``close()`` releases it (LOW)."""

    spec: PinSpec

    def set(self, on: bool) -> None: ...
    def close(self) -> None: ...


class PwmPin(Protocol):
    """A PWM output at a fixed frequency."""

    spec: PinSpec
    frequency: float

    def set_duty(self, duty: float) -> None: ...
    def set_ticks(self, ticks: int) -> None: ...
    def off(self) -> None: ...
    def close(self) -> None: ...


def _check_duty(duty: float) -> float:
    if not 0.0 <= duty <= 1.0:
        raise ValueError(f"duty cycle must be within [0, 1], got {duty!r}")
    return float(duty)


class PCA9685Pin:
    """One channel of a PCA9685 as a PWM or digital output (the board is opened by the PinSet)."""

    def __init__(self, spec: PinSpec, driver: PCA9685) -> None:
        self.spec = spec
        self.driver = driver

    @property
    def frequency(self) -> float:
        """The board's real PWM frequency in Hz."""
        return self.driver.frequency

    def set_ticks(self, ticks: int) -> None:
        """HIGH for ``ticks`` of the 4096 of a period (0 = LOW, 4096 = HIGH)."""
        if ticks <= 0:
            self.driver.set_full_off(self.spec.number)
        elif ticks >= TICKS:
            self.driver.set_full_on(self.spec.number)
        else:
            self.driver.set_ticks(self.spec.number, int(ticks))

    def set_duty(self, duty: float) -> None:
        """Duty cycle in [0, 1], rounded to the nearest tick."""
        self.set_ticks(round(_check_duty(duty) * TICKS))

    def set(self, on: bool) -> None:
        """Digital output: full ON or full OFF."""
        self.set_ticks(TICKS if on else 0)

    def off(self) -> None:
        """LOW: no pulses."""
        self.driver.set_full_off(self.spec.number)

    def close(self) -> None:
        """Nothing per channel: the PinSet closes the board."""


class GpioPwmPin:
    """A GPIO header pin as a PWM output through gpiozero's ``PWMOutputDevice``."""

    def __init__(self, spec: PinSpec, factory: Any, frequency: float) -> None:
        from gpiozero import PWMOutputDevice  # noqa: PLC0415 - hardware library, on open only

        self.spec = spec
        self.device = PWMOutputDevice(spec.gpio_name, frequency=frequency, initial_value=0,
                                      pin_factory=factory)
        self.frequency = float(frequency)

    def set_duty(self, duty: float) -> None:
        """Duty cycle in [0, 1]."""
        self.device.value = _check_duty(duty)

    def set_ticks(self, ticks: int) -> None:
        """HIGH for ``ticks`` of 4096 per period (a servo pulse in DonkeyCar's unit)."""
        self.device.value = min(max(ticks, 0), TICKS) / TICKS

    def off(self) -> None:
        """LOW."""
        self.device.value = 0

    def close(self) -> None:
        """Release the pin."""
        self.device.close()


class GpioOutputPin:
    """A GPIO header pin as a digital output through gpiozero's ``DigitalOutputDevice``."""

    def __init__(self, spec: PinSpec, factory: Any) -> None:
        from gpiozero import DigitalOutputDevice  # noqa: PLC0415 - hardware library, on open only

        self.spec = spec
        self.device = DigitalOutputDevice(spec.gpio_name, initial_value=False, pin_factory=factory)

    def set(self, on: bool) -> None:
        """HIGH or LOW."""
        self.device.value = bool(on)

    def close(self) -> None:
        """Release the pin."""
        self.device.close()


class PinSet:
    """Makes and owns the pins of one drivetrain.

    Args:
        frequency: PWM frequency in Hz of every PWM pin (PCA9685 boards run all channels at it).
        osc_hz: PCA9685 oscillator frequency.
        bus_factory: opens an I2C bus for PCA9685 pins (default smbus2; tests and MOCK pass the
            register-level fake).
        gpio_factory: the gpiozero pin factory for every GPIO pin (tests pass gpiozero's
            ``MockFactory``); default: gpiozero's own choice for RPI_GPIO, its pigpio factory for
            PIGPIO.
    """

    def __init__(self, frequency: float = 60.0, *, osc_hz: float | None = None,
                 bus_factory: BusFactory | None = None, gpio_factory: Any = None) -> None:
        if osc_hz is not None:
            check_settings(PCA9685_OSC_HZ=osc_hz)
        self.frequency = frequency
        self.osc_hz = osc_hz
        self.bus_factory = bus_factory
        self.gpio_factory = gpio_factory
        self.boards: dict[tuple[int, int], PCA9685] = {}
        self._factories: dict[str, Any] = {}
        self._pins: list[Any] = []
        self._used: dict[str, str] = {}

    def pwm_frequency(self, spec: PinSpec) -> float:
        """The frequency a PWM pin of ``spec`` will really run at (a PCA9685 quantises it)."""
        if spec.provider != "PCA9685":
            return float(self.frequency)
        from parts.actuators.pca9685 import OSC_HZ, actual_frequency, prescale_for  # noqa: PLC0415

        osc = self.osc_hz or OSC_HZ
        return actual_frequency(prescale_for(self.frequency, osc), osc)

    # -- making pins ------------------------------------------------------------------------------
    def pwm(self, spec: str | PinSpec, setting: str = "pin") -> PwmPin:
        """A PWM output pin for ``spec`` (opens its board or GPIO pin now)."""
        parsed = self._claim(spec, setting)
        if parsed.provider == "PCA9685":
            pin: Any = PCA9685Pin(parsed, self._board(parsed))
        else:
            pin = self._gpio(GpioPwmPin, parsed, setting, self.frequency)
        self._pins.append(pin)
        return pin

    def output(self, spec: str | PinSpec, setting: str = "pin") -> OutputPin:
        """A digital output pin for ``spec``."""
        parsed = self._claim(spec, setting)
        if parsed.provider == "PCA9685":
            pin: Any = PCA9685Pin(parsed, self._board(parsed))
        else:
            pin = self._gpio(GpioOutputPin, parsed, setting)
        self._pins.append(pin)
        return pin

    def gpio_levels(self) -> dict[str, float]:
        """What each open GPIO pin outputs now, by gpiozero name (duty 0-1; a digital pin 0 or 1):
        the bench report of GPIO_MOCK."""
        return {pin.spec.gpio_name: float(pin.device.pin.state) for pin in self._pins
                if isinstance(pin, GpioPwmPin | GpioOutputPin)}

    def close(self) -> None:
        """Release every pin and close every board (idempotent)."""
        pins, self._pins = self._pins, []
        for pin in pins:
            try:
                pin.close()
            except Exception:  # noqa: BLE001 - release the rest whatever one pin does
                logger.exception("releasing pin %s failed", pin.spec)
        for board in self.boards.values():
            board.close()
        for factory in self._factories.values():
            factory.close()
        self._factories.clear()

    # -- internals --------------------------------------------------------------------------------
    def _claim(self, spec: str | PinSpec, setting: str) -> PinSpec:
        parsed = spec if isinstance(spec, PinSpec) else parse_pin(spec, setting)
        key = parsed.physical  # the same GPIO named by BOARD and BCM numbers is one pin
        if key in self._used:
            raise ValueError(f"{setting} = {str(parsed)!r} is the same pin as {self._used[key]} "
                             f"({parsed.where()}); every output needs its own pin")
        self._used[key] = f"{setting} = {str(parsed)!r}"
        return parsed

    def _board(self, spec: PinSpec) -> PCA9685:
        key = spec.board
        assert key is not None
        if key not in self.boards:
            from parts.actuators.pca9685 import OSC_HZ, PCA9685  # noqa: PLC0415

            driver = PCA9685(key[0], key[1], self.frequency, osc_hz=self.osc_hz or OSC_HZ,
                             bus_factory=self.bus_factory)
            driver.open()
            self.boards[key] = driver
        return self.boards[key]

    def _gpio(self, cls: Any, spec: PinSpec, setting: str, *args: Any) -> Any:
        """Make a gpiozero-backed pin; gpiozero's errors become one line naming the setting."""
        where = f"{setting} = {str(spec)!r}"
        try:
            with gpio_errors(where, DrivetrainError):
                return cls(spec, self._gpio_factory(spec), *args)
        except DrivetrainError:
            raise
        except Exception as exc:  # noqa: BLE001 - gpiozero has many error classes, each said in one line
            kind = type(exc).__name__
            if spec.provider == "PIGPIO" and (isinstance(exc, ImportError | OSError) or "pigpio" in str(exc).lower()):
                raise DrivetrainError(
                    f"{where}: pigpio is not available ({exc}); install it and start its daemon (`sudo apt install "
                    "pigpio python3-pigpio && sudo systemctl enable --now pigpiod`; the Pi 5 has no pigpio: use "
                    "RPI_GPIO pins)") from exc
            if kind == "PinPWMUnsupported":  # gpiozero says nothing more; its MockFactory's default pins do no PWM
                raise DrivetrainError(f"{where}: this pin factory cannot make PWM on the pin ({kind}); for a bench "
                                      "run without GPIO set GPIO_MOCK = True (not GPIOZERO_PIN_FACTORY=mock)") from exc
            raise DrivetrainError(f"{where}: {exc or 'refused by gpiozero'} ({kind})") from exc

    def _gpio_factory(self, spec: PinSpec) -> Any:
        """The pin factory: the given one, pigpio's for PIGPIO, else None (gpiozero's default)."""
        if self.gpio_factory is not None or spec.provider != "PIGPIO":
            return self.gpio_factory
        if "PIGPIO" not in self._factories:
            from gpiozero.pins.pigpio import PiGPIOFactory  # noqa: PLC0415 - on open only

            self._factories["PIGPIO"] = PiGPIOFactory()
        return self._factories["PIGPIO"]
