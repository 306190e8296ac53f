"""Steering and throttle commands in [-1, 1] to PCA9685 ticks, with DonkeyCar's arithmetic.

DonkeyCar maps with ``map_range`` (a *floor*, after clamping the input to [-1, 1]), so the same
STEERING_LEFT_PWM / STEERING_RIGHT_PWM / THROTTLE_*_PWM values give the same pulses here: with the
defaults at 60 Hz, steering -1/0/+1 -> 460/375/290 and throttle -1/0/+1 -> 220/370/500.

>>> SteeringCalibration(left=460, right=290).ticks(0.0)
375
>>> ThrottleCalibration(forward=500, stopped=370, reverse=220).ticks(-0.5)
295
"""

from __future__ import annotations

import logging
import math
import numbers
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from parts.actuators.esc import ReverseStateMachine, SlewLimiter
from parts.actuators.pca9685 import MAX_TICK, PULSE_MAX_US, PULSE_MIN_US, pulse_tick_range
from parts.actuators.watchdog import CommandWatchdog

if TYPE_CHECKING:
    from parts.actuators.pca9685 import PCA9685, BusFactory

logger = logging.getLogger(__name__)


def clamp(x: float, lo: float, hi: float) -> float:
    """``x`` limited to [lo, hi]."""
    return lo if x < lo else hi if x > hi else x


def map_range(x: float, x_min: float, x_max: float, y_min: float, y_max: float) -> int:
    """DonkeyCar's ``map_range``: linear map, rounded down (floor), as an int.

    >>> map_range(0.01, -1, 1, 460, 290)
    374
    """
    x_range = x_max - x_min
    y_range = y_max - y_min
    return int(((x - x_min) / (x_range / y_range) + y_min) // 1)


def _check_tick(name: str, value: object) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= MAX_TICK:
        raise ValueError(f"{name} must be a pulse in ticks, an int 1-4095, got {value!r} "
                         "(find yours with `vehicle calibrate`)")
    return value


def _check_number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise TypeError(f"{name} must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class SteeringCalibration:
    """Steering pulses: ``left`` at angle -1, ``right`` at +1 (ticks at PWM_FREQ).

    ``trim`` (steering units, added before clamping) moves the centre without recalibrating;
    ``invert`` swaps left and right.
    """

    left: int = 460
    right: int = 290
    trim: float = 0.0
    invert: bool = False

    def __post_init__(self) -> None:
        _check_tick("STEERING_LEFT_PWM", self.left)
        _check_tick("STEERING_RIGHT_PWM", self.right)
        if self.left == self.right:
            raise ValueError(f"STEERING_LEFT_PWM and STEERING_RIGHT_PWM are both {self.left}: the "
                             "wheels could not turn; calibrate both ends with `vehicle calibrate`")
        if not -0.5 <= _check_number("STEERING_TRIM", self.trim) <= 0.5:
            raise ValueError(f"STEERING_TRIM must be within [-0.5, 0.5] (steering units), got "
                             f"{self.trim}; a larger offset means LEFT/RIGHT_PWM need recalibrating")

    def ticks(self, angle: float) -> int:
        """Ticks for a steering angle in [-1, 1] (values outside are clamped)."""
        a = -angle if self.invert else angle
        a = clamp(clamp(a, -1.0, 1.0) + self.trim, -1.0, 1.0)
        return map_range(a, -1.0, 1.0, self.left, self.right)

    @property
    def neutral(self) -> int:
        """Ticks for straight ahead (the midpoint, moved by the trim)."""
        return self.ticks(0.0)


@dataclass(frozen=True)
class ThrottleCalibration:
    """Throttle pulses: ``reverse`` at -1, ``stopped`` at 0, ``forward`` at +1 (ticks).

    ``forward_limit`` / ``reverse_limit`` cap the command (fractions of full throttle) before the
    mapping; ``invert`` swaps forward and reverse.
    """

    forward: int = 500
    stopped: int = 370
    reverse: int = 220
    forward_limit: float = 1.0
    reverse_limit: float = 1.0
    invert: bool = False

    def __post_init__(self) -> None:
        f = _check_tick("THROTTLE_FORWARD_PWM", self.forward)
        s = _check_tick("THROTTLE_STOPPED_PWM", self.stopped)
        r = _check_tick("THROTTLE_REVERSE_PWM", self.reverse)
        if not (r < s < f or r > s > f):
            raise ValueError(
                f"THROTTLE_STOPPED_PWM ({s}) must lie strictly between THROTTLE_REVERSE_PWM ({r}) and "
                f"THROTTLE_FORWARD_PWM ({f}); recalibrate with `vehicle calibrate`")
        for name, limit in (("THROTTLE_FORWARD_LIMIT", self.forward_limit),
                            ("THROTTLE_REVERSE_LIMIT", self.reverse_limit)):
            if not 0.0 <= _check_number(name, limit) <= 1.0:
                raise ValueError(f"{name} must be within [0, 1] (fraction of full throttle), got {limit}")

    def limit(self, throttle: float) -> float:
        """The command after inversion, clamping to [-1, 1] and the forward/reverse limits."""
        t = -throttle if self.invert else throttle
        return clamp(t, -self.reverse_limit, self.forward_limit)

    def ticks(self, throttle: float) -> int:
        """Ticks for a throttle command: :meth:`limit`, then :meth:`map`."""
        return self.map(self.limit(throttle))

    def map(self, t: float) -> int:
        """DonkeyCar's piecewise map around ``stopped`` (no inversion or limits applied)."""
        t = clamp(t, -1.0, 1.0)
        if t > 0:
            return map_range(t, 0.0, 1.0, self.stopped, self.forward)
        return map_range(t, -1.0, 0.0, self.reverse, self.stopped)

    @property
    def neutral(self) -> int:
        """Ticks that stop the motor (THROTTLE_STOPPED_PWM)."""
        return self.stopped


class PWMSteeringThrottle:
    """The drivetrain part: steering servo + ESC on two channels of one PCA9685.

    Inputs ``angle``, ``throttle`` in [-1, 1]; no outputs. Safety behaviour:

    - :meth:`open` (called by ``add_drivetrain`` before the loop starts, or lazily by the first
      ``run``) probes and initialises the chip and writes neutral to both channels; it is the only
      place hardware is touched before driving. Constructors never touch the bus.
    - ESC arming: throttle stays at THROTTLE_STOPPED_PWM for ``arm_s`` seconds after open, and
      then until a command at neutral arrives (a throttle held at start never launches the car).
      No other pulse is ever sent to arm (DonkeyCar pulses full throttle here).
    - command watchdog: no fresh command for ``watchdog_s`` -> neutral, and throttle stays neutral
      until a command at neutral arrives again. None or NaN commands are not fresh.
    - :meth:`neutral` (the Vehicle calls it first on every stop path) writes neutral at once;
      :meth:`shutdown` writes neutral again, holds it ``hold_s`` (at least two PWM periods) so the
      ESC sees complete neutral pulses, optionally switches the outputs off, closes the bus.

    Writes happen only when a channel's ticks change (one 4-byte block write each).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle")
    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    #: |throttle| at or below this counts as "at neutral" for arming and re-arming
    NEUTRAL_BAND = 0.05

    def __init__(self, driver: PCA9685, steering_channel: int, throttle_channel: int,
                 steering: SteeringCalibration, throttle: ThrottleCalibration, *,
                 slew_rate: float | None = None, reverse: ReverseStateMachine | None = None,
                 arm_s: float = 1.5, watchdog_s: float | None = 0.5, hold_s: float = 0.1,
                 full_off_on_shutdown: bool = False, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        for name, ch in (("STEERING_CHANNEL", steering_channel), ("THROTTLE_CHANNEL", throttle_channel)):
            if not isinstance(ch, int) or isinstance(ch, bool) or not 0 <= ch <= 15:
                raise ValueError(f"{name} must be a PCA9685 channel 0-15, got {ch!r}")
        if steering_channel == throttle_channel:
            raise ValueError(f"STEERING_CHANNEL and THROTTLE_CHANNEL are both {steering_channel}; "
                             "the servo and the ESC need their own channels")
        if not 0 <= _check_number("ESC_ARM_TIME_S", arm_s) <= 10:
            raise ValueError(f"ESC_ARM_TIME_S must be 0-10 seconds, got {arm_s}")
        if not 0 <= _check_number("PWM_SHUTDOWN_HOLD_S", hold_s) <= 5:
            raise ValueError(f"PWM_SHUTDOWN_HOLD_S must be 0-5 seconds, got {hold_s}")
        _check_pulse_widths(driver, steering, throttle)
        self.name = "PWMSteeringThrottle"
        self.driver = driver
        self.channels = (steering_channel, throttle_channel)
        self.steering = steering
        self.throttle = throttle
        self.slew = SlewLimiter(slew_rate)
        self.reverse = reverse or ReverseStateMachine("direct")
        self.arm_s = float(arm_s)
        self.hold_s = float(hold_s)
        self.full_off_on_shutdown = full_off_on_shutdown
        self.clock = clock
        self._sleep = sleep
        self._lock = threading.RLock()
        self._written: dict[int, int] = {}
        self._opened_at: float | None = None
        self._armed = False
        self._closed = False
        self.watchdog = CommandWatchdog(watchdog_s, self._on_watchdog, clock) if watchdog_s else None
        self.last_ticks: tuple[int, int] | None = None  # (steering, throttle) of the last run

    @classmethod
    def from_config(cls, cfg: Any, *, bus_factory: BusFactory | None = None,
                    clock: Callable[[], float] | None = None) -> PWMSteeringThrottle:
        """DRIVE_TRAIN_TYPE = "PWM_STEERING_THROTTLE": servo and ESC on the car's PCA9685, not opened
        yet (no hardware touched). ``bus_factory`` replaces smbus2; ``clock`` the monotonic clock."""
        from parts.actuators.esc import ReverseStateMachine
        from parts.actuators.pca9685 import PCA9685

        steering = SteeringCalibration(cfg.STEERING_LEFT_PWM, cfg.STEERING_RIGHT_PWM, cfg.STEERING_TRIM,
                                       cfg.STEERING_INVERT)
        throttle = ThrottleCalibration(cfg.THROTTLE_FORWARD_PWM, cfg.THROTTLE_STOPPED_PWM,
                                       cfg.THROTTLE_REVERSE_PWM, cfg.THROTTLE_FORWARD_LIMIT,
                                       cfg.THROTTLE_REVERSE_LIMIT, cfg.THROTTLE_INVERT)
        reverse = ReverseStateMachine(cfg.ESC_REVERSE_MODE, cfg.ESC_REVERSE_BRAKE_S, cfg.ESC_REVERSE_NEUTRAL_S)
        return cls(
            PCA9685.from_config(cfg, bus_factory), cfg.STEERING_CHANNEL, cfg.THROTTLE_CHANNEL, steering, throttle,
            slew_rate=cfg.THROTTLE_SLEW_RATE, reverse=reverse, arm_s=cfg.ESC_ARM_TIME_S,
            watchdog_s=cfg.ACTUATOR_WATCHDOG_S, hold_s=cfg.PWM_SHUTDOWN_HOLD_S,
            full_off_on_shutdown=cfg.PWM_FULL_OFF_ON_SHUTDOWN, clock=clock or time.monotonic)

    # -- life cycle ---------------------------------------------------------------------------
    def open(self) -> PWMSteeringThrottle:
        """Probe and initialise the board, write neutral, start the arming time and the watchdog."""
        with self._lock:
            if self._opened_at is not None:
                return self
            self.driver.open()
            self._write_neutral()
            self._opened_at = self.clock()
        if self.watchdog is not None:
            self.watchdog.start()
        else:
            logger.warning("drivetrain: the command watchdog is off (ACTUATOR_WATCHDOG_S = None): if the "
                           "loop stalls, the last throttle stays on; set it to 0.5 in myconfig.py")
        logger.info("drivetrain ready: steering ch %d (L %d / centre %d / R %d), throttle ch %d "
                    "(rev %d / stop %d / fwd %d) at %.2f Hz; arming the ESC for %.1f s",
                    self.channels[0], self.steering.left, self.steering.neutral, self.steering.right,
                    self.channels[1], self.throttle.reverse, self.throttle.stopped, self.throttle.forward,
                    self.driver.frequency, self.arm_s)
        return self

    def run(self, angle: float | None, throttle: float | None) -> None:
        """Drive: map the commands to ticks and write the channels that changed."""
        if self._opened_at is None:
            self.open()
        with self._lock:
            if self._closed:
                return
            now = self.clock()
            fresh = _valid(throttle)
            if not fresh and throttle is not None:
                logger.warning("throttle command %r is not a finite number: neutral", throttle)
            a = float(angle) if _valid(angle) else 0.0
            t = float(throttle) if fresh else 0.0
            if fresh and self.watchdog is not None:
                self.watchdog.feed()
            if not self._armed:
                if now - self._opened_at < self.arm_s:
                    t = 0.0
                elif abs(t) <= self.NEUTRAL_BAND:
                    self._armed = True
                    logger.info("drivetrain armed: throttle commands now reach the ESC")
                else:
                    t = 0.0
            t = self.reverse.step(self.slew.step(self.throttle.limit(t), now), now)
            ticks = (self.steering.ticks(a), self.throttle.map(t))
            self._write(self.channels[0], ticks[0])
            self._write(self.channels[1], ticks[1])
            self.last_ticks = ticks

    def neutral(self) -> None:
        """Steering centre and throttle stopped, now (the Vehicle calls this on every stop path)."""
        with self._lock:
            if self._opened_at is None or self._closed:
                return
            self._write_neutral()

    def shutdown(self) -> None:
        """Stop the watchdog, write neutral and hold it >= two PWM periods, then release the bus."""
        if self.watchdog is not None:
            self.watchdog.shutdown()
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if self._opened_at is None:
                return
            try:
                self._write_neutral()
                # the ESC must see whole neutral pulses before anything else happens to the signal
                self._sleep(max(self.hold_s, 2.0 / self.driver.frequency))
                if self.full_off_on_shutdown:
                    for ch in self.channels:
                        self.driver.set_full_off(ch)
            finally:
                self.driver.close()

    # -- internals ----------------------------------------------------------------------------
    def _on_watchdog(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._write_neutral()  # also disarms: throttle waits for a command at neutral again

    def _write_neutral(self) -> None:
        self.slew.reset()
        self.reverse.reset()
        self._armed = False
        self._write(self.channels[0], self.steering.neutral, force=True)
        self._write(self.channels[1], self.throttle.neutral, force=True)

    def _write(self, channel: int, ticks: int, force: bool = False) -> None:
        if force or self._written.get(channel) != ticks:
            self.driver.set_ticks(channel, ticks)
            self._written[channel] = ticks


class MockPWMSteeringThrottle(PWMSteeringThrottle):
    """DRIVE_TRAIN_TYPE = "MOCK": the same part and driver on a simulated PCA9685
    (:func:`parts.actuators.fake_pca9685.mock_board`), for bench tests without a car."""

    @classmethod
    def from_config(cls, cfg: Any, *, bus_factory: BusFactory | None = None,
                    clock: Callable[[], float] | None = None) -> PWMSteeringThrottle:
        """The simulated board at the car's bus and address, unless ``bus_factory`` is given."""
        if bus_factory is None:
            from parts.actuators.fake_pca9685 import mock_board

            bus_factory = mock_board(cfg)[0]
        return super().from_config(cfg, bus_factory=bus_factory, clock=clock)


def _check_pulse_widths(driver: PCA9685, steering: SteeringCalibration, throttle: ThrottleCalibration) -> None:
    """Refuse calibrations whose pulses are outside what servos and ESCs take at the driver's
    frequency (the config loader refuses them too; this guards code that builds the part)."""
    tick_us = driver.tick_us
    lo, hi = pulse_tick_range(tick_us)
    for name, ticks in (("STEERING_LEFT_PWM", steering.left), ("STEERING_RIGHT_PWM", steering.right),
                        ("THROTTLE_FORWARD_PWM", throttle.forward), ("THROTTLE_STOPPED_PWM", throttle.stopped),
                        ("THROTTLE_REVERSE_PWM", throttle.reverse)):
        if not lo <= ticks <= hi:
            raise ValueError(f"{name} = {ticks} is a {ticks * tick_us:.0f} µs pulse at {driver.frequency:.2f} Hz; "
                             f"valid: {lo} to {hi} ticks ({PULSE_MIN_US:.0f} to {PULSE_MAX_US:.0f} µs, what "
                             "servos and ESCs take; find yours with `vehicle calibrate`)")


def _valid(x: object) -> bool:
    """A usable command: a finite real number (numpy scalars too). None and NaN mean "no command";
    anything else is a wiring mistake."""
    if x is None:
        return False
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        raise TypeError(f"PWMSteeringThrottle: drive commands must be numbers in [-1, 1] or None, got "
                        f"{type(x).__name__} {x!r}; check what feeds the angle/throttle keys")
    return math.isfinite(x)

