"""Settings of the drivetrain family (DRIVE_TRAIN_TYPE picks a row of :data:`parts.actuators.registry.DRIVETRAINS`).

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Annotated, Any, Literal

from parts.actuators.drivetrain_config import drivetrain_problems
from parts.actuators.pca9685 import PRESCALE_MAX, PRESCALE_MIN, PULSE_MIN_US, pulse_tick_range, pwm_timing
from parts.actuators.pwm import SteeringCalibration, ThrottleCalibration, check_pulse_widths
from parts.actuators.registry import DRIVETRAINS
from vehicle.config_checks import Checked, Problem, Range, Rule, number_text

#: what a pulse setting must be (:func:`_pwm_pulses` checks it against PWM_FREQ)
PULSE_VALID = ("a pulse of 500 to 2500 µs at PWM_FREQ (123 to 612 ticks at 60 Hz), found with "
               "`vehicle calibrate`")
#: what None means for ACTUATOR_WATCHDOG_S
WATCHDOG_OFF = "None switches it off (not recommended: a stalled loop then keeps the last throttle)"
#: the pulse settings, each in ticks at PWM_FREQ
PULSE_SETTINGS = ("STEERING_LEFT_PWM", "STEERING_RIGHT_PWM", "THROTTLE_FORWARD_PWM",
                  "THROTTLE_STOPPED_PWM", "THROTTLE_REVERSE_PWM")

# == Drivetrain (PCA9685) ==

# What drives the wheels (DonkeyCar's names; docs/drivetrains.md): "PWM_STEERING_THROTTLE" =
# steering servo + ESC on two PWM pins (a PCA9685 board or GPIO); "SERVO_HBRIDGE_2PIN" /
# "SERVO_HBRIDGE_3PIN" = servo + DC motor on an H-bridge; "DC_STEER_THROTTLE" = DC steering motor +
# DC drive motor; "DC_TWO_WHEEL" / "DC_TWO_WHEEL_L298N" = differential drive, two motors;
# "VESC" = VESC motor controller over serial; "MM1" = Robo HAT MM1 over serial; "MOCK" = the
# PWM_STEERING_THROTTLE code on a simulated PCA9685 (bench tests without a car).
DRIVE_TRAIN_TYPE: Annotated[str, DRIVETRAINS.choice()] = "PWM_STEERING_THROTTLE"
# 7-bit I2C address of the PCA9685 (0x40 with no address jumpers bridged; `i2cdetect -y 1`).
PCA9685_I2C_ADDR: Annotated[int, Range(0x03, 0x77, note="a 7-bit address, 0x03 to 0x77; 0x40 unless A0-A5 "
                                                      "are bridged")] = 0x40
# I2C bus number (/dev/i2c-N). None = bus 1, the header pins 3/5 on a Raspberry Pi and a Jetson Nano.
PCA9685_I2C_BUSNUM: Annotated[int | None, Range(0, 255)] = None
# Oscillator of the PCA9685 in Hz. Boards run a few % off 25 MHz; set a measured value to get exact
# pulse widths (calibrated tick values stay valid only at the same setting).
PCA9685_OSC_HZ: Annotated[int, Range(1_000_000, 50_000_000, unit="Hz")] = 25_000_000
# PWM frequency in Hz. The *_PWM values below are ticks (1/4096 of a period) at this frequency;
# DonkeyCar calibrations assume 60 Hz (prescale 101, 59.84 Hz, 4.08 µs per tick).
PWM_FREQ: Annotated[int, Checked("what the PCA9685 makes at PCA9685_OSC_HZ (24 to 1525 Hz at 25 MHz); "
                                  "servos and ESCs: 50 to 60")] = 60
# PCA9685 channel of the steering servo (DonkeyCar: 1).
STEERING_CHANNEL: Annotated[int, Range(0, 15)] = 1
# PCA9685 channel of the ESC (DonkeyCar: 0).
THROTTLE_CHANNEL: Annotated[int, Range(0, 15, note="not STEERING_CHANNEL")] = 0
# Steering pulse in ticks at full left (angle -1); the centre is the midpoint of LEFT and RIGHT.
STEERING_LEFT_PWM: Annotated[int, Checked(PULSE_VALID)] = 460
# Steering pulse in ticks at full right (angle +1).
STEERING_RIGHT_PWM: Annotated[int, Checked(PULSE_VALID)] = 290
# Throttle pulse in ticks at full forward (+1).
THROTTLE_FORWARD_PWM: Annotated[int, Checked(PULSE_VALID)] = 500
# Throttle pulse in ticks that stops the motor (0, the ESC's neutral; it beeps when armed).
THROTTLE_STOPPED_PWM: Annotated[int, Checked(PULSE_VALID)] = 370
# Throttle pulse in ticks at full reverse (-1).
THROTTLE_REVERSE_PWM: Annotated[int, Checked(PULSE_VALID)] = 220
# Added to every steering command (steering units, -0.5..0.5) to make the car run straight without
# recalibrating; positive moves the centre to the right.
STEERING_TRIM: Annotated[float, Range(-0.5, 0.5)] = 0.0
# Swap left and right (a servo mounted the other way round).
STEERING_INVERT: bool = False
# Swap forward and reverse (a motor wired the other way round).
THROTTLE_INVERT: bool = False
# Largest forward throttle the drivetrain passes on (fraction of full, 0..1), for every driver,
# human or pilot.
THROTTLE_FORWARD_LIMIT: Annotated[float, Range(0, 1)] = 1.0
# Largest reverse throttle the drivetrain passes on (fraction of full, 0..1).
THROTTLE_REVERSE_LIMIT: Annotated[float, Range(0, 1)] = 1.0
# Fastest growth of the throttle in full-scale units per second (None = no limit). Releasing the
# throttle is never delayed. 4.0 = full throttle reached in 0.25 s.
THROTTLE_SLEW_RATE: Annotated[float | None, Range(0, lo_open=True, unit="per second")] = None
# Seconds of neutral sent to the ESC at start so it arms (beeps); throttle commands pass only after
# this and after the throttle has been at neutral once.
ESC_ARM_TIME_S: Annotated[float, Range(0, 10, unit="s")] = 1.5
# How a negative throttle reaches the ESC: "direct" passes it on (crawler ESCs, or when the drive
# logic's throttle filter already does the double-tap); "double_tap" sends brake, neutral, then
# reverse, as forward/brake/reverse car ESCs need to back up.
ESC_REVERSE_MODE: Literal["direct", "double_tap"] = "direct"
# double_tap: seconds of the first (braking) reverse pulse.
ESC_REVERSE_BRAKE_S: Annotated[float, Range(0, 5, unit="s")] = 0.1
# double_tap: seconds of neutral after braking, before the reverse pulses that back the car up.
ESC_REVERSE_NEUTRAL_S: Annotated[float, Range(0, 5, unit="s")] = 0.1
# Command watchdog: no fresh drive command for this many seconds -> neutral (None = off). Throttle
# then stays neutral until a command at neutral arrives.
ACTUATOR_WATCHDOG_S: Annotated[float | None, Range(0, 1, lo_open=True, unit="s", note=WATCHDOG_OFF)] = 0.5
# Seconds neutral is held on shutdown before the bus is released (at least two PWM periods).
PWM_SHUTDOWN_HOLD_S: Annotated[float, Range(0, 5, unit="s")] = 0.1
# After that hold, switch both channels off (no pulses: most ESCs stop, the servo goes limp).
PWM_FULL_OFF_ON_SHUTDOWN: bool = False
# MOCK drivetrain: append every output change of the simulated board to this file
# ("<time> <channel> <ticks|off|on>" per line; relative to CAR_PATH). None = keep it in memory.
PCA9685_MOCK_TRACE: str | None = None
# Bench mode of cars with GPIO pins (RPI_GPIO / PIGPIO pins of any DRIVE_TRAIN_TYPE, a GPIO wheel
# encoder): True = every GPIO pin is simulated (gpiozero's MockFactory with PWM pins), so the car
# runs on a machine without GPIO and moves nothing; `vehicle drivetrain check` prints each pin's output.
GPIO_MOCK: bool = False

# == Drivetrains beyond the PCA9685 ==

# DonkeyCar's dict for PWM_STEERING_THROTTLE: "PWM_STEERING_PIN", "PWM_THROTTLE_PIN" (pin
# specifiers: "PCA9685.1:40.1", "RPI_GPIO.BOARD.33", "RPI_GPIO.BCM.13", "PIGPIO.BCM.13"),
# "PWM_*_SCALE" (pulse multiplier for a board not at 60 Hz), "PWM_*_INVERTED" and the five *_PWM
# pulses. None = built from PCA9685_I2C_*, STEERING_CHANNEL, THROTTLE_CHANNEL and the *_PWM settings
# above; a dict wins for the keys it names.
PWM_STEERING_THROTTLE: dict[str, Any] | None = None
# SERVO_HBRIDGE_2PIN: steering servo on PWM_STEERING_PIN, motor on two PWM pins (duty on FWD_DUTY_PIN
# forward, on BWD_DUTY_PIN reverse; both HIGH brakes). Keys not given keep these defaults.
SERVO_HBRIDGE_2PIN: dict[str, Any] = {
    "FWD_DUTY_PIN": "RPI_GPIO.BOARD.18", "BWD_DUTY_PIN": "RPI_GPIO.BOARD.16",
    "PWM_STEERING_PIN": "RPI_GPIO.BOARD.33", "PWM_STEERING_SCALE": 1.0, "PWM_STEERING_INVERTED": False,
    "STEERING_LEFT_PWM": 460, "STEERING_RIGHT_PWM": 290}
# SERVO_HBRIDGE_3PIN: steering servo, motor on an L298N-style bridge: FWD_PIN / BWD_PIN digital
# direction inputs, DUTY_PIN the PWM enable (both HIGH brakes).
SERVO_HBRIDGE_3PIN: dict[str, Any] = {
    "FWD_PIN": "RPI_GPIO.BOARD.18", "BWD_PIN": "RPI_GPIO.BOARD.16", "DUTY_PIN": "RPI_GPIO.BOARD.35",
    "PWM_STEERING_PIN": "RPI_GPIO.BOARD.33", "PWM_STEERING_SCALE": 1.0, "PWM_STEERING_INVERTED": False,
    "STEERING_LEFT_PWM": 460, "STEERING_RIGHT_PWM": 290}
# DC_STEER_THROTTLE: DC steering motor on LEFT_DUTY_PIN / RIGHT_DUTY_PIN (coasts at neutral), DC drive
# motor on FWD_DUTY_PIN / BWD_DUTY_PIN (brakes at neutral); all PWM pins.
DC_STEER_THROTTLE: dict[str, Any] = {
    "LEFT_DUTY_PIN": "RPI_GPIO.BOARD.18", "RIGHT_DUTY_PIN": "RPI_GPIO.BOARD.16",
    "FWD_DUTY_PIN": "RPI_GPIO.BOARD.15", "BWD_DUTY_PIN": "RPI_GPIO.BOARD.13"}
# DC_TWO_WHEEL: differential drive, each wheel's motor on two PWM pins; steering is mixed in
# (left = throttle + angle, right = throttle - angle).
DC_TWO_WHEEL: dict[str, Any] = {
    "LEFT_FWD_DUTY_PIN": "RPI_GPIO.BOARD.18", "LEFT_BWD_DUTY_PIN": "RPI_GPIO.BOARD.16",
    "RIGHT_FWD_DUTY_PIN": "RPI_GPIO.BOARD.15", "RIGHT_BWD_DUTY_PIN": "RPI_GPIO.BOARD.13"}
# DC_TWO_WHEEL_L298N: differential drive on an L298N: per wheel two digital direction pins and a
# PWM enable (EN_DUTY).
DC_TWO_WHEEL_L298N: dict[str, Any] = {
    "LEFT_FWD_PIN": "RPI_GPIO.BOARD.16", "LEFT_BWD_PIN": "RPI_GPIO.BOARD.18", "LEFT_EN_DUTY_PIN": "RPI_GPIO.BOARD.22",
    "RIGHT_FWD_PIN": "RPI_GPIO.BOARD.15", "RIGHT_BWD_PIN": "RPI_GPIO.BOARD.13",
    "RIGHT_EN_DUTY_PIN": "RPI_GPIO.BOARD.11"}
# VESC: serial device of the VESC (USB: /dev/ttyACM0; `ls /dev/tty*` before and after plugging in).
VESC_SERIAL_PORT: str = "/dev/ttyACM0"
# VESC: serial speed in baud (a USB VESC ignores it).
VESC_BAUDRATE: Annotated[int, Range(1200, 4_000_000, unit="baud")] = 115200
# VESC: how throttle is sent: "duty" (x VESC_MAX_SPEED_PERCENT), "current" (x VESC_MAX_CURRENT)
# or "rpm" (x VESC_MAX_ERPM, the VESC's own speed loop).
VESC_CONTROL_MODE: Literal["duty", "current", "rpm"] = "duty"
# VESC: duty cycle at full throttle (DonkeyCar's name; 0.2 = 20 %).
VESC_MAX_SPEED_PERCENT: Annotated[float, Range(0, 0.95)] = 0.2
# VESC: motor current at full throttle in "current" mode.
VESC_MAX_CURRENT: Annotated[float, Range(0, 200, unit="A")] = 10.0
# VESC: electrical RPM at full throttle in "rpm" mode (motor RPM x pole pairs).
VESC_MAX_ERPM: Annotated[float, Range(0, 200_000, unit="ERPM")] = 10000.0
# VESC: braking current at neutral (every stop path, the watchdog); 0 = release the motor (coast).
VESC_BRAKE_CURRENT: Annotated[float, Range(0, 200, unit="A")] = 5.0
# VESC: servo position = angle x VESC_STEERING_SCALE + VESC_STEERING_OFFSET (the VESC's servo
# output takes 0..1; DonkeyCar's defaults centre it at 0.5).
VESC_STEERING_SCALE: Annotated[float, Range(-1, 1)] = 0.5
# VESC: servo position at angle 0.
VESC_STEERING_OFFSET: Annotated[float, Range(0, 1)] = 0.5
# VESC: magnet poles of the motor (not pole pairs), for the measured speed.
VESC_MOTOR_POLES: Annotated[int, Range(2, 100)] = 4
# VESC: motor turns per wheel turn (spur / pinion x any other reduction). None = no measured speed;
# set it to publish enc/speed (m/s) from the VESC's RPM (with WHEEL_RADIUS, the car's geometry in
# parts/sensors/settings.py).
VESC_GEAR_RATIO: Annotated[float | None, Range(0, 1000, lo_open=True)] = None
# MM1: serial port of the Robo HAT MM1 (Pi: /dev/ttyS0; Jetson Nano: /dev/ttyTHS1).
MM1_SERIAL_PORT: str = "/dev/ttyS0"
# MM1: steering pulse in µs that drives straight (DonkeyCar's name; -1 -> 2000, +1 -> 1000 µs).
MM1_STEERING_MID: Annotated[int, Range(1000, 2000, unit="µs")] = 1500
# MM1: throttle pulse in µs at full forward.
MM1_MAX_FORWARD: Annotated[int, Range(1000, 2000, unit="µs")] = 2000
# MM1: throttle pulse in µs that stops the motor (the ESC's neutral).
MM1_STOPPED_PWM: Annotated[int, Range(1000, 2000, unit="µs")] = 1500
# MM1: throttle pulse in µs at full reverse.
MM1_MAX_REVERSE: Annotated[int, Range(1000, 2000, unit="µs")] = 1000


#: the settings of each calibration, in the order of its constructor's arguments
_PULSE_ORDER: dict[type, tuple[str, ...]] = {
    SteeringCalibration: ("STEERING_LEFT_PWM", "STEERING_RIGHT_PWM"),
    ThrottleCalibration: ("THROTTLE_FORWARD_PWM", "THROTTLE_STOPPED_PWM", "THROTTLE_REVERSE_PWM"),
}


def _pwm_pulses(v: Mapping[str, Any]) -> Iterator[Problem]:
    freq, osc = v["PWM_FREQ"], v["PCA9685_OSC_HZ"]
    prescale, real, tick_us = pwm_timing(freq, osc)
    if not PRESCALE_MIN <= prescale <= PRESCALE_MAX:
        low = osc / 4096.0 / (PRESCALE_MAX + 1)
        high = osc / 4096.0 / (PRESCALE_MIN + 1)
        yield Problem("PWM_FREQ", f"PWM_FREQ = {number_text(freq)} is outside what the PCA9685 can "
                      f"make with PCA9685_OSC_HZ = {number_text(osc)}; valid: {math.ceil(low)} to "
                      f"{math.floor(high)} Hz (servos and ESCs: 50 to 60)", ("PCA9685_OSC_HZ",))
        return
    lo, hi = pulse_tick_range(tick_us)
    if lo > hi:
        yield Problem("PWM_FREQ", f"PWM_FREQ = {number_text(freq)} makes a period of {1e6 / real:.0f} µs, "
                      f"too short for servo pulses of {number_text(PULSE_MIN_US)} µs and more; "
                      "valid: 50 to 60 Hz for servos and ESCs", ("PCA9685_OSC_HZ",))
        return
    # the parts' own checks (parts/actuators/pwm.py), so each rule is written once
    for name in PULSE_SETTINGS:
        try:
            check_pulse_widths(real, {name: v[name]}, asked=freq)
        except ValueError as exc:
            yield Problem(name, str(exc), ("PWM_FREQ", "PCA9685_OSC_HZ"))
            return
    for settings, build in ((("STEERING_LEFT_PWM", "STEERING_RIGHT_PWM"), SteeringCalibration),
                            (("THROTTLE_STOPPED_PWM", "THROTTLE_FORWARD_PWM", "THROTTLE_REVERSE_PWM"),
                             ThrottleCalibration)):
        try:
            build(*(v[name] for name in _PULSE_ORDER[build]))
        except ValueError as exc:
            yield Problem(settings[0], str(exc), settings[1:])


def _channels(v: Mapping[str, Any]) -> Iterator[Problem]:
    if v["STEERING_CHANNEL"] == v["THROTTLE_CHANNEL"]:
        yield Problem("THROTTLE_CHANNEL", f"STEERING_CHANNEL and THROTTLE_CHANNEL are both "
                      f"{v['THROTTLE_CHANNEL']}; valid: two different channels 0 to 15 (the servo and "
                      "the ESC each need their own)", ("STEERING_CHANNEL",))


def _watchdog(v: Mapping[str, Any]) -> Iterator[Problem]:
    watchdog, hz = v["ACTUATOR_WATCHDOG_S"], v["DRIVE_LOOP_HZ"]
    if watchdog is not None and watchdog < 2.0 / hz:
        yield Problem("ACTUATOR_WATCHDOG_S", f"ACTUATOR_WATCHDOG_S = {watchdog!r} is shorter than two "
                      f"loops at DRIVE_LOOP_HZ = {hz} ({number_text(2.0 / hz)} s): the drivetrain "
                      f"would go to neutral between commands; valid: {number_text(2.0 / hz)} to 1 s "
                      "(or a faster loop)", ("DRIVE_LOOP_HZ",))


#: rules across this module's settings, run after every setting passed its own range
RULES: tuple[Rule, ...] = (_pwm_pulses, _channels, _watchdog, drivetrain_problems)
