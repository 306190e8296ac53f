"""The follower: PID and pure pursuit with known geometry, speeds, its states, and no throttle
without a trustworthy pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parts.drive.speed import PIController
from parts.path.follower import PID, PathFollower
from vehicle.part_check import check_part

LINE = np.array([[x, 0.0] for x in np.arange(0.0, 5.01, 0.5)], np.float32)
SPEEDS = np.full(len(LINE), 1.0, np.float32)


def follow(f: PathFollower, x, y, heading, *, ok=True, xy=LINE, speeds=SPEEDS, version=1, recording=False,
           mode="local", speed=1.0):
    return f.run(x, y, heading, ok, xy, speeds, version, recording, mode, speed)


def test_pid_output_from_known_errors():
    pid = PID(kp=2.0, ki=0.5, kd=0.1, integral_limit=0.2)
    assert pid.update(0.1, 0.05) == pytest.approx(2.0 * 0.1 + 0.5 * 0.005)  # no derivative at first
    assert pid.update(0.2, 0.05) == pytest.approx(0.4 + 0.5 * 0.015 + 0.1 * 2.0)
    for _ in range(200):
        pid.update(1.0, 0.05)
    assert pid.integral == pytest.approx(0.2 / 0.5)  # clamped: ki * integral <= 0.2


def test_pid_alone_steers_back_to_the_line_and_the_target_is_ahead():
    f = PathFollower(0.05, pid=PID(0.5, 0, 0), look_ahead_dist=1.0, constant_throttle=0.3)
    angle, throttle, tx, ty, cte, state = follow(f, 2.0, 0.4, None)  # no heading: no pure pursuit
    assert state == "following" and throttle == 0.3
    assert cte == pytest.approx(0.4)
    assert angle == pytest.approx(0.5 * 0.4)  # left of the path: steer right (positive)
    assert (tx, ty) == pytest.approx((3.0, 0.0))


def test_pure_pursuit_plus_pid_with_a_heading():
    f = PathFollower(0.05, pid=PID(0.5, 0, 0), look_ahead_dist=1.0, wheel_base=0.26, max_steering_angle=0.436,
                     constant_throttle=0.3)
    angle, *_ = follow(f, 2.0, 0.0, math.radians(20))  # on the line, heading 20 deg to its left
    alpha = -math.radians(20)
    expected = -math.atan(2 * math.sin(alpha) / 1.0 * 0.26) / 0.436
    assert angle == pytest.approx(expected) and angle > 0  # turn right, back to the line


def test_speed_follows_the_recording_scaled_and_capped():
    pi = PIController(1.0, 0.0, 0.0, 1.0)
    f = PathFollower(0.05, speed_pi=pi, speed_scale=2.0, max_speed=1.5, constant_throttle=None)
    _, throttle, *_ = follow(f, 1.0, 0.0, 0.0, speed=1.0)
    assert pi.set_point == pytest.approx(1.5)  # 1.0 m/s x 2 capped at 1.5
    assert throttle == pytest.approx(0.5)
    slow = np.full(len(LINE), 0.0, np.float32)  # recorded standing still: PATH_MIN_SPEED keeps it going
    follow(f, 1.0, 0.0, 0.0, speeds=slow, version=2, speed=0.0)
    assert pi.set_point == pytest.approx(0.3)
    _, throttle, *_ = follow(f, 1.0, 0.0, 0.0, version=2, speed=None)
    assert throttle == 0.0  # no measured speed: no throttle


def test_states_and_a_lost_pose_gives_throttle_zero():
    f = PathFollower(0.05, constant_throttle=0.4)
    assert follow(f, 0, 0, 0, xy=np.zeros((0, 2)), version=0)[5] == "empty"
    assert follow(f, 0, 0, 0, recording=True)[5] == "recording"
    angle, throttle, tx, ty, cte, state = follow(f, 1.0, 0.1, 0.0, mode="user")
    assert (state, throttle, tx) == ("ready", 0.0, None) and cte == pytest.approx(0.1)
    assert follow(f, 1.0, 0.1, 0.0)[1] == 0.4
    angle, throttle, tx, ty, cte, state = follow(f, 1.0, 0.1, 0.0, ok=False)
    assert (state, angle, throttle, tx, cte) == ("lost", 0.0, 0.0, None, None)
    angle, throttle, *_, state = follow(f, None, None, None, ok=True)
    assert (state, throttle) == ("lost", 0.0)


def test_an_open_path_ends_with_throttle_zero_and_a_lap_goes_round():
    f = PathFollower(0.05, constant_throttle=0.4)
    assert follow(f, 4.9, 0.0, 0.0)[5] == "following"
    angle, throttle, *_, state = follow(f, 5.1, 0.0, 0.0)
    assert (state, throttle) == ("done", 0.0)
    assert follow(f, 4.0, 0.0, 0.0)[5] == "done"  # stays done ...
    follow(f, 4.0, 0.0, 0.0, mode="user")
    assert follow(f, 4.0, 0.0, 0.0)[5] == "following"  # ... until engaged again
    t = np.linspace(0, 2 * math.pi, 40, endpoint=False)
    circle = np.stack([np.cos(t), np.sin(t)], axis=1).astype(np.float32)
    lap = PathFollower(0.05, constant_throttle=0.4, look_ahead_dist=0.5)
    _, throttle, tx, ty, _, state = follow(lap, 1.0, -0.05, math.pi / 2, xy=circle, speeds=np.ones(40))
    assert state == "following" and throttle == 0.4
    assert ty > 0.3  # the target is round the start, not the end of the list


def test_follower_keeps_the_part_contract():
    check_part(PathFollower(0.05))
    check_part(PathFollower(0.05), [1.0, 0.0, 0.0, True, LINE, SPEEDS, 1, False, "local", 1.0])
