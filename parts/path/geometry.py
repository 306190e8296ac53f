"""Path geometry: nearest point, signed cross-track error, the point ahead, pure pursuit.

Angles are radians counter-clockwise; the cross-track error is positive when the car is left of
the path (looking along it). A steering command is DonkeyCar's: -1 = full left, +1 = full right.
"""

from __future__ import annotations

import math

import numpy as np


def _index(i: int, n: int, closed: bool) -> int:
    return i % n if closed else min(max(i, 0), n - 1)


def nearest_index(xy: np.ndarray, x: float, y: float, start: int | None = None, search_length: int | None = None,
                  closed: bool = False) -> int:
    """Index of the path point nearest to (x, y).

    With ``start`` and ``search_length`` (DonkeyCar's PATH_SEARCH_LENGTH) only the points from
    ``start`` to ``start + search_length`` (wrapping round a closed path) are searched, so the car
    keeps its place on a path that crosses itself; otherwise the whole path.
    """
    n = len(xy)
    if n == 0:
        raise ValueError("nearest_index: the path is empty")
    if start is None or search_length is None or search_length >= n:
        idx = np.arange(n)
    else:
        idx = np.arange(start, start + search_length)
        idx = idx % n if closed else idx[idx < n]
    d2 = (xy[idx, 0] - x) ** 2 + (xy[idx, 1] - y) ** 2
    return int(idx[int(np.argmin(d2))])


def cross_track_error(xy: np.ndarray, x: float, y: float, i: int, behind: int = 1, ahead: int = 1,
                      closed: bool = False) -> float:
    """Signed distance (m, left positive) from (x, y) to the line through the points ``behind``
    before and ``ahead`` after point ``i`` (DonkeyCar's PATH_LOOK_BEHIND / PATH_LOOK_AHEAD)."""
    n = len(xy)
    if n < 2:
        return float(math.hypot(x - xy[0, 0], y - xy[0, 1])) if n else 0.0
    ia, ib = _index(i - behind, n, closed), _index(i + ahead, n, closed)
    if ia == ib:  # at the end of an open path with no look-behind: its last segment
        ia, ib = max(ib - 1, 0), max(ib, 1)
    a, b = xy[ia], xy[ib]
    dx, dy = float(b[0] - a[0]), float(b[1] - a[1])
    norm = math.hypot(dx, dy)
    if norm == 0.0:
        return float(math.hypot(x - a[0], y - a[1]))
    return (dx * (y - float(a[1])) - dy * (x - float(a[0]))) / norm


def point_ahead(xy: np.ndarray, i: int, distance: float, closed: bool = False) -> tuple[float, float, bool]:
    """The point ``distance`` metres along the path after point ``i`` (interpolated), and whether
    the path ended before it (an open path: then its last point)."""
    n = len(xy)
    left = float(distance)
    j = i
    while True:
        k = j + 1
        if k >= n and not closed:
            return float(xy[-1, 0]), float(xy[-1, 1]), True
        a, b = xy[j % n], xy[k % n]
        seg = float(math.hypot(b[0] - a[0], b[1] - a[1]))
        if seg >= left and seg > 0:
            f = left / seg
            return float(a[0] + f * (b[0] - a[0])), float(a[1] + f * (b[1] - a[1])), False
        left -= seg
        j = k
        if j - i > n:  # round a closed path once: a degenerate path of one repeated point
            return float(xy[i % n, 0]), float(xy[i % n, 1]), False


def pure_pursuit(x: float, y: float, heading: float, tx: float, ty: float, wheel_base: float,
                 max_steering_angle: float) -> float:
    """Steering command in [-1, 1] that drives a car (bicycle model) at (x, y, ``heading``) on the
    circular arc through the target (tx, ty): curvature 2 sin(alpha) / L (Coulter 1992), wheel angle
    atan(curvature x wheel base), scaled by MAX_STEERING_ANGLE."""
    dx, dy = tx - x, ty - y
    dist = math.hypot(dx, dy)
    if dist < 1e-6:
        return 0.0
    alpha = math.atan2(dy, dx) - heading
    curvature = 2.0 * math.sin(alpha) / dist
    wheel = math.atan(curvature * wheel_base)  # positive = left
    return max(-1.0, min(1.0, -wheel / max_steering_angle))
