"""DC motors on H-bridges, and the drivetrains built from them.

Two ways to wire one motor to an H-bridge (L298N, L9110S, TB6612, DRV8833 ...), DonkeyCar's terms:

- **2-pin** (:class:`HBridge2Pin`): two PWM inputs. Forward = duty on FWD, BWD LOW; reverse = the
  other way round; both LOW = coast (the motor is disconnected and glides); both HIGH = brake
  (the windings are shorted).
- **3-pin** (:class:`HBridge3Pin`, the L298N's IN1/IN2/EN): two digital direction inputs and one
  PWM enable. FWD HIGH + BWD LOW = forward at the EN duty; LOW/HIGH = reverse; both LOW = coast;
  both HIGH with EN HIGH = brake.

Neutral is *brake* for drive motors (the car stops, it does not roll on) and *coast* for a DC
steering motor (a spring-centred toy-car steering returns to straight by itself).

Drivetrains (DRIVE_TRAIN_TYPE): :class:`ServoHBridge` (SERVO_HBRIDGE_2PIN / _3PIN),
:class:`DCSteerThrottle` (DC_STEER_THROTTLE), :class:`DifferentialDrive` (DC_TWO_WHEEL /
DC_TWO_WHEEL_L298N, with arcade mixing: :func:`arcade_mix`).

>>> arcade_mix(0.5, 0.0)
(0.5, 0.5)
>>> arcade_mix(1.0, 0.5)
(1.0, 0.3333333333333333)
>>> arcade_mix(0.0, 1.0)
(1.0, -1.0)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from parts.actuators.drivetrain import Drivetrain, check_number, clamp
from parts.actuators.drivetrain_config import drivetrain_dict, motor_limits, pinset, safety_from_config
from parts.actuators.pins import OutputPin, PinSet, PwmPin, parse_pin
from parts.actuators.pwm import MAX_TICK, SteeringCalibration, check_pulse_widths, steering_pulses
from vehicle.config import check_settings


def arcade_mix(throttle: float, angle: float) -> tuple[float, float]:
    """Arcade mixing for differential drive: (left, right) wheel commands in [-1, 1].

    ``left = throttle + angle``, ``right = throttle - angle`` (angle +1 turns right), both scaled
    down together when one exceeds 1, so the turn keeps its shape at full throttle. With throttle 0
    the car turns on the spot.
    """
    left, right = throttle + angle, throttle - angle
    scale = max(1.0, abs(left), abs(right))
    return left / scale, right / scale


@dataclass(frozen=True)
class MotorPins:
    """The pin specifiers of one H-bridge motor: 2-pin (``fwd``, ``bwd`` PWM) or 3-pin
    (``fwd``, ``bwd`` digital + ``duty`` PWM). ``names`` are the settings, for messages."""

    fwd: str
    bwd: str
    duty: str | None = None
    names: tuple[str, str, str] = ("FWD_DUTY_PIN", "BWD_DUTY_PIN", "DUTY_PIN")

    @classmethod
    def from_dict(cls, kind: str, d: dict[str, Any], fwd: str, bwd: str, duty: str | None = None) -> MotorPins:
        """The motor whose pins are keys ``fwd``, ``bwd`` (and ``duty``) of the dict setting ``kind``."""
        names = tuple(f"{kind}[{k!r}]" if k else "" for k in (fwd, bwd, duty))
        return cls(d[fwd], d[bwd], d[duty] if duty else None, names)  # type: ignore[arg-type]

    def check(self) -> None:
        """Parse every specifier now (one-line errors naming the setting)."""
        for spec, name in zip((self.fwd, self.bwd, self.duty), self.names, strict=True):
            if spec is not None:
                parse_pin(spec, name)

    def open(self, pins: PinSet) -> HBridge2Pin | HBridge3Pin:
        """The motor on opened pins."""
        if self.duty is None:
            return HBridge2Pin(pins.pwm(self.fwd, self.names[0]), pins.pwm(self.bwd, self.names[1]))
        return HBridge3Pin(pins.output(self.fwd, self.names[0]), pins.output(self.bwd, self.names[1]),
                           pins.pwm(self.duty, self.names[2]))

    def __str__(self) -> str:
        pins = f"{self.fwd}/{self.bwd}" + (f"/{self.duty}" if self.duty else "")
        return f"H-bridge {'3' if self.duty else '2'}-pin {pins}"


class HBridge2Pin:
    """A motor on two PWM inputs (see the module doc)."""

    def __init__(self, fwd: PwmPin, bwd: PwmPin) -> None:
        self.fwd, self.bwd = fwd, bwd

    def drive(self, value: float) -> None:
        """Speed in [-1, 1]; 0 coasts."""
        v = clamp(value, -1.0, 1.0)
        # the idle side first, so both inputs are never driven at once on a direction change
        if v >= 0:
            self.bwd.set_duty(0.0)
            self.fwd.set_duty(v)
        else:
            self.fwd.set_duty(0.0)
            self.bwd.set_duty(-v)

    def brake(self) -> None:
        """Both inputs HIGH: windings shorted."""
        self.fwd.set_duty(1.0)
        self.bwd.set_duty(1.0)

    def coast(self) -> None:
        """Both inputs LOW: motor disconnected."""
        self.fwd.set_duty(0.0)
        self.bwd.set_duty(0.0)


class HBridge3Pin:
    """A motor on two direction inputs and a PWM enable (see the module doc)."""

    def __init__(self, fwd: OutputPin, bwd: OutputPin, duty: PwmPin) -> None:
        self.fwd, self.bwd, self.duty = fwd, bwd, duty
        self._direction: int | None = None

    def drive(self, value: float) -> None:
        """Speed in [-1, 1]; 0 coasts."""
        v = clamp(value, -1.0, 1.0)
        direction = (v > 0) - (v < 0)
        if direction != self._direction:
            self.duty.set_duty(0.0)  # no power while the direction inputs change
            self.fwd.set(direction > 0)
            self.bwd.set(direction < 0)
            self._direction = direction
        self.duty.set_duty(abs(v))

    def brake(self) -> None:
        """Both direction inputs HIGH, enable HIGH."""
        self.fwd.set(True)
        self.bwd.set(True)
        self.duty.set_duty(1.0)
        self._direction = None

    def coast(self) -> None:
        """Everything LOW."""
        self.duty.set_duty(0.0)
        self.fwd.set(False)
        self.bwd.set(False)
        self._direction = None


class _MotorDrivetrain(Drivetrain):
    """Shared by the H-bridge drivetrains: pins, throttle limits and inversion, release on close."""

    def __init__(self, pins: PinSet, *, forward_limit: float = 1.0, reverse_limit: float = 1.0,
                 throttle_invert: bool = False, steering_invert: bool = False, **safety: Any) -> None:
        super().__init__(**safety)
        check_settings(THROTTLE_FORWARD_LIMIT=forward_limit, THROTTLE_REVERSE_LIMIT=reverse_limit)
        self.pins = pins
        self.limits = (float(forward_limit), float(reverse_limit))
        self.throttle_invert = throttle_invert
        self.steering_invert = steering_invert
        self.motors: list[HBridge2Pin | HBridge3Pin] = []

    def _limit(self, throttle: float) -> float:
        t = -throttle if self.throttle_invert else throttle
        return clamp(t, -self.limits[1], self.limits[0])

    def _steer(self, angle: float) -> float:
        return -angle if self.steering_invert else angle

    def _open_motors(self, *specs: MotorPins) -> None:
        try:
            self.motors = [spec.open(self.pins) for spec in specs]
        except BaseException:
            self.pins.close()
            raise

    def _close_hardware(self) -> None:
        try:
            for motor in self.motors:
                motor.coast()  # after the held brake: release, do not leave current in the windings
        finally:
            self.pins.close()


class ServoHBridge(_MotorDrivetrain):
    """Steering servo on a PWM pin + one drive motor on an H-bridge (SERVO_HBRIDGE_2PIN / _3PIN)."""

    def __init__(self, pins: PinSet, steering_pin: str, steering: SteeringCalibration, motor: MotorPins, *,
                 steering_scale: float = 1.0, steering_inverted: bool = False, **kwargs: Any) -> None:
        super().__init__(pins, **kwargs)
        self.steering_spec = parse_pin(steering_pin, "PWM_STEERING_PIN")
        motor.check()
        if not 0.1 <= check_number("PWM_STEERING_SCALE", steering_scale) <= 10:
            raise ValueError(f"PWM_STEERING_SCALE must be within [0.1, 10], got {steering_scale}")
        self.steering = steering
        self.motor_pins = motor
        self.scale = float(steering_scale)
        self.inverted = bool(steering_inverted)
        self.frequency = pins.pwm_frequency(self.steering_spec)
        check_pulse_widths(self.frequency, steering_pulses(steering))
        self.servo: PwmPin | None = None
        self.last: tuple[int, float] | None = None  # (steering ticks, motor command) of the last run

    @classmethod
    def from_config(cls, cfg: Any, *, bus_factory: Any = None, gpio_factory: Any = None,
                    clock: Callable[[], float] | None = None) -> ServoHBridge:
        """SERVO_HBRIDGE_2PIN / SERVO_HBRIDGE_3PIN (DRIVE_TRAIN_TYPE picks the dict)."""
        kind = cfg.DRIVE_TRAIN_TYPE
        d = drivetrain_dict(cfg, kind)
        if kind == "SERVO_HBRIDGE_3PIN":
            motor = MotorPins.from_dict(kind, d, "FWD_PIN", "BWD_PIN", "DUTY_PIN")
        else:
            motor = MotorPins.from_dict(kind, d, "FWD_DUTY_PIN", "BWD_DUTY_PIN")
        steering = SteeringCalibration(d["STEERING_LEFT_PWM"], d["STEERING_RIGHT_PWM"], cfg.STEERING_TRIM)
        return cls(pinset(cfg, bus_factory=bus_factory, gpio_factory=gpio_factory), d["PWM_STEERING_PIN"], steering,
                   motor, steering_scale=d["PWM_STEERING_SCALE"], steering_inverted=d["PWM_STEERING_INVERTED"],
                   **motor_limits(cfg), **safety_from_config(cfg, clock))

    def describe(self) -> str:
        s = self.steering
        return (f"steering servo {self.steering_spec} (L {s.left} / centre {s.neutral} / R {s.right} at "
                f"{self.frequency:.2f} Hz), drive motor {self.motor_pins}")

    def _open_hardware(self) -> None:
        try:
            self.servo = self.pins.pwm(self.steering_spec, "PWM_STEERING_PIN")
        except BaseException:
            self.pins.close()
            raise
        self._open_motors(self.motor_pins)

    def _servo(self, ticks: int) -> None:
        assert self.servo is not None
        out = MAX_TICK - ticks if self.inverted else ticks
        self.servo.set_ticks(int(out * self.scale))

    def _drive(self, angle: float, throttle: float) -> None:
        ticks = self.steering.ticks(self._steer(angle))
        self._servo(ticks)
        self.motors[0].drive(throttle)
        self.last = (ticks, throttle)

    def _neutral_outputs(self) -> None:
        self._servo(self.steering.neutral)
        self.motors[0].brake()

    def _hold_seconds(self) -> float:
        return max(self.hold_s, 2.0 / self.frequency)


class DCSteerThrottle(_MotorDrivetrain):
    """A DC steering motor + a DC drive motor, each on a 2-pin H-bridge (DC_STEER_THROTTLE).

    Angle +1 (right) drives the steering motor's RIGHT_DUTY_PIN, -1 its LEFT_DUTY_PIN; neutral
    coasts the steering motor (spring-centred) and brakes the drive motor.
    """

    def __init__(self, pins: PinSet, steering: MotorPins, drive: MotorPins, **kwargs: Any) -> None:
        super().__init__(pins, **kwargs)
        steering.check()
        drive.check()
        self.specs = (steering, drive)
        self.last: tuple[float, float] | None = None

    @classmethod
    def from_config(cls, cfg: Any, *, bus_factory: Any = None, gpio_factory: Any = None,
                    clock: Callable[[], float] | None = None) -> DCSteerThrottle:
        """DC_STEER_THROTTLE."""
        kind = "DC_STEER_THROTTLE"
        d = drivetrain_dict(cfg, kind)
        steering = MotorPins.from_dict(kind, d, "RIGHT_DUTY_PIN", "LEFT_DUTY_PIN")
        drive = MotorPins.from_dict(kind, d, "FWD_DUTY_PIN", "BWD_DUTY_PIN")
        return cls(pinset(cfg, bus_factory=bus_factory, gpio_factory=gpio_factory), steering, drive,
                   **motor_limits(cfg), **safety_from_config(cfg, clock))

    def describe(self) -> str:
        return f"steering motor {self.specs[0]}, drive motor {self.specs[1]}"

    def _open_hardware(self) -> None:
        self._open_motors(*self.specs)

    def _drive(self, angle: float, throttle: float) -> None:
        steer = self._steer(angle)
        self.motors[0].drive(steer)
        self.motors[1].drive(throttle)
        self.last = (steer, throttle)

    def _neutral_outputs(self) -> None:
        self.motors[0].coast()
        self.motors[1].brake()


class DifferentialDrive(_MotorDrivetrain):
    """Two drive motors, left and right, with arcade mixing (DC_TWO_WHEEL: 2-pin; DC_TWO_WHEEL_L298N:
    3-pin). Steering alone turns the car on the spot, so it is held at neutral with the throttle
    (before arming, under the watchdog). Neutral brakes both motors."""

    STEERING_MOVES_CAR = True

    def __init__(self, pins: PinSet, left: MotorPins, right: MotorPins, **kwargs: Any) -> None:
        super().__init__(pins, **kwargs)
        left.check()
        right.check()
        self.specs = (left, right)
        self.last: tuple[float, float] | None = None  # (left, right) of the last run

    @classmethod
    def from_config(cls, cfg: Any, *, bus_factory: Any = None, gpio_factory: Any = None,
                    clock: Callable[[], float] | None = None) -> DifferentialDrive:
        """DC_TWO_WHEEL (2-pin) / DC_TWO_WHEEL_L298N (3-pin)."""
        kind = cfg.DRIVE_TRAIN_TYPE
        d = drivetrain_dict(cfg, kind)
        if kind == "DC_TWO_WHEEL_L298N":
            sides = [MotorPins.from_dict(kind, d, f"{s}_FWD_PIN", f"{s}_BWD_PIN", f"{s}_EN_DUTY_PIN")
                     for s in ("LEFT", "RIGHT")]
        else:
            sides = [MotorPins.from_dict(kind, d, f"{s}_FWD_DUTY_PIN", f"{s}_BWD_DUTY_PIN") for s in ("LEFT", "RIGHT")]
        return cls(pinset(cfg, bus_factory=bus_factory, gpio_factory=gpio_factory), *sides,
                   **motor_limits(cfg), **safety_from_config(cfg, clock))

    def describe(self) -> str:
        return f"differential drive: left {self.specs[0]}, right {self.specs[1]}"

    def _open_hardware(self) -> None:
        self._open_motors(*self.specs)

    def _drive(self, angle: float, throttle: float) -> None:
        left, right = arcade_mix(throttle, self._steer(angle))
        self.motors[0].drive(left)
        self.motors[1].drive(right)
        self.last = (left, right)

    def _neutral_outputs(self) -> None:
        for motor in self.motors:
            motor.brake()

