"""Pin specifiers and pins: PCA9685 channels on the register-level board, GPIO pins on gpiozero's
MockFactory (the pin numbers of the 40-pin header: BOARD33 is GPIO13, BOARD18 is GPIO24)."""

from __future__ import annotations

import sys

import pytest
from gpiozero.pins.mock import MockFactory, MockPWMPin

from parts.actuators.drivetrain import DrivetrainError
from parts.actuators.fake_pca9685 import OFF, ON
from parts.actuators.pins import PinSet, PinSpec, parse_pin
from parts.actuators.pwm import PWMSteeringThrottle, SteeringCalibration, ThrottleCalibration


@pytest.fixture
def gpio():
    factory = MockFactory(pin_class=MockPWMPin)
    yield factory
    factory.close()


@pytest.mark.parametrize(("text", "spec"), [
    ("PCA9685.1:40.1", PinSpec("PCA9685", 1, None, 1, 0x40)),
    ("PCA9685.0:0x41.15", PinSpec("PCA9685", 15, None, 0, 0x41)),
    ("RPI_GPIO.BOARD.33", PinSpec("RPI_GPIO", 33, "BOARD")),
    ("RPI_GPIO.BCM.13", PinSpec("RPI_GPIO", 13, "BCM")),
    ("PIGPIO.BCM.13", PinSpec("PIGPIO", 13, "BCM")),
])
def test_donkeycar_pin_specifiers_parse(text, spec):
    assert parse_pin(text) == spec


@pytest.mark.parametrize(("text", "why"), [
    ("PCA9685.1:40.16", "channel 16 is outside 0-15"),
    ("PCA9685.1.1", "PCA9685 pins are <bus>:<hex address>.<channel>"),
    ("PIGPIO.BOARD.33", "pigpio numbers pins by BCM only"),
    ("RPI_GPIO.WIRINGPI.3", "must be BOARD or BCM"),
    ("ARDUINO.BCM.3", "unknown pin provider"),
    (13, "a pin specifier is a string"),
])
def test_bad_specifiers_say_the_setting_and_the_form(text, why):
    with pytest.raises(ValueError, match=why) as info:
        parse_pin(text, "PWM_STEERING_PIN")
    assert str(info.value).startswith(f"PWM_STEERING_PIN = {text!r}: ")
    assert "RPI_GPIO.BOARD.33" in str(info.value) and "\n" not in str(info.value)


def test_pca9685_channel_outputs(i2c, board):
    pins = PinSet(60, bus_factory=i2c.smbus)
    pwm = pins.pwm("PCA9685.1:40.3")
    out = pins.output("PCA9685.1:40.4")
    pwm.set_ticks(375)
    assert board.output(3) == 375
    pwm.set_duty(0.5)
    assert board.output(3) == 2048
    pwm.set_duty(1.0)
    assert board.output(3) == ON
    out.set(True)
    assert board.output(4) == ON
    out.set(False)
    assert board.output(4) == OFF
    assert board.prescale == 101  # one board, opened once at PWM_FREQ
    assert len(pins.boards) == 1
    pins.close()
    assert all(bus.closed for bus in i2c.opened)


def test_gpio_pwm_pin_runs_at_the_frequency_with_ticks_as_duty(gpio):
    pins = PinSet(60, gpio_factory=gpio)
    pin = pins.pwm("RPI_GPIO.BOARD.33", "PWM_STEERING_PIN")
    pin.set_ticks(375)
    header = gpio.pin(13)  # BOARD 33 is GPIO13
    assert header.frequency == 60
    assert header.state == pytest.approx(375 / 4096)
    pins.close()
    assert header.state == 0 and header.frequency is None


def test_gpio_digital_pin(gpio):
    pins = PinSet(60, gpio_factory=gpio)
    out = pins.output("RPI_GPIO.BCM.5")
    out.set(True)
    assert gpio.pin(5).state == 1
    out.set(False)
    assert gpio.pin(5).state == 0
    pins.close()


def test_one_pin_twice_is_refused(gpio, i2c, board):
    pins = PinSet(60, bus_factory=i2c.smbus, gpio_factory=gpio)
    pins.pwm("PCA9685.1:40.1", "PWM_STEERING_PIN")
    with pytest.raises(ValueError, match="PWM_THROTTLE_PIN = 'PCA9685.1:40.1' is the same pin as PWM_STEERING_PIN"):
        pins.pwm("PCA9685.1:40.1", "PWM_THROTTLE_PIN")
    pins.pwm("RPI_GPIO.BOARD.33", "FWD_DUTY_PIN")
    with pytest.raises(ValueError, match=r"BWD_DUTY_PIN = 'RPI_GPIO.BCM.13' is the same pin as FWD_DUTY_PIN = "
                       r"'RPI_GPIO.BOARD.33' \(header pin 33, GPIO13\)"):
        pins.pwm("RPI_GPIO.BCM.13", "BWD_DUTY_PIN")
    with pytest.raises(ValueError, match="PWM_STEERING_PIN = 'PIGPIO.BCM.13' is the same pin as FWD_DUTY_PIN"):
        pins.pwm("PIGPIO.BCM.13", "PWM_STEERING_PIN")
    with pytest.raises(ValueError, match="DUTY_PIN = 'RPI_GPIO.BOARD.1': header pin 1 is 3.3 V power, not a GPIO"):
        pins.pwm("RPI_GPIO.BOARD.1", "DUTY_PIN")
    pins.close()


def test_servo_and_esc_on_gpio_pins(gpio):
    """PWM_STEERING_THROTTLE with RPI_GPIO pins: the same ticks as on a PCA9685, as a duty cycle."""
    part = PWMSteeringThrottle(PinSet(60, gpio_factory=gpio), "RPI_GPIO.BOARD.33", "RPI_GPIO.BCM.18",
                               SteeringCalibration(), ThrottleCalibration(), arm_s=0.0, watchdog_s=None,
                               sleep=lambda s: None).open()
    steering, esc = gpio.pin(13), gpio.pin(18)
    assert (steering.state, esc.state) == (375 / 4096, 370 / 4096)  # neutral at open
    part.run(0.0, 0.0)
    part.run(-1.0, 1.0)
    assert (steering.state, esc.state) == (460 / 4096, 500 / 4096)
    part.neutral()
    assert (steering.state, esc.state) == (375 / 4096, 370 / 4096)
    part.shutdown()
    assert [s.state for s in esc.states][-2:] == [370 / 4096, 0]  # neutral held, then released


def test_scale_and_inversion_like_donkeycar(i2c, board):
    part = PWMSteeringThrottle(PinSet(60, bus_factory=i2c.smbus), "PCA9685.1:40.1", "PCA9685.1:40.0",
                               SteeringCalibration(), ThrottleCalibration(), steering_scale=1.2,
                               throttle_inverted=True, arm_s=0.0, watchdog_s=None, sleep=lambda s: None).open()
    assert board.output(1) == int(375 * 1.2)
    assert board.output(0) == 4095 - 370
    part.shutdown()


def test_no_gpio_backend_is_one_line_naming_the_setting(monkeypatch):
    from gpiozero import Device

    monkeypatch.setenv("GPIOZERO_PIN_FACTORY", "no-such-backend")
    monkeypatch.setattr(Device, "pin_factory", None)
    with pytest.raises(DrivetrainError, match=r"^PWM_STEERING_PIN = 'RPI_GPIO.BOARD.33': no GPIO here .*python3-lgpio"):
        PinSet(60).pwm("RPI_GPIO.BOARD.33", "PWM_STEERING_PIN")
    monkeypatch.setitem(sys.modules, "pigpio", None)  # the pigpio library is not installed
    with pytest.raises(DrivetrainError, match=r"^FWD_PIN = 'PIGPIO.BCM.13': pigpio is not available .*pigpiod"):
        PinSet(60).output("PIGPIO.BCM.13", "FWD_PIN")
