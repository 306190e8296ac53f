"""Wheel encoders: tick counters on GPIO pins (gpiozero) or on a microcontroller over serial.

- :class:`GpioTicks` counts a single-channel encoder (one pin; the direction comes from the
  throttle, DonkeyCar's TACHOMETER_MODE) or a quadrature encoder (two pins, A and B; the direction
  comes from the phase, one tick per full cycle of A, i.e. ENCODER_PPR ticks per revolution).
- :class:`SerialTicks` speaks DonkeyCar's Arduino encoder protocol (``arduino/*_encoder.ino``):
  the host sends ``r\\n`` (reset to zero) and ``p\\n`` (send the position now); the device answers
  one line ``ticks,ms[;ticks,ms]`` per request, one ``ticks,ms`` pair per encoder, ``ms`` being its
  ``millis()`` at the reading.
- :class:`Encoder` is the part: cumulative ticks per channel and the reading's time, with staleness.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from typing import Any, ClassVar, Literal, Protocol

from parts.gpio import gpio_errors, pin_factory
from parts.sensors.freshness import SensorPart
from parts.serial_port import pyserial_port
from vehicle.config import check_settings
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

#: DonkeyCar's TACHOMETER_MODE values for a single-channel encoder
TachometerMode = Literal["FORWARD_ONLY", "FORWARD_REVERSE", "FORWARD_REVERSE_STOP"]
TACHOMETER_MODES: tuple[str, ...] = ("FORWARD_ONLY", "FORWARD_REVERSE", "FORWARD_REVERSE_STOP")


class EncoderError(VehicleError):
    """An encoder cannot be opened or answers nonsense (the message says which and how to check)."""


class TickSource(Protocol):
    """What :class:`Encoder` reads: cumulative signed ticks per channel."""

    channels: int

    def open(self) -> None: ...
    def read(self) -> tuple[int, ...] | None: ...
    def close(self) -> None: ...


def gpio_pin_name(pin: int | str) -> str:
    """A pin as gpiozero names it: an int is a header pin number (DonkeyCar's ODOM_PIN is in board
    numbering), DonkeyCar's specifiers ``RPI_GPIO.BOARD.33`` / ``RPI_GPIO.BCM.13`` /
    ``PIGPIO.BCM.13`` are translated, other strings (``GPIO17``, ``BOARD11``) pass as they are."""
    if isinstance(pin, int) and not isinstance(pin, bool):
        return f"BOARD{pin}"
    if not isinstance(pin, str) or not pin:
        raise EncoderError(f"encoder pin {pin!r}: use a header pin number (13), 'GPIO17' or 'RPI_GPIO.BCM.17'")
    parts = pin.split(".")
    if len(parts) == 3 and parts[0] in ("RPI_GPIO", "PIGPIO") and parts[1] in ("BOARD", "BCM") and parts[2].isdigit():
        return f"{'BOARD' if parts[1] == 'BOARD' else 'GPIO'}{int(parts[2])}"
    return pin


class GpioTicks:
    """Ticks of an encoder on GPIO pins, counted by gpiozero callbacks.

    Args:
        pin: the encoder's output (single channel) or its A channel.
        pin_b: the B channel of a quadrature encoder (None: single channel).
        mode: direction rule of a single channel (see :data:`TACHOMETER_MODES`): FORWARD_ONLY counts
            up; FORWARD_REVERSE counts with the sign of the last non-zero throttle; FORWARD_REVERSE_STOP
            counts with the sign of the current throttle and ignores pulses at zero throttle.
        debounce_s: ignore pulses closer than this after the previous one (ENCODER_DEBOUNCE_NS).
        pin_factory: gpiozero pin factory (tests: ``MockFactory``; GPIO_MOCK: the simulated pins);
            None = gpiozero's default.
        settings: the names of ``pin`` and ``pin_b`` in the car's settings, for messages.
    """

    def __init__(self, pin: int | str, pin_b: int | str | None = None, *, mode: TachometerMode = "FORWARD_ONLY",
                 debounce_s: float = 0.0, pin_factory: Any = None,
                 settings: tuple[str, str] = ("ODOM_PIN", "ODOM_PIN_B")) -> None:
        if mode not in TACHOMETER_MODES:
            raise EncoderError(f"TACHOMETER_MODE {mode!r}: use one of {', '.join(TACHOMETER_MODES)}")
        check_settings(ENCODER_DEBOUNCE_NS=round(debounce_s * 1e9), **{settings[0]: pin},
                       **({settings[1]: pin_b} if pin_b is not None else {}))
        self.pin, self.pin_b = gpio_pin_name(pin), None if pin_b is None else gpio_pin_name(pin_b)
        given = [f"{settings[0]} = {pin!r}"] + ([] if pin_b is None else [f"{settings[1]} = {pin_b!r}"])
        self.where = ", ".join(given)  # the settings as the user wrote them, for messages
        self.mode = mode
        self.debounce_s = float(debounce_s)
        self.pin_factory = pin_factory
        self.channels = 1
        self.direction = 1  # single channel: sign of the count, set from the throttle
        self._count = 0
        self._device: Any = None

    def open(self) -> None:
        """Claim the pins (gpiozero imported here)."""
        bounce = self.debounce_s or None
        with gpio_errors(f"encoder {self.where}", EncoderError):
            import gpiozero  # noqa: PLC0415 - hardware library, imported only when a part starts

            self._make(gpiozero, bounce)

    def _make(self, gpiozero: Any, bounce: float | None) -> None:
        try:
            if self.pin_b is not None:
                self._device = gpiozero.RotaryEncoder(self.pin, self.pin_b, max_steps=0, bounce_time=bounce,
                                                      pin_factory=self.pin_factory)
            else:
                self._device = gpiozero.DigitalInputDevice(self.pin, pull_up=True, bounce_time=bounce,
                                                           pin_factory=self.pin_factory)
                self._device.when_activated = self._pulse
        except gpiozero.BadPinFactory:
            raise  # no GPIO here: gpio_errors says so
        except (gpiozero.GPIOZeroError, ValueError) as exc:
            raise EncoderError(f"encoder {self.where}: {exc} (check the pin setting and that no other program "
                               "uses the pin)") from exc

    def _pulse(self, *_: Any) -> None:
        if self.mode == "FORWARD_ONLY":
            self._count += 1
        elif self.direction:
            self._count += self.direction

    def set_throttle(self, throttle: float | None) -> None:
        """Direction of a single-channel count from the throttle command (see ``mode``)."""
        if throttle is None:
            return
        if throttle > 0:
            self.direction = 1
        elif throttle < 0:
            self.direction = -1
        elif self.mode == "FORWARD_REVERSE_STOP":
            self.direction = 0

    def read(self) -> tuple[int, ...] | None:
        """The cumulative ticks (None before open)."""
        if self._device is None:
            return None
        return (int(self._device.steps),) if self.pin_b is not None else (self._count,)

    def close(self) -> None:
        """Release the pins."""
        if self._device is not None:
            self._device.close()
            self._device = None


class TickGroup:
    """Several single-channel tick sources read as one (left and right wheel on GPIO pins)."""

    def __init__(self, sources: Sequence[GpioTicks]) -> None:
        self.sources = list(sources)
        self.channels = len(self.sources)

    def open(self) -> None:
        for source in self.sources:
            source.open()

    def set_throttle(self, throttle: float | None) -> None:
        for source in self.sources:
            source.set_throttle(throttle)

    def read(self) -> tuple[int, ...] | None:
        readings = [source.read() for source in self.sources]
        if any(r is None for r in readings):
            return None
        return tuple(r[0] for r in readings if r is not None)

    def close(self) -> None:
        for source in self.sources:
            source.close()


def tachometer_mode(value: str | int) -> TachometerMode:
    """TACHOMETER_MODE as a name: DonkeyCar's config writes the constants 1, 2, 3."""
    if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= 3:
        return TACHOMETER_MODES[value - 1]  # type: ignore[return-value]
    if value in TACHOMETER_MODES:
        return value  # type: ignore[return-value]
    raise EncoderError(f"TACHOMETER_MODE {value!r}: use one of {', '.join(TACHOMETER_MODES)} (or 1, 2, 3)")


class SerialTicks:
    """Ticks from a microcontroller speaking DonkeyCar's encoder protocol over serial.

    Args:
        port: serial device (``/dev/ttyACM0``) or a pyserial URL.
        baudrate: ODOM_SERIAL_BAUDRATE (the sketches use 115200).
        channels: encoders the device reports (1, or 2 for a differential drive: left, right).
        timeout: seconds to wait for an answer to one request.
        serial_factory: ``factory(port, baudrate, timeout)`` returning a pyserial-like object
            (default ``serial.serial_for_url``).
    """

    def __init__(self, port: str, baudrate: int = 115200, *, channels: int = 1, timeout: float = 0.2,
                 serial_factory: Callable[..., Any] | None = None) -> None:
        if channels not in (1, 2):
            raise EncoderError(f"serial encoder: channels must be 1 or 2, got {channels}")
        check_settings(ODOM_SERIAL_BAUDRATE=baudrate)
        self.port, self.baudrate, self.channels, self.timeout = port, int(baudrate), channels, float(timeout)
        self._factory = serial_factory
        self._serial: Any = None
        self.bad_lines = 0  # answers that did not parse
        self.device_ms: int | None = None  # the device's millis() at the latest reading

    def open(self) -> None:
        """Open the port and reset the device's counts to zero."""
        factory = self._factory or pyserial_port
        try:
            self._serial = factory(self.port, self.baudrate, self.timeout)
        except (OSError, ValueError) as exc:
            raise EncoderError(f"encoder serial port {self.port}: {exc} (check ODOM_SERIAL, the cable, and "
                               "that your user is in the 'dialout' group)") from exc
        self._serial.reset_input_buffer()
        self._serial.write(b"r\n")

    def read(self) -> tuple[int, ...] | None:
        """Ask for the position and parse the answer; None when no valid answer came in time."""
        if self._serial is None:
            return None
        self._serial.write(b"p\n")
        line = self._serial.readline()
        if not line:
            return None
        ticks = self.parse(line)
        if ticks is None:
            self.bad_lines += 1
            logger.debug("serial encoder: ignored line %r", line)
        return ticks

    def parse(self, line: bytes) -> tuple[int, ...] | None:
        """``b"ticks,ms[;ticks,ms]\\n"`` -> ticks per channel (None: not a valid answer)."""
        try:
            pairs = [p.split(",") for p in line.decode("ascii").strip().split(";")]
            if len(pairs) < self.channels or any(len(p) != 2 for p in pairs):
                return None
            values = [(int(t), int(ms)) for t, ms in pairs[: self.channels]]
        except (UnicodeDecodeError, ValueError):
            return None
        self.device_ms = values[0][1]
        return tuple(t for t, _ in values)

    def close(self) -> None:
        """Close the port."""
        if self._serial is not None:
            self._serial.close()
            self._serial = None


class Encoder(SensorPart):
    """Part: cumulative ticks of one encoder -> ``enc/ticks, enc/timestamp, enc/ok``; of two
    (``channels=2``: differential drive) -> ``enc/left/ticks, enc/right/ticks, enc/timestamp, enc/ok``.

    ``enc/timestamp`` is the reading's time on ``clock`` (seconds), which the odometer divides by.
    Input ``throttle`` sets a single-channel GPIO encoder's direction. Add it threaded for a serial
    device (each reading waits for an answer); a GPIO counter is instant.

    Args:
        source: a :class:`GpioTicks`, :class:`SerialTicks` or any :class:`TickSource`.
        max_age: seconds without a reading after which the values read None (ok False).
        period: seconds between readings when threaded.
        clock: time source of the timestamps and the staleness (the vehicle's clock).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("throttle",)
    FEEDBACK: ClassVar[tuple[str, ...]] = ("throttle",)
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("throttle",)

    def __init__(self, source: TickSource, *, max_age: float = 0.5, period: float = 0.01,
                 clock: Callable[[], float] = time.monotonic, mm_per_tick: float | None = None) -> None:
        check_settings(ODOM_MAX_AGE_S=max_age, **({} if mm_per_tick is None else {"MM_PER_TICK": mm_per_tick}))
        super().__init__(max_age, clock)
        self.source = source
        self.period = period
        self.mm_per_tick = mm_per_tick  # only to say the ticks in metres (hw check); the odometer scales

    @property
    def OUTPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """The ticks of one channel or of the left and right wheels, their time, the ok flag."""
        ticks = ("enc/ticks",) if self.source.channels == 1 else ("enc/left/ticks", "enc/right/ticks")
        return (*ticks, "enc/timestamp", "enc/ok")

    @classmethod
    def from_config(cls, cfg: Any, clock: Callable[[], float] | None = None) -> Encoder:
        """The encoder of a car's settings: ENCODER_TYPE "GPIO" (ODOM_PIN[, ODOM_PIN_B], with
        HAVE_ODOM_2 a second single-channel encoder on ODOM_PIN_2) or "ARDUINO" (ODOM_SERIAL, two
        channels with HAVE_ODOM_2)."""
        kind = str(cfg.ENCODER_TYPE).upper()
        two = bool(cfg.HAVE_ODOM_2)
        source: TickSource
        if kind != "GPIO":  # each kind reads only its own settings (a bad unused one is no error)
            source = make_tick_source(kind, port=cfg.ODOM_SERIAL, baudrate=cfg.ODOM_SERIAL_BAUDRATE,
                                      channels=2 if two else 1)
            return cls(source, max_age=cfg.ODOM_MAX_AGE_S, clock=clock or time.monotonic,
                       mm_per_tick=cfg.MM_PER_TICK)
        mode = tachometer_mode(cfg.TACHOMETER_MODE)
        debounce = cfg.ENCODER_DEBOUNCE_NS / 1e9
        factory = pin_factory(cfg.GPIO_MOCK)
        if two:
            source = TickGroup([
                GpioTicks(cfg.ODOM_PIN, mode=mode, debounce_s=debounce, pin_factory=factory),
                GpioTicks(cfg.ODOM_PIN_2, mode=mode, debounce_s=debounce, pin_factory=factory,
                          settings=("ODOM_PIN_2", ""))])
        else:
            pins = [cfg.ODOM_PIN] + ([cfg.ODOM_PIN_B] if cfg.ODOM_PIN_B is not None else [])
            source = make_tick_source(kind, pins=pins, mode=mode, debounce_s=debounce, pin_factory=factory)
        return cls(source, max_age=cfg.ODOM_MAX_AGE_S, clock=clock or time.monotonic, mm_per_tick=cfg.MM_PER_TICK)

    def where(self) -> str:
        """The serial port of an Arduino counter, or the GPIO pin(s)."""
        port = getattr(self.source, "port", None)
        if port:
            return f"on {port}"
        pins = (getattr(self.source, "pin", None), getattr(self.source, "pin_b", None))
        return "on pin " + "/".join(str(p) for p in pins if p)

    def describe(self, values: tuple[object, ...]) -> tuple[bool, str]:
        """The ticks counted (in metres at MM_PER_TICK)."""
        ok, text = super().describe(values)
        if not ok:
            return ok, text
        ticks = [int(t) for t in values[:-2]]  # type: ignore[call-overload]
        metres = f" ({', '.join(f'{t * self.mm_per_tick / 1000:.2f} m' for t in ticks)} at MM_PER_TICK " \
                 f"{self.mm_per_tick:.3g})" if self.mm_per_tick else ""
        return True, f"{self.where()}: ticks {', '.join(str(t) for t in ticks)}{metres}; turn a wheel and run again"

    def open(self) -> None:
        self.source.open()

    def read(self) -> tuple[object, ...] | None:
        inputs = self.inputs
        setter = getattr(self.source, "set_throttle", None)
        if setter is not None and inputs:
            setter(inputs[0])
        ticks = self.source.read()
        if ticks is None:
            return None
        return (*ticks, self.freshness.clock())

    def close(self) -> None:
        self.source.close()


def make_tick_source(kind: str, *, pins: Sequence[int | str] = (), port: str = "", baudrate: int = 115200,
                     channels: int = 1, mode: TachometerMode = "FORWARD_ONLY", debounce_s: float = 0.0,
                     pin_factory: Any = None) -> TickSource:
    """The tick source for DonkeyCar's ENCODER_TYPE: "GPIO" (``pins``: one pin, or A and B of a
    quadrature encoder, on ``pin_factory``) or "ARDUINO" (``port``)."""
    kind = kind.upper()
    if kind == "GPIO":
        if len(pins) not in (1, 2):
            raise EncoderError(f"ENCODER_TYPE 'GPIO' needs ODOM_PIN (and ODOM_PIN_B for quadrature), got {list(pins)}")
        return GpioTicks(pins[0], pins[1] if len(pins) == 2 else None, mode=mode, debounce_s=debounce_s,
                         pin_factory=pin_factory)
    if kind == "ARDUINO":
        return SerialTicks(port, baudrate, channels=channels)
    raise EncoderError(f"ENCODER_TYPE {kind!r} is not supported: use 'GPIO' or 'ARDUINO'")
