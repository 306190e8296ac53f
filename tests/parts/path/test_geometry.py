"""Path geometry with known answers: straight lines, circles, the ends of an open path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parts.path.geometry import cross_track_error, nearest_index, point_ahead, pure_pursuit

LINE = np.array([[x, 0.0] for x in np.arange(0.0, 5.01, 0.5)])  # along +x, 0.5 m apart
SQUARE = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [2, 2], [1, 2], [0, 2], [0, 1]], float)


def test_cross_track_error_is_signed_left_positive():
    i = nearest_index(LINE, 2.1, 0.3)
    assert i == 4
    assert cross_track_error(LINE, 2.1, 0.3, i) == pytest.approx(0.3)
    assert cross_track_error(LINE, 2.1, -0.2, i) == pytest.approx(-0.2)
    # at the ends of an open path the end segment is the line
    assert cross_track_error(LINE, 5.3, 0.1, nearest_index(LINE, 5.3, 0.1), behind=0) == pytest.approx(0.1)
    assert cross_track_error(LINE, -0.3, -0.1, 0) == pytest.approx(-0.1)


def test_search_window_keeps_the_place_and_wraps_round_a_lap():
    # without a window the nearest point to (0.1, 0.9) is point 7; searching from 1 for 3 points finds 1
    assert nearest_index(SQUARE, 0.1, 0.9) == 7
    assert nearest_index(SQUARE, 0.1, 0.9, start=1, search_length=3) == 1
    assert nearest_index(SQUARE, 0.1, 0.1, start=6, search_length=4, closed=True) == 0


def test_point_ahead_interpolates_along_segments_and_stops_at_an_open_end():
    assert point_ahead(SQUARE, 1, 1.5, closed=True) == pytest.approx((2.0, 0.5, False))
    assert point_ahead(SQUARE, 7, 0.25, closed=True) == pytest.approx((0.0, 0.75, False))
    assert point_ahead(LINE, 9, 2.0) == pytest.approx((5.0, 0.0, True))


def test_pure_pursuit_steers_onto_the_circle_through_the_target():
    wheel_base, max_angle = 0.26, math.radians(25)
    r = 2.0  # a target on the circle of radius 2 m to the left, tangent to the heading at the car
    theta = 0.4
    tx, ty = r * math.sin(theta), r * (1 - math.cos(theta))
    steering = pure_pursuit(0.0, 0.0, 0.0, tx, ty, wheel_base, max_angle)
    assert steering == pytest.approx(-math.atan(wheel_base / r) / max_angle, rel=1e-6)  # negative = left
    assert pure_pursuit(0, 0, 0, 1.0, 0.0, wheel_base, max_angle) == 0.0  # straight ahead
    assert pure_pursuit(0, 0, 0, 0.0, -0.1, wheel_base, max_angle) == 1.0  # hard right, clipped
