"""Steering and throttle commands in [-1, 1] to servo/ESC pulse ticks, with DonkeyCar's arithmetic.

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
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from parts.actuators.drivetrain import Drivetrain, check_number, clamp
from parts.actuators.pca9685 import MAX_TICK, PULSE_MAX_US, PULSE_MIN_US, pulse_tick_range
from parts.actuators.pins import PinSet, PwmPin, parse_pin
from vehicle.config import check_settings
from vehicle.config_checks import number_text

logger = logging.getLogger(__name__)


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
            raise ValueError(f"STEERING_LEFT_PWM and STEERING_RIGHT_PWM are both {self.left}: the wheels could "
                             "not turn; valid: two pulses that differ (full left and full right, found with "
                             "`vehicle calibrate`)")
        check_settings(STEERING_TRIM=self.trim)  # beyond it, LEFT/RIGHT_PWM need recalibrating

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
                f"THROTTLE_STOPPED_PWM = {s} must be the ESC's neutral; valid: a pulse strictly between "
                f"THROTTLE_REVERSE_PWM ({r}) and THROTTLE_FORWARD_PWM ({f}) (recalibrate with `vehicle calibrate`)")
        check_settings(THROTTLE_FORWARD_LIMIT=self.forward_limit, THROTTLE_REVERSE_LIMIT=self.reverse_limit)

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


class PWMSteeringThrottle(Drivetrain):
    """The drivetrain part for a steering servo + ESC on two PWM pins (DRIVE_TRAIN_TYPE =
    "PWM_STEERING_THROTTLE"): PCA9685 channels or GPIO pins, named by pin specifiers.

    Inputs ``angle``, ``throttle`` in [-1, 1]; no outputs. The safety rules are
    :class:`~parts.actuators.drivetrain.Drivetrain`'s: neutral (steering centre, THROTTLE_STOPPED_PWM)
    at open, during ``arm_s`` (the ESC arms on neutral; no other pulse is ever sent to arm, where
    DonkeyCar pulses full throttle), under the watchdog and on every stop path; shutdown holds
    neutral for at least two PWM periods so the ESC sees whole neutral pulses, then optionally
    switches the outputs off.

    ``steering_scale`` / ``throttle_scale`` and ``*_inverted`` are DonkeyCar's PWM_*_SCALE and
    PWM_*_INVERTED: the pulse sent is ``int(pulse * scale)``, of ``4095 - pulse`` when inverted.
    Writes happen only when a pin's ticks change (one 4-byte block write on a PCA9685).
    """

    def __init__(self, pins: PinSet, steering_pin: str, throttle_pin: str,
                 steering: SteeringCalibration, throttle: ThrottleCalibration, *,
                 steering_scale: float = 1.0, throttle_scale: float = 1.0,
                 steering_inverted: bool = False, throttle_inverted: bool = False,
                 full_off_on_shutdown: bool = False, **safety: Any) -> None:
        safety.setdefault("arm_s", 1.5)
        super().__init__(**safety)
        self.specs = (parse_pin(steering_pin, "PWM_STEERING_PIN"), parse_pin(throttle_pin, "PWM_THROTTLE_PIN"))
        if str(self.specs[0]) == str(self.specs[1]):
            raise ValueError(f"PWM_STEERING_PIN and PWM_THROTTLE_PIN are both {str(self.specs[0])!r}; "
                             "the servo and the ESC need their own pins")
        for name, scale in (("PWM_STEERING_SCALE", steering_scale), ("PWM_THROTTLE_SCALE", throttle_scale)):
            if not 0.1 <= check_number(name, scale) <= 10:
                raise ValueError(f"{name} must be within [0.1, 10] (pulse multiplier for a PWM frequency "
                                 f"other than 60 Hz), got {scale}")
        self.pins = pins
        self.steering = steering
        self.throttle = throttle
        self.scales = (float(steering_scale), float(throttle_scale))
        self.inverted = (bool(steering_inverted), bool(throttle_inverted))
        self.full_off_on_shutdown = full_off_on_shutdown
        self.frequency = pins.pwm_frequency(self.specs[0])
        check_pulse_widths(self.frequency, {
            **steering_pulses(steering), "THROTTLE_FORWARD_PWM": throttle.forward,
            "THROTTLE_STOPPED_PWM": throttle.stopped, "THROTTLE_REVERSE_PWM": throttle.reverse})
        self._outputs: tuple[PwmPin, PwmPin] | None = None
        self._written: dict[int, int] = {}
        self.last_ticks: tuple[int, int] | None = None  # (steering, throttle) of the last run

    @classmethod
    def from_config(cls, cfg: Any, *, bus_factory: Any = None, gpio_factory: Any = None,
                    clock: Callable[[], float] | None = None) -> PWMSteeringThrottle:
        """DRIVE_TRAIN_TYPE = "PWM_STEERING_THROTTLE" (and "MOCK", given the simulated board's
        ``bus_factory``): pins and pulses from the PWM_STEERING_THROTTLE dict or the flat
        settings; not opened (no hardware touched)."""
        from parts.actuators.drivetrain_config import drivetrain_dict, pinset, safety_from_config  # noqa: PLC0415

        d = drivetrain_dict(cfg, "PWM_STEERING_THROTTLE")
        steering = SteeringCalibration(d["STEERING_LEFT_PWM"], d["STEERING_RIGHT_PWM"], cfg.STEERING_TRIM,
                                       cfg.STEERING_INVERT)
        throttle = ThrottleCalibration(d["THROTTLE_FORWARD_PWM"], d["THROTTLE_STOPPED_PWM"], d["THROTTLE_REVERSE_PWM"],
                                       cfg.THROTTLE_FORWARD_LIMIT, cfg.THROTTLE_REVERSE_LIMIT, cfg.THROTTLE_INVERT)
        return cls(pinset(cfg, bus_factory=bus_factory, gpio_factory=gpio_factory), d["PWM_STEERING_PIN"],
                   d["PWM_THROTTLE_PIN"], steering, throttle, steering_scale=d["PWM_STEERING_SCALE"],
                   throttle_scale=d["PWM_THROTTLE_SCALE"], steering_inverted=d["PWM_STEERING_INVERTED"],
                   throttle_inverted=d["PWM_THROTTLE_INVERTED"], full_off_on_shutdown=cfg.PWM_FULL_OFF_ON_SHUTDOWN,
                   **safety_from_config(cfg, clock))

    def describe(self) -> str:
        s, t = self.steering, self.throttle
        return (f"steering {self.specs[0]} (L {s.left} / centre {s.neutral} / R {s.right}), throttle "
                f"{self.specs[1]} (rev {t.reverse} / stop {t.stopped} / fwd {t.forward}) at {self.frequency:.2f} Hz")

    def _open_hardware(self) -> None:
        try:
            self._outputs = (self.pins.pwm(self.specs[0], "PWM_STEERING_PIN"),
                             self.pins.pwm(self.specs[1], "PWM_THROTTLE_PIN"))
        except BaseException:
            self.pins.close()
            raise

    def _limit(self, throttle: float) -> float:
        return self.throttle.limit(throttle)

    def _drive(self, angle: float, throttle: float) -> None:
        ticks = (self.steering.ticks(angle), self.throttle.map(throttle))
        self._write(0, ticks[0])
        self._write(1, ticks[1])
        self.last_ticks = ticks

    def _neutral_outputs(self) -> None:
        self._write(0, self.steering.neutral, force=True)
        self._write(1, self.throttle.neutral, force=True)

    def _hold_seconds(self) -> float:
        # the ESC must see whole neutral pulses before anything else happens to the signal
        return max(self.hold_s, 2.0 / self.frequency)

    def _close_hardware(self) -> None:
        try:
            if self.full_off_on_shutdown and self._outputs is not None:
                for pin in self._outputs:
                    pin.off()
        finally:
            self.pins.close()

    def _write(self, index: int, ticks: int, force: bool = False) -> None:
        if force or self._written.get(index) != ticks:
            assert self._outputs is not None
            out = MAX_TICK - ticks if self.inverted[index] else ticks
            self._outputs[index].set_ticks(int(out * self.scales[index]))
            self._written[index] = ticks


class MockPWMSteeringThrottle(PWMSteeringThrottle):
    """DRIVE_TRAIN_TYPE = "MOCK": the same part and driver on a simulated PCA9685
    (:func:`parts.actuators.fake_pca9685.mock_board`), for bench tests without a car."""

    @classmethod
    def from_config(cls, cfg: Any, *, bus_factory: Any = None, gpio_factory: Any = None,
                    clock: Callable[[], float] | None = None) -> PWMSteeringThrottle:
        """The simulated board at the car's bus and address, unless ``bus_factory`` is given."""
        if bus_factory is None:
            from parts.actuators.fake_pca9685 import mock_board  # noqa: PLC0415

            bus_factory = mock_board(cfg)[0]
        return super().from_config(cfg, bus_factory=bus_factory, gpio_factory=gpio_factory, clock=clock)


def check_pulse_widths(frequency: float, pulses: dict[str, int], asked: float | None = None) -> None:
    """Refuse pulses (``{setting: ticks}``) outside what servos and ESCs take at ``frequency`` (the
    PCA9685's real one for the ``asked`` PWM_FREQ); the config loader's rule calls it too."""
    tick_us = 1e6 / frequency / 4096.0
    lo, hi = pulse_tick_range(tick_us)
    at = f"PWM_FREQ = {number_text(asked)} ({frequency:.2f} Hz)" if asked is not None else f"{frequency:.2f} Hz"
    for name, ticks in pulses.items():
        if not lo <= ticks <= hi:
            raise ValueError(f"{name} = {ticks} is a {ticks * tick_us:.0f} µs pulse at {at}; "
                             f"valid: {lo} to {hi} ticks ({PULSE_MIN_US:.0f} to {PULSE_MAX_US:.0f} µs, what "
                             "servos and ESCs take; find yours with `vehicle calibrate`)")


def steering_pulses(steering: SteeringCalibration) -> dict[str, int]:
    """The steering calibration's pulses by setting name."""
    return {"STEERING_LEFT_PWM": steering.left, "STEERING_RIGHT_PWM": steering.right}
