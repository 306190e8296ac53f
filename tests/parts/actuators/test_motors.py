"""H-bridge motors and the drivetrains built from them, on gpiozero's MockFactory pins: what each
motor input does is read back from the pins (duty of PWM inputs, level of digital inputs)."""

from __future__ import annotations

import pytest
from gpiozero.pins.mock import MockFactory, MockPWMPin

from parts.actuators.motors import DCSteerThrottle, DifferentialDrive, MotorPins, ServoHBridge
from parts.actuators.pins import PinSet
from parts.actuators.pwm import SteeringCalibration

# BOARD pin -> BCM GPIO on the 40-pin header
GPIO = {11: 17, 13: 27, 15: 22, 16: 23, 18: 24, 22: 25, 33: 13, 35: 19}


@pytest.fixture
def gpio():
    factory = MockFactory(pin_class=MockPWMPin)
    yield factory
    factory.close()


def level(gpio, board_pin):
    return gpio.pin(GPIO[board_pin]).state


SAFE = dict(arm_s=0.0, watchdog_s=None, sleep=lambda s: None)
TWO_PIN = MotorPins("RPI_GPIO.BOARD.18", "RPI_GPIO.BOARD.16")
THREE_PIN = MotorPins("RPI_GPIO.BOARD.18", "RPI_GPIO.BOARD.16", "RPI_GPIO.BOARD.35",
                      names=("FWD_PIN", "BWD_PIN", "DUTY_PIN"))


def test_servo_hbridge_2pin(gpio):
    part = ServoHBridge(PinSet(60, gpio_factory=gpio), "RPI_GPIO.BOARD.33", SteeringCalibration(), TWO_PIN,
                        **SAFE).open()
    assert level(gpio, 33) == 375 / 4096
    assert (level(gpio, 18), level(gpio, 16)) == (1, 1)  # neutral brakes
    part.run(0.0, 0.0)
    part.run(1.0, 0.6)
    assert level(gpio, 33) == 290 / 4096
    assert (level(gpio, 18), level(gpio, 16)) == (0.6, 0)
    part.run(0.0, -0.25)
    assert (level(gpio, 18), level(gpio, 16)) == (0, 0.25)
    part.neutral()
    assert (level(gpio, 18), level(gpio, 16)) == (1, 1)
    part.shutdown()
    assert [s.state for s in gpio.pin(GPIO[18]).states][-2:] == [1, 0]  # brake held, then released


def test_servo_hbridge_3pin(gpio):
    part = ServoHBridge(PinSet(60, gpio_factory=gpio), "RPI_GPIO.BOARD.33", SteeringCalibration(), THREE_PIN,
                        **SAFE).open()
    assert (level(gpio, 18), level(gpio, 16), level(gpio, 35)) == (1, 1, 1)  # brake: both HIGH, EN HIGH
    part.run(0.0, 0.0)
    assert (level(gpio, 18), level(gpio, 16), level(gpio, 35)) == (0, 0, 0)  # coast at zero
    part.run(0.0, 0.5)
    assert (level(gpio, 18), level(gpio, 16), level(gpio, 35)) == (1, 0, 0.5)
    part.run(0.0, -0.75)
    assert (level(gpio, 18), level(gpio, 16), level(gpio, 35)) == (0, 1, 0.75)
    # the enable went to 0 before the direction inputs changed
    assert [s.state for s in gpio.pin(GPIO[35]).states][-3:] == [0.5, 0, 0.75]
    part.shutdown()
    assert (level(gpio, 18), level(gpio, 16), level(gpio, 35)) == (0, 0, 0)


def test_dc_steer_throttle(gpio):
    steering = MotorPins("RPI_GPIO.BOARD.16", "RPI_GPIO.BOARD.18", names=("RIGHT_DUTY_PIN", "LEFT_DUTY_PIN", ""))
    drive = MotorPins("RPI_GPIO.BOARD.15", "RPI_GPIO.BOARD.13")
    part = DCSteerThrottle(PinSet(60, gpio_factory=gpio), steering, drive, **SAFE).open()
    assert (level(gpio, 16), level(gpio, 18)) == (0, 0)  # steering coasts (spring-centred)
    assert (level(gpio, 15), level(gpio, 13)) == (1, 1)  # drive brakes
    part.run(0.0, 0.0)
    part.run(0.5, 0.3)
    assert (level(gpio, 16), level(gpio, 18), level(gpio, 15), level(gpio, 13)) == (0.5, 0, 0.3, 0)
    part.run(-1.0, 0.3)
    assert (level(gpio, 16), level(gpio, 18)) == (0, 1)
    part.shutdown()


@pytest.mark.parametrize("three_pin", [False, True])
def test_differential_drive_mixes_and_brakes(gpio, three_pin):
    if three_pin:  # DC_TWO_WHEEL_L298N's default pins
        left = MotorPins("RPI_GPIO.BOARD.16", "RPI_GPIO.BOARD.18", "RPI_GPIO.BOARD.22")
        right = MotorPins("RPI_GPIO.BOARD.15", "RPI_GPIO.BOARD.13", "RPI_GPIO.BOARD.11")
    else:
        left = MotorPins("RPI_GPIO.BOARD.18", "RPI_GPIO.BOARD.16")
        right = MotorPins("RPI_GPIO.BOARD.15", "RPI_GPIO.BOARD.13")
    part = DifferentialDrive(PinSet(60, gpio_factory=gpio), left, right, **SAFE).open()
    speed = (lambda m: level(gpio, int(m.duty.split(".")[-1]))) if three_pin else \
        (lambda m: level(gpio, int(m.fwd.split(".")[-1])))
    assert (speed(left), speed(right)) == (1, 1)  # brake
    part.run(1.0, 0.8)  # before arming (a throttle held at start) steering does not spin the car either
    assert part.last == (0.0, 0.0)
    part.run(0.0, 0.0)
    part.run(0.5, 0.5)
    assert part.last == (1.0, 0.0)
    assert speed(left) == 1.0 and speed(right) == 0
    part.run(0.5, 1.0)
    assert part.last == (1.0, pytest.approx(1 / 3))
    part.run(1.0, None)  # no throttle command: no spinning on the spot either
    assert part.last == (0.0, 0.0)
    part.neutral()
    assert (speed(left), speed(right)) == (1, 1)
    part.shutdown()
    assert (speed(left), speed(right)) == (0, 0)


def test_watchdog_brakes_motors(gpio, clock):
    part = DifferentialDrive(PinSet(60, gpio_factory=gpio), MotorPins("RPI_GPIO.BOARD.18", "RPI_GPIO.BOARD.16"),
                             MotorPins("RPI_GPIO.BOARD.15", "RPI_GPIO.BOARD.13"), arm_s=0.0, watchdog_s=0.5,
                             clock=clock, sleep=lambda s: None)
    part.watchdog.start = lambda: None  # checked inline below, in the test's clock
    part.open()
    part.run(0.0, 0.0)
    part.run(0.0, 0.8)
    assert level(gpio, 18) == 0.8
    clock.advance(0.6)
    assert part.watchdog.check()
    assert (level(gpio, 18), level(gpio, 16), level(gpio, 15), level(gpio, 13)) == (1, 1, 1, 1)
    part.run(0.0, 0.8)  # throttle waits for a command at neutral again
    assert part.last == (0.0, 0.0)
    part.shutdown()


def test_bad_motor_pin_names_the_setting(gpio):
    with pytest.raises(ValueError, match="^LEFT_FWD_DUTY_PIN = 'RPI_GPIO.BOARD.99': header pin 99 is not on the"):
        DifferentialDrive(PinSet(60, gpio_factory=gpio),
                          MotorPins("RPI_GPIO.BOARD.99", "RPI_GPIO.BOARD.16",
                                    names=("LEFT_FWD_DUTY_PIN", "LEFT_BWD_DUTY_PIN", "")),
                          MotorPins("RPI_GPIO.BOARD.15", "RPI_GPIO.BOARD.13"), **SAFE).open()


@pytest.mark.parametrize("three_pin", [False, True])
def test_differential_drive_arms_only_on_a_neutral_steering_and_throttle(gpio, clock, three_pin):
    """Steering alone spins a two-wheel car: the command that arms it (right after open, right after
    the watchdog fired) must be neutral in steering too, for the whole arming time."""
    if three_pin:
        left = MotorPins("RPI_GPIO.BOARD.16", "RPI_GPIO.BOARD.18", "RPI_GPIO.BOARD.22")
        right = MotorPins("RPI_GPIO.BOARD.15", "RPI_GPIO.BOARD.13", "RPI_GPIO.BOARD.11")
        duty = lambda m: level(gpio, int(m.duty.split(".")[-1]))  # noqa: E731
    else:
        left = MotorPins("RPI_GPIO.BOARD.18", "RPI_GPIO.BOARD.16")
        right = MotorPins("RPI_GPIO.BOARD.15", "RPI_GPIO.BOARD.13")
        duty = lambda m: max(level(gpio, int(m.fwd.split(".")[-1])), level(gpio, int(m.bwd.split(".")[-1])))  # noqa: E731
    part = DifferentialDrive(PinSet(60, gpio_factory=gpio), left, right, arm_s=1.0, watchdog_s=0.5, clock=clock,
                             sleep=lambda s: None)
    part.watchdog.start = lambda: None  # checked inline, in the test's clock
    part.open()
    clock.advance(1.5)
    part.run(0.9, 0.0)  # the arming time is over, the throttle is neutral, the steering is not
    assert part.last == (0.0, 0.0) and duty(left) in (0, 1) and duty(right) in (0, 1)  # braked, not driven
    part.run(0.0, 0.0)  # neutral from here on: the arming time starts now
    clock.advance(0.5)
    part.run(0.0, 0.0)
    part.run(0.9, 0.0)
    assert part.last == (0.0, 0.0)  # not armed yet, and this steering restarts the arming time
    clock.advance(0.6)
    part.run(0.0, 0.0)
    clock.advance(0.6)
    part.run(0.9, 0.0)
    assert part.last == (0.0, 0.0)  # 0.6 s of neutral since the last steering: not yet
    part.run(0.0, 0.0)
    clock.advance(1.0)
    part.run(0.0, 0.0)
    part.run(0.9, 0.0)
    assert part.last == (0.9, -0.9)  # armed after a whole second of neutral: steering turns on the spot
    clock.advance(0.6)
    assert part.watchdog.check()  # no command for 0.6 s: neutral, disarmed
    part.run(0.9, 0.0)
    assert part.last == (0.0, 0.0)
    part.shutdown()
