"""Steering/throttle mapping (DonkeyCar's numbers) and the drivetrain part on the register model."""

from __future__ import annotations

import math
import time

import pytest

from parts.actuators.esc import ReverseStateMachine
from parts.actuators.fake_pca9685 import OFF
from parts.actuators.pwm import SteeringCalibration, ThrottleCalibration, map_range

STEERING_CH, THROTTLE_CH = 1, 0  # as in conftest.make_drivetrain


def test_map_range_floors_like_donkeycar():
    assert map_range(0.01, -1, 1, 460, 290) == 374
    assert map_range(-0.01, -1, 0, 220, 370) == 368


@pytest.mark.parametrize(("angle", "ticks"), [(-1, 460), (-0.5, 417), (0, 375), (0.01, 374), (0.5, 332),
                                              (1, 290), (1.5, 290), (-7, 460)])
def test_steering_table(angle, ticks):
    assert SteeringCalibration(460, 290).ticks(angle) == ticks


@pytest.mark.parametrize(("throttle", "ticks"), [(-1, 220), (-0.5, 295), (-0.01, 368), (0, 370), (0.01, 371),
                                                 (0.5, 435), (1, 500), (3, 500)])
def test_throttle_table(throttle, ticks):
    assert ThrottleCalibration(500, 370, 220).ticks(throttle) == ticks


def test_trim_invert_and_limits():
    assert SteeringCalibration(460, 290, trim=0.1).neutral == 366
    assert SteeringCalibration(460, 290, trim=0.1).ticks(1.0) == 290  # still clamped to the end
    assert SteeringCalibration(460, 290, invert=True).ticks(-1.0) == 290
    limited = ThrottleCalibration(500, 370, 220, forward_limit=0.5, reverse_limit=0.25)
    assert limited.ticks(1.0) == 435 and limited.ticks(-1.0) == 332
    assert ThrottleCalibration(500, 370, 220, invert=True).ticks(1.0) == 220
    # reversed wiring: forward below stopped is valid too
    assert ThrottleCalibration(220, 370, 500).ticks(1.0) == 220


@pytest.mark.parametrize(("make", "message"), [
    (lambda: SteeringCalibration(400, 400), "both 400"),
    (lambda: SteeringCalibration(5000, 290), "STEERING_LEFT_PWM must be a pulse in ticks"),
    (lambda: SteeringCalibration(460, 290, trim=0.8), "STEERING_TRIM"),
    (lambda: ThrottleCalibration(500, 520, 220),
     "THROTTLE_STOPPED_PWM = 520 must be the ESC.s neutral; valid: a pulse strictly between"),
    (lambda: ThrottleCalibration(500, 370, 220, forward_limit=1.5), "THROTTLE_FORWARD_LIMIT"),
    (lambda: ThrottleCalibration(500.0, 370, 220), "THROTTLE_FORWARD_PWM"),
])
def test_bad_calibrations_say_which_setting(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_constructor_does_no_io_and_run_opens_lazily(make_drivetrain, board):
    part = make_drivetrain()
    assert board.trace == []
    part.run(0.0, 0.0)
    assert board.prescale == 101
    assert board.output(STEERING_CH) == 375 and board.output(THROTTLE_CH) == 370


def test_donkeycar_default_pulses_on_the_register_model(make_drivetrain, board):
    part = make_drivetrain().open()
    seen = {}
    for angle, throttle in [(-1, 0), (0, 0), (1, 0), (0, -1), (0, 0), (0, 1)]:
        part.run(angle, throttle)
        seen[(angle, throttle)] = (board.output(STEERING_CH), board.output(THROTTLE_CH))
    assert [seen[(a, 0)][0] for a in (-1, 0, 1)] == [460, 375, 290]
    assert [seen[(0, t)][1] for t in (-1, 0, 1)] == [220, 370, 500]
    assert board.prescale == 101 and board.violations == []


def test_open_writes_neutral_first(make_drivetrain, board):
    make_drivetrain().open()
    assert board.pulses(STEERING_CH) == [OFF, 375] and board.pulses(THROTTLE_CH) == [OFF, 370]


def test_arming_sends_only_neutral_and_waits_for_a_neutral_command(make_drivetrain, board, clock):
    part = make_drivetrain(arm_s=1.5).open()
    for _ in range(10):  # throttle held from the start
        part.run(0.0, 1.0)
        clock.advance(0.2)
    assert board.pulses(THROTTLE_CH) == [OFF, 370]  # never a full-throttle pulse to arm
    part.run(0.0, 0.0)
    part.run(0.0, 0.5)
    assert board.pulses(THROTTLE_CH) == [OFF, 370, 435]


def test_unchanged_commands_are_not_rewritten(make_drivetrain, board):
    part = make_drivetrain().open()
    n = len(board.trace)
    part.run(0.0, 0.0)
    part.run(0.0, 0.0)
    assert len(board.trace) == n


def test_none_and_nan_mean_neutral(make_drivetrain, board):
    part = make_drivetrain().open()
    part.run(0.5, 0.5)
    part.run(None, math.nan)
    assert board.output(STEERING_CH) == 375 and board.output(THROTTLE_CH) == 370
    with pytest.raises(TypeError):
        SteeringCalibration(460, 290, trim="0.1")


def test_numpy_commands_work_and_strings_are_wiring_errors(make_drivetrain, board):
    np = pytest.importorskip("numpy")
    part = make_drivetrain().open()
    part.run(np.float32(0.0), np.float32(0.0))
    part.run(np.float32(-1.0), np.float64(1.0))
    assert board.output(STEERING_CH) == 460 and board.output(THROTTLE_CH) == 500
    with pytest.raises(TypeError, match="must be numbers in \\[-1, 1\\] or None, got str"):
        part.run("0.5", 0.0)


def test_slew_limit_ramps_up_and_releases_at_once(make_drivetrain, board, clock):
    part = make_drivetrain(slew_rate=2.0).open()
    part.run(0.0, 0.0)  # arm
    for _ in range(6):
        part.run(0.0, 1.0)
        clock.advance(0.125)  # binary fractions: no rounding noise in the expected ticks
    part.run(0.0, 0.0)
    assert board.pulses(THROTTLE_CH) == [OFF, 370, 402, 435, 467, 500, 370]


def test_double_tap_reverse_on_the_board(make_drivetrain, board, clock):
    part = make_drivetrain(reverse=ReverseStateMachine("double_tap", 0.125, 0.125)).open()
    part.run(0.0, 0.0)  # arm
    part.run(0.0, 0.5)
    for _ in range(6):
        part.run(0.0, -1.0)
        clock.advance(0.0625)
    assert board.pulses(THROTTLE_CH) == [OFF, 370, 435, 220, 370, 220]


def test_watchdog_timeout_goes_neutral_and_needs_neutral_to_rearm(make_drivetrain, board, clock):
    part = make_drivetrain(watchdog_s=0.5)
    part.open()
    part.watchdog.shutdown()  # drive the watchdog by hand in simulated time
    part.run(0.3, 0.0)  # arm
    part.run(0.3, 0.8)
    clock.advance(0.4)
    assert part.watchdog.check() is False
    clock.advance(0.2)
    assert part.watchdog.check() is True
    assert board.output(STEERING_CH) == 375 and board.output(THROTTLE_CH) == 370
    part.run(0.3, 0.8)  # commands are back, but the throttle was not released yet
    assert board.output(THROTTLE_CH) == 370 and board.output(STEERING_CH) != 375
    part.run(0.3, 0.0)
    part.run(0.3, 0.8)
    assert board.output(THROTTLE_CH) == 474


def test_watchdog_thread_fires_when_the_loop_stalls(make_drivetrain, board):
    part = make_drivetrain(watchdog_s=0.05, clock=time.monotonic).open()
    part.run(0.0, 0.0)  # arm
    part.run(0.0, 0.6)
    assert board.output(THROTTLE_CH) == 448
    deadline = time.monotonic() + 5.0
    while board.output(THROTTLE_CH) != 370 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert board.pulses(THROTTLE_CH)[-1] == 370
    assert part.watchdog.trips == 1


def test_neutral_and_shutdown_hold_two_periods(i2c, board, make_drivetrain):
    slept = []
    part = make_drivetrain(hold_s=0.0, sleep=slept.append).open()
    part.run(-1.0, 0.0)
    part.run(-1.0, 1.0)
    part.neutral()
    assert board.output(STEERING_CH) == 375 and board.output(THROTTLE_CH) == 370
    part.run(-1.0, 1.0)  # neutral() disarmed: the throttle waits for a neutral command
    assert board.output(THROTTLE_CH) == 370
    part.shutdown()
    assert slept == [pytest.approx(2 / board.frequency())]
    assert board.pulses(THROTTLE_CH)[-1] == 370 and board.pulses(STEERING_CH)[-1] == 375
    assert i2c.opened[-1].closed
    part.run(1.0, 1.0)  # after shutdown nothing is written
    assert board.pulses(THROTTLE_CH)[-1] == 370


def test_full_off_after_the_neutral_hold(make_drivetrain, board):
    part = make_drivetrain(full_off_on_shutdown=True).open()
    part.run(0.0, 0.0)
    part.run(0.0, 0.5)
    part.shutdown()
    assert board.pulses(THROTTLE_CH)[-2:] == [370, OFF]
    assert board.pulses(STEERING_CH)[-2:] == [375, OFF]


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"arm_s": -1}, "ESC_ARM_TIME_S"),
    ({"watchdog_s": -0.1}, "ACTUATOR_WATCHDOG_S"),
    ({"slew_rate": 0}, "THROTTLE_SLEW_RATE"),
])
def test_bad_part_settings(make_drivetrain, kwargs, message):
    with pytest.raises(ValueError, match=message):
        make_drivetrain(**kwargs)


def test_pulses_outside_what_servos_take_are_refused_at_the_frequency(make_drivetrain):
    # issue 21: THROTTLE_FORWARD_PWM = 4000 at 60 Hz is a 16 ms pulse (throttle 0.4 sent 1,822 ticks)
    with pytest.raises(ValueError, match=r"THROTTLE_FORWARD_PWM = 4000 is a 16320 µs pulse at 59.84 Hz; "
                                         r"valid: 123 to 612 ticks"):
        make_drivetrain(throttle=ThrottleCalibration(4000, 370, 220))
    with pytest.raises(ValueError, match="STEERING_RIGHT_PWM = 100 is a 408 µs pulse"):
        make_drivetrain(steering=SteeringCalibration(460, 100))
    part = make_drivetrain(throttle=ThrottleCalibration(612, 370, 123))  # the edges are valid
    assert part.throttle.forward == 612


def test_an_off_watchdog_is_said_at_start(make_drivetrain, caplog):
    import logging

    with caplog.at_level(logging.WARNING):
        make_drivetrain(watchdog_s=0.5).open()
    assert "watchdog" not in caplog.text
    with caplog.at_level(logging.WARNING):
        make_drivetrain(watchdog_s=None).open()
    assert "ACTUATOR_WATCHDOG_S = None" in caplog.text and "stall" in caplog.text
