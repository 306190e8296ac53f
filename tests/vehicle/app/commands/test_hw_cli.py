"""`vehicle hw check` against fake devices on ptys; `vehicle hw tune-speed --sim`."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[3] / "parts" / "sensors"))
from sensor_fakes import ArduinoEncoder, NmeaSource, RPLidarDevice, gga  # noqa: E402

from vehicle.app.cli import main  # noqa: E402


def test_hw_check_says_what_each_device_sees(tmp_path, capsys):
    encoder, gps, lidar = ArduinoEncoder(), NmeaSource(), RPLidarDevice(lambda a: 0.8 if 80 <= a < 100 else 0.0)
    try:
        gps.sentences = [gga(48.1, 11.5, hdop=1.0)]
        (tmp_path / "myconfig.py").write_text(
            f"HAVE_ODOM = True\nENCODER_TYPE = 'arduino'\nODOM_SERIAL = {encoder.path!r}\nMM_PER_TICK = 10.0\n"
            f"HAVE_GPS = True\nGPS_SERIAL = {gps.path!r}\nUSE_LIDAR = True\nLIDAR_SERIAL = {lidar.path!r}\n")
        encoder.step = 7
        assert main(["hw", "check", "--car", str(tmp_path)]) == 0
        out = capsys.readouterr().out.splitlines()
        assert out[0].startswith(f"odom   arduino on {encoder.path}: ticks ") and "MM_PER_TICK 10" in out[0]
        assert out[1].startswith(f"gps    NMEA on {gps.path}: fix 48.1000000, 11.5000000 (±5.0 m)")
        # a return 0.8 m away at the LiDAR's 80-100 degrees clockwise: the car's right, 260-280 ccw
        assert out[2].startswith(f"lidar  RP on {lidar.path}: 360 bins, 20 with a return, nearest 0.80 m at 2")
        gps.sentences = []
        assert main(["hw", "check", "--car", str(tmp_path), "--only", "gps", "--timeout", "0.5"]) == 1
        assert "no NMEA sentences" in capsys.readouterr().out
    finally:
        for device in (encoder, gps, lidar):
            device.close()


def test_hw_check_names_a_missing_device_and_an_empty_car(tmp_path, capsys):
    (tmp_path / "myconfig.py").write_text("HAVE_ODOM = True\nENCODER_TYPE = 'ARDUINO'\nODOM_SERIAL = '/dev/ttyNOPE9'\n")
    assert main(["hw", "check", "--car", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "/dev/ttyNOPE9" in out and "ODOM_SERIAL" in out
    (tmp_path / "myconfig.py").write_text("")
    assert main(["hw", "check", "--car", str(tmp_path)]) == 1
    assert "no sensor to check" in capsys.readouterr().out


def test_tune_speed_in_the_simulator_prints_and_saves_gains(tmp_path, capsys):
    (tmp_path / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\n")
    assert main(["hw", "tune-speed", "--sim", "--car", str(tmp_path), "--save"]) == 0
    out = capsys.readouterr().out
    assert "K 3.7" in out  # the simulated car: (4 x 0.3 - 0.3) / 0.8 / 0.3 = 3.75 m/s per throttle
    text = (tmp_path / "myconfig.py").read_text()
    assert "PILOT_SPEED_KP = " in text and "PILOT_SPEED_KI = " in text


def test_hw_check_reads_the_imu(tmp_path, capsys, monkeypatch):
    import smbus2
    from sensor_fakes import FakeSMBus, MPU6050Model

    model = MPU6050Model(0x71)
    model.accel_g, model.gyro_dps, model.temp_raw = (0.0, 0.0, 1.0), (0.0, 0.0, 5.73), 0
    monkeypatch.setattr(smbus2, "SMBus", lambda bus: FakeSMBus({0x69: model}))  # the chip on the I2C bus
    (tmp_path / "myconfig.py").write_text("HAVE_IMU = True\nIMU_SENSOR = 'mpu9250'\nIMU_ADDRESS = 0x69\n")
    assert main(["hw", "check", "--car", str(tmp_path)]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("imu    mpu9250 at bus 1 0x69: acc (0.00, 0.00, 9.81) m/s^2 |a| 9.81, "
                           "gyro (0.000, 0.000, 0.100)")  # 5.73 degrees/s
    assert line.endswith("20.9 °C")  # MPU9250: (0 - 21) / 333.87 + 21


def test_tune_speed_on_a_real_car_path_mock_drivetrain_and_a_serial_encoder(tmp_path, capsys):
    encoder = ArduinoEncoder()
    try:
        encoder.step = 3  # the wheel turns: about 150 ticks/s
        (tmp_path / "myconfig.py").write_text(
            f"DRIVE_TRAIN_TYPE = 'MOCK'\nESC_ARM_TIME_S = 0.0\nHAVE_ODOM = True\nENCODER_TYPE = 'ARDUINO'\n"
            f"ODOM_SERIAL = {encoder.path!r}\nMM_PER_TICK = 10.0\nODOM_SMOOTHING = 5\n")
        assert main(["hw", "tune-speed", "--car", str(tmp_path), "--duration", "1.5",
                     "--distance", "100"]) == 0  # 1.5 m/s for 1.5 s: time, not distance, ends it
    finally:
        encoder.close()
    out = capsys.readouterr().out
    assert "(time reached)" in out and "PILOT_SPEED_KP = " in out
    assert b"p\n" in encoder.received  # the speed came from the encoder's answers


def test_hw_check_says_one_line_per_missing_device_and_tracebacks_only_with_debug(tmp_path):
    import subprocess

    (tmp_path / "myconfig.py").write_text(
        "HAVE_ODOM = True\nENCODER_TYPE = 'GPIO'\nODOM_PIN = 13\n"  # no GPIO here: one line, no warnings
        "HAVE_IMU = True\nIMU_I2C_BUSNUM = 9\nHAVE_GPS = True\nGPS_SERIAL = '/dev/ttyNOPE7'\n"
        "USE_LIDAR = True\nLIDAR_SERIAL = '/dev/ttyNOPE8'\n")
    cmd = [sys.executable, "-m", "vehicle.app.cli", "hw", "check", "--car", str(tmp_path), "--timeout", "0.5"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    lines = (run.stdout + run.stderr).splitlines()
    assert run.returncode == 1
    assert [line.split()[0] for line in lines] == ["odom", "imu", "gps", "lidar"], lines
    assert "/dev/ttyNOPE7" in lines[2] and "GPS_SERIAL" in lines[2] and "LIDAR_SERIAL" in lines[3]
    debug = subprocess.run([*cmd, "--debug"], capture_output=True, text=True, timeout=120)
    assert debug.returncode == 1 and debug.stderr.count("Traceback (most recent call last)") >= 3


def _no_gpio_here() -> bool:
    """This machine has no GPIO backend gpiozero can use (the tests' machines; not a Pi)."""
    import warnings

    from gpiozero import Device
    from gpiozero.exc import BadPinFactory
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            Device._default_pin_factory().close()
        except (BadPinFactory, ImportError):
            return True
    return False


def test_hw_check_of_a_gpio_encoder_without_gpio_is_one_line(tmp_path, capsys, recwarn):
    import pytest
    from gpiozero.exc import PinFactoryFallback

    if not _no_gpio_here():
        pytest.skip("this machine has GPIO")
    (tmp_path / "myconfig.py").write_text("HAVE_ODOM = True\nENCODER_TYPE = 'GPIO'\nODOM_PIN = 13\n")
    assert main(["hw", "check", "--car", str(tmp_path)]) == 1
    captured = capsys.readouterr()
    lines = [line for line in (captured.out + captured.err).splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert "ODOM_PIN = 13" in lines[0] and "no GPIO here" in lines[0] and "GPIO_MOCK = True" in lines[0]
    assert not [w for w in recwarn if issubclass(w.category, PinFactoryFallback)]
