"""A PCA9685 register model and an SMBus look-alike: the hardware-free board behind ``MOCK``.

:class:`PCA9685Model` behaves like the datasheet: power-on values (MODE1 0x11 asleep, MODE2 0x04,
PRE_SCALE 30, every channel full-off), PRE_SCALE writes ignored unless SLEEP is set, register
auto-increment only when MODE1.AI is set (otherwise every byte lands in the same register),
ALL_LED broadcast registers (write-only, read 0), full-on/full-off bits, the RESTART bit, and
reserved registers that are not acknowledged (``OSError`` errno 121, like a NACK on a Pi).

:class:`FakeI2C` holds buses of models; its :meth:`FakeI2C.smbus` is a bus factory for
:class:`parts.actuators.pca9685.PCA9685`, so the real driver code runs against the model. Each
model keeps a transaction trace and a per-channel history of the *output* (what a scope on the
pin would show), optionally appended to a text file so another process can check it.
"""

from __future__ import annotations

import errno
import os
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from parts.actuators import pca9685 as reg

#: output value of a channel in :attr:`PCA9685Model.history`: ticks HIGH per period, or these
OFF = "off"  # no pulses (full-off, ON == OFF, or oscillator stopped)
ON = "on"  # constant HIGH (full-on)
Output = int | str

_RESERVED = range(0x46, 0xFA)
_TEST_MODE = 0xFF


class Transfer(NamedTuple):
    """One bus transaction seen by a model: ``op`` is "w" or "r", data the bytes moved."""

    t: float
    op: str
    register: int
    data: tuple[int, ...]


class PulseEvent(NamedTuple):
    """The output of a channel changed at time ``t`` to ``output``."""

    t: float
    output: Output


@dataclass(frozen=True)
class ChannelState:
    """Decoded LEDn registers."""

    on: int
    off: int
    full_on: bool
    full_off: bool


def _nack(register: int) -> OSError:
    return OSError(errno.EREMOTEIO, f"Remote I/O error (register 0x{register:02X} not acknowledged)")


class PCA9685Model:
    """One PCA9685 at the register level.

    Args:
        clock: time source for the trace and history (default ``time.monotonic``).
        trace_path: if set, every output change is appended to this file as a line
            ``<t> <channel> <ticks|off|on>`` (unbuffered, so a killed process leaves it complete).
        osc_hz: the oscillator the model pretends to have.
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic, trace_path: str | None = None,
                 osc_hz: float = reg.OSC_HZ) -> None:
        self.clock = clock
        self.osc_hz = osc_hz
        self.trace_path = trace_path
        self.trace: list[Transfer] = []
        self.history: dict[int, list[PulseEvent]] = {ch: [] for ch in range(reg.CHANNELS)}
        self.violations: list[str] = []  # datasheet timing rules broken by the driver
        self._lock = threading.Lock()
        self._woke_at: float | None = None
        self.regs = bytearray(256)
        self.power_on_reset()

    # -- state ------------------------------------------------------------------------------------
    def power_on_reset(self) -> None:
        """Registers as after power-up or SWRST: asleep, 200 Hz prescale, every channel full-off."""
        r = self.regs
        r[:] = bytes(256)
        r[reg.MODE1] = reg.SLEEP | reg.ALLCALL
        r[reg.MODE2] = reg.MODE2_DEFAULT
        r[0x02], r[0x03], r[0x04], r[0x05] = 0xE2, 0xE4, 0xE8, 0xE0
        for ch in range(reg.CHANNELS):
            r[reg.LED0_ON_L + 4 * ch + 3] = reg.FULL_BIT
        r[reg.PRE_SCALE] = 0x1E
        self._restart_pending = False
        self._record_outputs(to_file=bool(self.trace))  # power-up itself is not written to the file

    @property
    def sleeping(self) -> bool:
        """MODE1.SLEEP: oscillator off, no pulses."""
        return bool(self.regs[reg.MODE1] & reg.SLEEP)

    @property
    def prescale(self) -> int:
        """The PRE_SCALE register."""
        return self.regs[reg.PRE_SCALE]

    def frequency(self) -> float:
        """PWM frequency in Hz from the prescale."""
        return reg.actual_frequency(self.prescale, self.osc_hz)

    def channel(self, n: int) -> ChannelState:
        """Decoded registers of channel ``n``."""
        b = self.regs[reg.LED0_ON_L + 4 * n: reg.LED0_ON_L + 4 * n + 4]
        return ChannelState(b[0] | (b[1] & 0x0F) << 8, b[2] | (b[3] & 0x0F) << 8,
                            bool(b[1] & reg.FULL_BIT), bool(b[3] & reg.FULL_BIT))

    def output(self, n: int) -> Output:
        """What pin ``n`` does now: pulse length in ticks, ``OFF`` or ``ON``."""
        if self.sleeping or self._restart_pending:
            return OFF
        c = self.channel(n)
        if c.full_off:  # full-off wins over full-on
            return OFF
        if c.full_on:
            return ON
        width = (c.off - c.on) % 4096
        return OFF if width == 0 else width

    def pulse_us(self, n: int) -> float | None:
        """Pulse width of channel ``n`` in µs (None when it sends no pulses)."""
        out = self.output(n)
        if not isinstance(out, int):
            return None
        return out * 1e6 / self.frequency() / 4096.0

    def pulses(self, n: int) -> list[Output]:
        """The history of channel ``n`` without times (the first entry is the power-on OFF)."""
        return [e.output for e in self.history[n]]

    # -- bus side ----------------------------------------------------------------------------------
    def write(self, register: int, data: Sequence[int]) -> None:
        """One write transaction starting at ``register`` (outputs update at its STOP)."""
        with self._lock:
            if register in _RESERVED or register == _TEST_MODE:
                raise _nack(register)
            self.trace.append(Transfer(self.clock(), "w", register, tuple(data)))
            pointer = register
            for value in data:
                self._write_register(pointer, value)
                pointer = self._next(pointer)
            self._record_outputs()

    def read(self, register: int, n: int = 1) -> list[int]:
        """One read transaction of ``n`` bytes starting at ``register``."""
        with self._lock:
            if register in _RESERVED or register == _TEST_MODE:
                raise _nack(register)
            out, pointer = [], register
            for _ in range(n):
                out.append(0 if reg.ALL_LED_ON_L <= pointer <= reg.ALL_LED_OFF_H else self.regs[pointer])
                pointer = self._next(pointer)
            self.trace.append(Transfer(self.clock(), "r", register, tuple(out)))
            return out

    def software_reset(self) -> None:
        """SWRST received through the general call address."""
        with self._lock:
            self.trace.append(Transfer(self.clock(), "w", -1, (reg.SWRST_BYTE,)))
            self.power_on_reset()

    def _next(self, pointer: int) -> int:
        if not self.regs[reg.MODE1] & reg.AI:
            return pointer  # AI = 0: every byte lands in the same register
        if pointer == 0x45 or pointer >= reg.PRE_SCALE:
            return 0x00
        if pointer == reg.ALL_LED_OFF_H:
            return reg.PRE_SCALE
        return pointer + 1

    def _write_register(self, r: int, value: int) -> None:
        value &= 0xFF
        if r == reg.MODE1:
            self._write_mode1(value)
        elif r == reg.PRE_SCALE:
            if self.sleeping:  # datasheet: writes are blocked while the oscillator runs
                self.regs[r] = max(value, reg.PRESCALE_MIN)
        elif reg.ALL_LED_ON_L <= r <= reg.ALL_LED_OFF_H:
            offset = r - reg.ALL_LED_ON_L
            for ch in range(reg.CHANNELS):
                self.regs[reg.LED0_ON_L + 4 * ch + offset] = value & (0x1F if offset % 2 else 0xFF)
        elif reg.LED0_ON_L <= r <= 0x45:
            # ON_H / OFF_H bits 7..5 are read-only zeros
            self.regs[r] = value & (0x1F if (r - reg.LED0_ON_L) % 2 else 0xFF)
        elif r == _TEST_MODE:
            raise _nack(r)
        else:
            self.regs[r] = value

    def _write_mode1(self, value: int) -> None:
        old = self.regs[reg.MODE1]
        now = self.clock()
        if value & reg.SLEEP and not old & reg.SLEEP and any(
                self.output(ch) != OFF for ch in range(reg.CHANNELS)):
            self._restart_pending = True  # going to sleep with active channels sets RESTART
        if old & reg.SLEEP and not value & reg.SLEEP:
            self._woke_at = now
        if value & reg.RESTART and self._restart_pending and not value & reg.SLEEP:
            if self._woke_at is not None and now - self._woke_at < 0.0005:
                self.violations.append(f"RESTART written {1e6 * (now - self._woke_at):.0f} µs after "
                                       "wake-up; the oscillator needs 500 µs")
            self._restart_pending = False
        # RESTART reads 1 while a restart is pending; writing 0 to it has no effect
        self.regs[reg.MODE1] = (value & ~reg.RESTART & 0xFF) | (reg.RESTART if self._restart_pending else 0)

    def _record_outputs(self, to_file: bool = True) -> None:
        t = self.clock()
        lines = []
        for ch in range(reg.CHANNELS):
            out = self.output(ch)
            hist = self.history[ch]
            if not hist or hist[-1].output != out:
                hist.append(PulseEvent(t, out))
                lines.append(f"{t:.6f} {ch} {out}\n")
        if lines and self.trace_path and to_file:
            fd = os.open(self.trace_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
            try:
                os.write(fd, "".join(lines).encode())
            finally:
                os.close(fd)


def read_trace_file(path: str | os.PathLike[str]) -> dict[int, list[Output]]:
    """Parse a model's trace file into ``{channel: [output, ...]}`` in the order written."""
    result: dict[int, list[Output]] = {}
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) != 3:
                continue  # a torn last line of a killed writer
            out: Output = parts[2] if parts[2] in (OFF, ON) else int(parts[2])
            result.setdefault(int(parts[1]), []).append(out)
    return result


def _byte(value: Any) -> int:
    """What ctypes does with a value for a c_uint8: floats are refused, ints are truncated."""
    if isinstance(value, float) or not isinstance(value, int):
        raise TypeError(f"int expected instead of {type(value).__name__}")
    return value & 0xFF


class FakeSMBus:
    """``smbus2.SMBus``'s methods over the models of one :class:`FakeI2C` bus."""

    def __init__(self, i2c: FakeI2C, busnum: int) -> None:
        self._i2c = i2c
        self.busnum = busnum
        self.closed = False

    def _model(self, address: int) -> PCA9685Model:
        if self.closed:
            raise OSError(errno.EBADF, "Bad file descriptor (bus closed)")
        model = self._i2c.buses[self.busnum].get(address)
        if model is None:
            raise OSError(errno.EREMOTEIO, "Remote I/O error")
        return model

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        return self._model(i2c_addr).read(_byte(register), 1)[0]

    def write_byte_data(self, i2c_addr: int, register: int, value: int, force: bool | None = None) -> None:
        self._model(i2c_addr).write(_byte(register), [_byte(value)])

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int,
                            force: bool | None = None) -> list[int]:
        if length > 32:
            raise ValueError("Desired block length over 32 bytes")
        return self._model(i2c_addr).read(_byte(register), length)

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int],
                             force: bool | None = None) -> None:
        if len(data) > 32:
            raise ValueError("Data length cannot exceed 32 bytes")
        self._model(i2c_addr).write(_byte(register), [_byte(v) for v in data])

    def write_byte(self, i2c_addr: int, value: int, force: bool | None = None) -> None:
        if i2c_addr == reg.GENERAL_CALL:  # every chip on the bus listens to the general call
            if self.closed:
                raise OSError(errno.EBADF, "Bad file descriptor (bus closed)")
            if _byte(value) == reg.SWRST_BYTE:
                for model in self._i2c.buses[self.busnum].values():
                    model.software_reset()
            return
        model = self._model(i2c_addr)
        with model._lock:  # a bare byte sets the register pointer only
            model.trace.append(Transfer(model.clock(), "w", _byte(value), ()))

    def read_byte(self, i2c_addr: int, force: bool | None = None) -> int:
        return self._model(i2c_addr).read(0, 1)[0]

    def close(self) -> None:
        self.closed = True

    def __enter__(self) -> FakeSMBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class FakeI2C:
    """Some I2C buses with PCA9685 models on them; :meth:`smbus` is the driver's bus factory.

    >>> i2c = FakeI2C(); board = i2c.add_board(bus=1, address=0x40)
    >>> from parts.actuators.pca9685 import PCA9685
    >>> pca = PCA9685(1, 0x40, 60, bus_factory=i2c.smbus).open()
    >>> board.prescale
    101
    """

    def __init__(self) -> None:
        self.buses: dict[int, dict[int, PCA9685Model]] = {}
        self.opened: list[FakeSMBus] = []

    def add_bus(self, bus: int) -> None:
        """An adapter with nothing on it (every transfer NACKs)."""
        self.buses.setdefault(bus, {})

    def add_board(self, bus: int = 1, address: int = 0x40, model: PCA9685Model | None = None,
                  **model_args: Any) -> PCA9685Model:
        """Put a PCA9685 model at ``address`` on ``bus`` and return it."""
        model = model if model is not None else PCA9685Model(**model_args)
        self.buses.setdefault(bus, {})[address] = model
        return model

    def smbus(self, busnum: int) -> FakeSMBus:
        """Open ``/dev/i2c-<busnum>``: FileNotFoundError when the bus does not exist, like smbus2."""
        if busnum not in self.buses:
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", f"/dev/i2c-{busnum}")
        bus = FakeSMBus(self, busnum)
        self.opened.append(bus)
        return bus


def mock_board(cfg: Any) -> tuple[Callable[[int], FakeSMBus], PCA9685Model]:
    """A simulated PCA9685 at the car's bus and address (DRIVE_TRAIN_TYPE = "MOCK", ``vehicle
    calibrate --mock``): (bus factory, register model), tracing to PCA9685_MOCK_TRACE when set.

    The model keeps real (monotonic) time, also under a simulated vehicle clock: it checks the
    driver's real delays (oscillator start-up) against the datasheet.
    """
    from parts.actuators.pca9685 import busnum

    trace = str(cfg.path("PCA9685_MOCK_TRACE")) if cfg.PCA9685_MOCK_TRACE else None
    i2c = FakeI2C()
    model = i2c.add_board(busnum(cfg), cfg.PCA9685_I2C_ADDR, trace_path=trace)
    return i2c.smbus, model
