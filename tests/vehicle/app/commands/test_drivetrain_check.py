"""`vehicle drivetrain check` steps the car's drivetrain through its bench script (here the MOCK
board, whose trace file records every pulse the car would have received)."""

from __future__ import annotations

from parts.actuators.fake_pca9685 import read_trace_file
from vehicle.app.cli import main

STEERING_CH, THROTTLE_CH = 1, 0


def _car(tmp_path):
    (tmp_path / "myconfig.py").write_text('DRIVE_TRAIN_TYPE = "MOCK"\nPCA9685_MOCK_TRACE = "pwm.txt"\n'
                                          "ESC_ARM_TIME_S = 0.0\n")
    return tmp_path


def test_the_bench_script_steers_drives_and_ends_in_neutral(tmp_path, capsys):
    car = _car(tmp_path)
    assert main(["drivetrain", "check", "--yes", "--seconds", "0.05", "--throttle", "0.2", "--car", str(car)]) == 0
    pulses = read_trace_file(car / "pwm.txt")
    assert pulses[STEERING_CH] == [375, 460, 290, 375]  # centre, full left, full right, centre
    assert pulses[THROTTLE_CH] == [370, 396, 370, 340, 370]  # stop, forward 0.2, stop, reverse 0.2, stop
    out = capsys.readouterr().out
    assert "steering full LEFT" in out and "done: the drivetrain is at neutral" in out


def test_nothing_moves_unless_the_wheels_are_off_the_ground(tmp_path, monkeypatch, capsys):
    car = _car(tmp_path)
    monkeypatch.setattr("builtins.input", lambda prompt: "n")
    assert main(["drivetrain", "check", "--car", str(car)]) == 1
    assert not (car / "pwm.txt").exists()
    assert "Put the car on a stand first" in capsys.readouterr().out


def test_too_much_throttle_is_refused(tmp_path, capsys):
    assert main(["drivetrain", "check", "--yes", "--throttle", "0.8", "--car", str(_car(tmp_path))]) == 2
    assert "--throttle 0.8: give 0 < throttle <= 0.5" in capsys.readouterr().err


def test_a_standard_input_without_an_answer_names_yes(tmp_path, monkeypatch, capsys):
    """Hardening item 16: stdin not a terminal (a script, `< /dev/null`): an EOFError traceback."""
    import io

    car = _car(tmp_path)
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # input() meets end of file at once
    assert main(["drivetrain", "check", "--car", str(car)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert "--yes" in err and "wheels off the ground" in err
    assert not (car / "pwm.txt").exists()


def test_a_gpio_car_without_gpio_is_one_line_and_gpio_mock_is_its_bench_mode(tmp_path, capsys, recwarn):
    """An H-bridge car on a machine without GPIO: one line saying so and how to fix it (no
    gpiozero fallback warnings); with GPIO_MOCK the same car runs the bench script on gpiozero's
    MockFactory (PWM pins) and prints what each pin would output."""
    from gpiozero.exc import PinFactoryFallback
    from test_hw_cli import _no_gpio_here

    (tmp_path / "myconfig.py").write_text('DRIVE_TRAIN_TYPE = "SERVO_HBRIDGE_2PIN"\n')
    if _no_gpio_here():
        assert main(["drivetrain", "check", "--yes", "--seconds", "0.05", "--car", str(tmp_path)]) != 0
        captured = capsys.readouterr()
        err = [line for line in captured.err.splitlines() if line.strip()]
        assert len(err) == 1 and "no GPIO here" in err[0] and "GPIO_MOCK = True" in err[0], err
        assert not [w for w in recwarn if issubclass(w.category, PinFactoryFallback)]
    (tmp_path / "myconfig.py").write_text('DRIVE_TRAIN_TYPE = "SERVO_HBRIDGE_2PIN"\nGPIO_MOCK = True\n')
    assert main(["drivetrain", "check", "--yes", "--seconds", "0.05", "--throttle", "0.2", "--car", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "GPIO_MOCK" in out
    # the defaults: FWD_DUTY_PIN BOARD18, BWD_DUTY_PIN BOARD16, servo on BOARD33 at 60 Hz (ticks / 4096)
    steps = [line for line in out.splitlines() if line.lstrip().startswith("pins:")]
    assert len(steps) == 8
    assert "BOARD18 0.20" in steps[4] and "BOARD16 0.00" in steps[4]  # forward at 0.2
    assert "BOARD18 0.00" in steps[6] and "BOARD16 0.20" in steps[6]  # reverse at 0.2
    assert f"BOARD33 {460 / 4096:.3f}" in steps[1]  # full left: STEERING_LEFT_PWM 460 ticks
    assert "done: the drivetrain is at neutral" in out
