"""DonkeyCar's drivetrain settings dicts, and building drivetrains from a car's settings.

DonkeyCar configures each DRIVE_TRAIN_TYPE with a dict of pins and values (``SERVO_HBRIDGE_2PIN =
{"FWD_DUTY_PIN": "RPI_GPIO.BOARD.18", ...}``). The same dicts work here, with the same keys and
defaults (:data:`DONKEY_DICTS`); a dict in myconfig.py may name only the keys it changes (the rest
keep their defaults), and a key that is not one of the type's is refused with the dict's name.

``PWM_STEERING_THROTTLE = None`` (the default) builds the servo + ESC from the flat settings
(PCA9685_I2C_BUSNUM / _ADDR, STEERING_CHANNEL, THROTTLE_CHANNEL, STEERING_LEFT_PWM ...), which
`vehicle calibrate` writes; a DonkeyCar dict given instead wins for the keys it has.

:func:`drivetrain_problems` is the load-time check (one line naming the dict and the key).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from typing import Any

from parts.actuators.pca9685 import pulse_tick_range, pwm_timing
from parts.actuators.pins import PinSet, parse_pin
from parts.gpio import mock_factory
from vehicle.config_checks import Problem

#: DonkeyCar's defaults for each dict setting (donkeycar/templates/cfg_complete.py)
DONKEY_DICTS: dict[str, dict[str, Any]] = {
    "PWM_STEERING_THROTTLE": {
        "PWM_STEERING_PIN": "PCA9685.1:40.1", "PWM_STEERING_SCALE": 1.0, "PWM_STEERING_INVERTED": False,
        "PWM_THROTTLE_PIN": "PCA9685.1:40.0", "PWM_THROTTLE_SCALE": 1.0, "PWM_THROTTLE_INVERTED": False,
        "STEERING_LEFT_PWM": 460, "STEERING_RIGHT_PWM": 290, "THROTTLE_FORWARD_PWM": 500,
        "THROTTLE_STOPPED_PWM": 370, "THROTTLE_REVERSE_PWM": 220,
    },
    "SERVO_HBRIDGE_2PIN": {
        "FWD_DUTY_PIN": "RPI_GPIO.BOARD.18", "BWD_DUTY_PIN": "RPI_GPIO.BOARD.16",
        "PWM_STEERING_PIN": "RPI_GPIO.BOARD.33", "PWM_STEERING_SCALE": 1.0, "PWM_STEERING_INVERTED": False,
        "STEERING_LEFT_PWM": 460, "STEERING_RIGHT_PWM": 290,
    },
    "SERVO_HBRIDGE_3PIN": {
        "FWD_PIN": "RPI_GPIO.BOARD.18", "BWD_PIN": "RPI_GPIO.BOARD.16", "DUTY_PIN": "RPI_GPIO.BOARD.35",
        "PWM_STEERING_PIN": "RPI_GPIO.BOARD.33", "PWM_STEERING_SCALE": 1.0, "PWM_STEERING_INVERTED": False,
        "STEERING_LEFT_PWM": 460, "STEERING_RIGHT_PWM": 290,
    },
    "DC_STEER_THROTTLE": {
        "LEFT_DUTY_PIN": "RPI_GPIO.BOARD.18", "RIGHT_DUTY_PIN": "RPI_GPIO.BOARD.16",
        "FWD_DUTY_PIN": "RPI_GPIO.BOARD.15", "BWD_DUTY_PIN": "RPI_GPIO.BOARD.13",
    },
    "DC_TWO_WHEEL": {
        "LEFT_FWD_DUTY_PIN": "RPI_GPIO.BOARD.18", "LEFT_BWD_DUTY_PIN": "RPI_GPIO.BOARD.16",
        "RIGHT_FWD_DUTY_PIN": "RPI_GPIO.BOARD.15", "RIGHT_BWD_DUTY_PIN": "RPI_GPIO.BOARD.13",
    },
    "DC_TWO_WHEEL_L298N": {
        "LEFT_FWD_PIN": "RPI_GPIO.BOARD.16", "LEFT_BWD_PIN": "RPI_GPIO.BOARD.18",
        "LEFT_EN_DUTY_PIN": "RPI_GPIO.BOARD.22", "RIGHT_FWD_PIN": "RPI_GPIO.BOARD.15",
        "RIGHT_BWD_PIN": "RPI_GPIO.BOARD.13", "RIGHT_EN_DUTY_PIN": "RPI_GPIO.BOARD.11",
    },
}
PULSE_KEYS = ("STEERING_LEFT_PWM", "STEERING_RIGHT_PWM", "THROTTLE_FORWARD_PWM", "THROTTLE_STOPPED_PWM",
              "THROTTLE_REVERSE_PWM")
#: DRIVE_TRAIN_TYPE values that drive an ESC (arming time, reverse double-tap, slew limit apply)
ESC_TYPES = ("PWM_STEERING_THROTTLE", "MOCK", "MM1")


def flat_pwm_dict(cfg: Mapping[str, Any]) -> dict[str, Any]:
    """PWM_STEERING_THROTTLE's dict as the flat settings describe it (checked with their ranges,
    so a bad one is named, not the pin spec made from it)."""
    from vehicle.config import check_settings  # noqa: PLC0415 - the loader imports this module

    check_settings(**{k: cfg[k] for k in ("PCA9685_I2C_BUSNUM", "PCA9685_I2C_ADDR", "STEERING_CHANNEL",
                                         "THROTTLE_CHANNEL")})
    bus = 1 if cfg["PCA9685_I2C_BUSNUM"] is None else cfg["PCA9685_I2C_BUSNUM"]
    board = f"PCA9685.{bus}:{cfg['PCA9685_I2C_ADDR']:02X}"
    return {**DONKEY_DICTS["PWM_STEERING_THROTTLE"],
            "PWM_STEERING_PIN": f"{board}.{cfg['STEERING_CHANNEL']}",
            "PWM_THROTTLE_PIN": f"{board}.{cfg['THROTTLE_CHANNEL']}",
            **{key: cfg[key] for key in PULSE_KEYS}}


def drivetrain_dict(cfg: Mapping[str, Any], kind: str) -> dict[str, Any]:
    """The dict setting ``kind`` with the user's keys over the defaults (ConfigError: unknown key)."""
    from vehicle.config import ConfigError  # noqa: PLC0415 - the loader imports this module

    base = flat_pwm_dict(cfg) if kind == "PWM_STEERING_THROTTLE" else dict(DONKEY_DICTS[kind])
    given = cfg[kind] or {}
    unknown = sorted(set(given) - set(base))
    if unknown:
        raise ConfigError(f"{kind} has unknown key {unknown[0]!r}; valid keys: {', '.join(base)}")
    return {**base, **given}


def pin_keys(values: Mapping[str, Any]) -> list[str]:
    """The keys of a drivetrain dict that name pins."""
    return [key for key in values if key.endswith("_PIN")]


def drivetrain_problems(v: Mapping[str, Any]) -> Iterator[Problem]:
    """Load-time check of the dict setting DRIVE_TRAIN_TYPE uses: keys, pin specifiers, one pin per
    output, servo pulses at PWM_FREQ (a PCA9685 pin: at the frequency the chip really makes)."""
    kind = v["DRIVE_TRAIN_TYPE"]
    if kind not in DONKEY_DICTS:
        return
    try:
        values = drivetrain_dict(v, kind)
    except ValueError as exc:  # ConfigError
        yield Problem(kind, str(exc))
        return
    seen: dict[str, str] = {}
    for key in pin_keys(values):
        try:
            spec = parse_pin(values[key], f"{kind}[{key!r}]")
        except ValueError as exc:
            yield Problem(kind, str(exc))
            return
        if spec.physical in seen:  # RPI_GPIO.BOARD.33 and RPI_GPIO.BCM.13 are one pin
            yield Problem(kind, f"{kind}[{key!r}] = {values[key]!r} is the same pin as {seen[spec.physical]} "
                          f"({spec.where()}); valid: a pin of its own for every output")
            return
        seen[spec.physical] = f"{kind}[{key!r}] = {values[key]!r}"
    # PWM_STEERING_THROTTLE's pulses from the flat settings are checked (and named) by their own rule
    source = (v[kind] or {}) if kind == "PWM_STEERING_THROTTLE" else values
    pulses = [key for key in PULSE_KEYS if key in source]
    if not pulses:
        return
    steering = parse_pin(values["PWM_STEERING_PIN"])
    freq = v["PWM_FREQ"]
    real = pwm_timing(freq, v["PCA9685_OSC_HZ"])[1] if steering.provider == "PCA9685" else float(freq)
    tick_us = 1e6 / real / 4096.0
    lo, hi = pulse_tick_range(tick_us)
    for key in pulses:
        ticks = values[key]
        if isinstance(ticks, bool) or not isinstance(ticks, int) or not lo <= ticks <= hi:
            yield Problem(kind, f"{kind}[{key!r}] = {ticks!r} is not a servo pulse at PWM_FREQ = {freq} "
                          f"({real:.2f} Hz); valid: {lo} to {hi} ticks (500 to 2500 µs, found with "
                          "`vehicle calibrate`)", ("PWM_FREQ",))
            return


def pinset(cfg: Any, *, bus_factory: Any = None, gpio_factory: Any = None) -> PinSet:
    """The PinSet for the car: PWM_FREQ, PCA9685_OSC_HZ, and the given bus / GPIO factories (GPIO:
    with GPIO_MOCK the simulated pins, when none is given)."""
    if gpio_factory is None and cfg.GPIO_MOCK:
        gpio_factory = mock_factory()
    return PinSet(cfg.PWM_FREQ, osc_hz=cfg.PCA9685_OSC_HZ, bus_factory=bus_factory, gpio_factory=gpio_factory)


def safety_from_config(cfg: Any, clock: Callable[[], float] | None) -> dict[str, Any]:
    """The Drivetrain safety arguments from the car's settings; ESC settings for ESC drivetrains."""
    from parts.actuators.esc import ReverseStateMachine  # noqa: PLC0415

    common: dict[str, Any] = {"watchdog_s": cfg.ACTUATOR_WATCHDOG_S, "hold_s": cfg.PWM_SHUTDOWN_HOLD_S,
                              "clock": clock or time.monotonic, "slew_rate": cfg.THROTTLE_SLEW_RATE}
    if cfg.DRIVE_TRAIN_TYPE in ESC_TYPES:
        common["arm_s"] = cfg.ESC_ARM_TIME_S
        common["reverse"] = ReverseStateMachine(cfg.ESC_REVERSE_MODE, cfg.ESC_REVERSE_BRAKE_S,
                                                cfg.ESC_REVERSE_NEUTRAL_S)
    else:
        common["arm_s"] = 0.0  # an H-bridge or a VESC needs no arming (it still waits for neutral)
    return common


def motor_limits(cfg: Any) -> dict[str, Any]:
    """Throttle limits and inversions of the H-bridge drivetrains."""
    return {"forward_limit": cfg.THROTTLE_FORWARD_LIMIT, "reverse_limit": cfg.THROTTLE_REVERSE_LIMIT,
            "throttle_invert": cfg.THROTTLE_INVERT, "steering_invert": cfg.STEERING_INVERT}
