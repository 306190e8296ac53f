"""DonkeyCar's drivetrain settings dicts: accepted as DonkeyCar writes them, checked when the config
loads (one line: file, line, the dict and its key), and turned into the right part."""

from __future__ import annotations

import pytest

from parts.actuators.motors import DifferentialDrive, ServoHBridge
from parts.actuators.pwm import PWMSteeringThrottle
from parts.actuators.vesc import VESC
from vehicle.app.assembly.drivetrain import build_drivetrain
from vehicle.config import Config, ConfigError, load_config


def _load(tmp_path, text: str) -> Config:
    (tmp_path / "myconfig.py").write_text(text)
    return load_config(car_path=tmp_path)


def test_a_donkeycar_pwm_dict_carries_over(tmp_path):
    cfg = _load(tmp_path, 'PWM_STEERING_THROTTLE = {\n'
                          '    "PWM_STEERING_PIN": "PCA9685.1:40.1", "PWM_STEERING_SCALE": 1.0,\n'
                          '    "PWM_STEERING_INVERTED": False, "PWM_THROTTLE_PIN": "PCA9685.1:40.0",\n'
                          '    "PWM_THROTTLE_SCALE": 1.0, "PWM_THROTTLE_INVERTED": False,\n'
                          '    "STEERING_LEFT_PWM": 455, "STEERING_RIGHT_PWM": 300, "THROTTLE_FORWARD_PWM": 490,\n'
                          '    "THROTTLE_STOPPED_PWM": 375, "THROTTLE_REVERSE_PWM": 230}\n')
    part = build_drivetrain(cfg)
    assert isinstance(part, PWMSteeringThrottle)
    assert (part.steering.left, part.steering.right, part.throttle.stopped) == (455, 300, 375)
    assert [str(s) for s in part.specs] == ["PCA9685.1:40.1", "PCA9685.1:40.0"]


def test_flat_settings_make_the_pins_when_there_is_no_dict():
    part = build_drivetrain(Config.defaults(PCA9685_I2C_BUSNUM=0, PCA9685_I2C_ADDR=0x41, STEERING_CHANNEL=3,
                                            THROTTLE_CHANNEL=4, STEERING_LEFT_PWM=450))
    assert [str(s) for s in part.specs] == ["PCA9685.0:41.3", "PCA9685.0:41.4"]
    assert part.steering.left == 450


def test_a_partial_dict_keeps_the_other_defaults():
    cfg = Config.defaults(DRIVE_TRAIN_TYPE="SERVO_HBRIDGE_3PIN", SERVO_HBRIDGE_3PIN={"DUTY_PIN": "PCA9685.1:40.2"})
    part = build_drivetrain(cfg)
    assert isinstance(part, ServoHBridge)
    assert (part.motor_pins.fwd, part.motor_pins.duty) == ("RPI_GPIO.BOARD.18", "PCA9685.1:40.2")


@pytest.mark.parametrize(("text", "message"), [
    ('DRIVE_TRAIN_TYPE = "DC_TWO_WHEEL"\nDC_TWO_WHEEL = {"LEFT_FWD_DUTY_PIN": "RPI_GPIO.BOARD.40.1"}\n',
     r"line 2: DC_TWO_WHEEL\['LEFT_FWD_DUTY_PIN'\] = 'RPI_GPIO.BOARD.40.1': expected three parts"),
    ('DRIVE_TRAIN_TYPE = "DC_TWO_WHEEL"\nDC_TWO_WHEEL = {"LEFT_FORWARD_PIN": "RPI_GPIO.BOARD.12"}\n',
     r"line 2: DC_TWO_WHEEL has unknown key 'LEFT_FORWARD_PIN'; valid keys: LEFT_FWD_DUTY_PIN"),
    ('DRIVE_TRAIN_TYPE = "DC_TWO_WHEEL_L298N"\nDC_TWO_WHEEL_L298N = {"RIGHT_EN_DUTY_PIN": "RPI_GPIO.BOARD.22"}\n',
     r"line 2: DC_TWO_WHEEL_L298N\['RIGHT_EN_DUTY_PIN'\] = 'RPI_GPIO.BOARD.22' is the same pin as "
     r"DC_TWO_WHEEL_L298N\['LEFT_EN_DUTY_PIN'\]"),
    ('PWM_STEERING_THROTTLE = {"PWM_STEERING_PIN": "RPI_GPIO.BOARD.33", "STEERING_LEFT_PWM": 1000}\n',
     r"line 1: PWM_STEERING_THROTTLE\['STEERING_LEFT_PWM'\] = 1000 is not a servo pulse at PWM_FREQ = 60 "
     r"\(60.00 Hz\); valid: 123 to 614 ticks"),
    ('DRIVE_TRAIN_TYPE = "SERVO_HBRIDGE_2PIN"\nSERVO_HBRIDGE_2PIN = {"FWD_DUTY_PIN": "RPI_GPIO.BCM.13"}\n',
     r"line 2: SERVO_HBRIDGE_2PIN\['PWM_STEERING_PIN'\] = 'RPI_GPIO.BOARD.33' is the same pin as "
     r"SERVO_HBRIDGE_2PIN\['FWD_DUTY_PIN'\] = 'RPI_GPIO.BCM.13' \(header pin 33, GPIO13\)"),
    ('DRIVE_TRAIN_TYPE = "DC_TWO_WHEEL"\nDC_TWO_WHEEL = {"LEFT_FWD_DUTY_PIN": "PIGPIO.BCM.22"}\n',
     r"line 2: DC_TWO_WHEEL\['RIGHT_FWD_DUTY_PIN'\] = 'RPI_GPIO.BOARD.15' is the same pin as "
     r"DC_TWO_WHEEL\['LEFT_FWD_DUTY_PIN'\] = 'PIGPIO.BCM.22' \(header pin 15, GPIO22\)"),
    ('DRIVE_TRAIN_TYPE = "DC_TWO_WHEEL"\nDC_TWO_WHEEL = {"LEFT_FWD_DUTY_PIN": "RPI_GPIO.BOARD.6"}\n',
     r"line 2: DC_TWO_WHEEL\['LEFT_FWD_DUTY_PIN'\] = 'RPI_GPIO.BOARD.6': header pin 6 is ground, not a GPIO"),
    ('DRIVE_TRAIN_TYPE = "VESC"\nVESC_CONTROL_MODE = "torque"\n', r"line 2: VESC_CONTROL_MODE"),
    ('DRIVE_TRAIN_TYPE = "MM1"\nMM1_MAX_FORWARD = 2100\n', r"line 2: MM1_MAX_FORWARD = 2100"),
])
def test_bad_drivetrain_settings_are_one_line_at_load(tmp_path, text, message):
    with pytest.raises(ConfigError, match=message) as info:
        _load(tmp_path, text)
    assert "\n" not in str(info.value) and "myconfig.py" in str(info.value)


def test_vesc_and_differential_drive_from_settings():
    vesc = build_drivetrain(Config.defaults(DRIVE_TRAIN_TYPE="VESC", VESC_SERIAL_PORT="/dev/ttyACM1",
                                            VESC_GEAR_RATIO=8.5, WHEEL_RADIUS=0.05))
    assert isinstance(vesc, VESC) and vesc.OUTPUTS == ("enc/speed",)
    assert (vesc.port_name, vesc.gear_ratio, vesc.wheel_radius, vesc.arm_s) == ("/dev/ttyACM1", 8.5, 0.05, 0.0)
    diff = build_drivetrain(Config.defaults(DRIVE_TRAIN_TYPE="DC_TWO_WHEEL_L298N"))
    assert isinstance(diff, DifferentialDrive) and diff.specs[1].duty == "RPI_GPIO.BOARD.11"


def test_a_bad_flat_pulse_is_named_by_its_own_name_not_the_dict(tmp_path):
    with pytest.raises(ConfigError, match=r"line 1: STEERING_LEFT_PWM = 1000 is a 4080 µs pulse at PWM_FREQ = 60"):
        _load(tmp_path, "STEERING_LEFT_PWM = 1000\n")
