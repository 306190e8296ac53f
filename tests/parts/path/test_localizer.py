"""The localiser: odometry's frame and origin, GPS honest about a lost fix, the fused filter."""

from __future__ import annotations

import math

import pytest

from parts.path.localizer import Localizer, _FrameFit
from vehicle.part_check import check_part


def test_odometry_pose_in_the_frame_of_the_origin_pose_and_its_growing_uncertainty():
    loc = Localizer("odometry", odom_drift=0.02)
    assert loc.run(1.0, 2.0, math.pi / 2, None)[:3] == (0.0, 0.0, 0.0)  # the start is the origin
    x, y, h, std, ok, source = loc.run(1.0, 5.0, math.pi / 2, None)  # 3 m along the start heading
    assert (x, y, h) == pytest.approx((3.0, 0.0, 0.0))
    assert std == pytest.approx(0.06) and ok and source == "odometry"
    x, y, h, *_ = loc.run(0.0, 5.0, math.pi, "reset_origin")  # here becomes (0, 0, 0)
    assert (x, y, h) == (0.0, 0.0, 0.0)
    assert loc.run(-1.0, 5.0, math.pi, None)[:2] == pytest.approx((1.0, 0.0))
    assert loc.run(None, None, None, None) == (None, None, None, None, False, "odometry")


def test_gps_fix_lost_is_not_a_pose():
    loc = Localizer("gps", gps_heading_dist=0.5)
    names = loc.INPUTS
    assert names == ("gps/x", "gps/y", "gps/ok", "gps/accuracy", "angle", "path/command")

    def gps(x, y, ok=True, accuracy=0.3):
        return loc.run(x, y, ok, accuracy, 0.0, None)

    assert gps(10.0, 5.0)[2] is None  # no course yet: the heading is unknown
    x, y, h, std, ok, _ = gps(10.0, 6.0)
    assert (x, y) == pytest.approx((10.0, 6.0)) and h == pytest.approx(math.pi / 2) and std == 0.3 and ok
    assert gps(10.0, 6.0, ok=False)[4:] == (False, "gps")
    assert gps(None, None, ok=False)[:5] == (None, None, None, None, False)
    loc.run(10.0, 6.0, True, 0.3, 0.0, "reset_origin")
    assert gps(11.0, 6.0)[:2] == pytest.approx((1.0, 0.0))


def test_gps_pose_moves_between_fixes_on_the_steering_model():
    loc = Localizer("gps", dt=0.1, gps_heading_dist=0.5, wheel_base=0.26, max_steering_angle=0.436)
    loc.run(0.0, 0.0, True, 0.1, 0.0, None)
    loc.run(1.0, 0.0, True, 0.1, 0.0, None)  # 1 m in 0.1 s east: course 0, 10 m/s
    x, y, h, *_ = loc.run(1.0, 0.0, True, 0.1, 0.0, None)  # no new fix: carried 1 m further
    assert (x, y, h) == pytest.approx((2.0, 0.0, 0.0))
    x, y, h, *_ = loc.run(1.0, 0.0, True, 0.1, -1.0, None)  # full left: turns left
    assert h > 0 and y > 0


def test_frame_fit_recovers_rotation_and_offset():
    fit = _FrameFit()
    rot, t = 0.7, (3.0, -2.0)
    for i in range(20):
        g = (math.cos(i / 3) * 4, math.sin(i / 2) * 3)
        o = (math.cos(rot) * g[0] - math.sin(rot) * g[1] + t[0], math.sin(rot) * g[0] + math.cos(rot) * g[1] + t[1])
        fit.add(g, o)
    assert fit.transform() == pytest.approx((rot, *t))
    assert fit.spread() > 2


def _drive_circle(loc, steps, *, gps_ok, odo_drift=0.0):
    """A car on a circle of radius 3 m at 1 m/s, 20 Hz; GPS 5 Hz in a frame rotated by 1 rad and
    shifted; odometry off by ``odo_drift`` m/s along x."""
    out = None
    for k in range(steps):
        t = k * 0.05
        a = t / 3.0
        x, y = 3 * math.sin(a), 3 * (1 - math.cos(a))
        g = (math.cos(1) * x - math.sin(1) * y + 10, math.sin(1) * x + math.cos(1) * y)
        fix = gps_ok and k % 4 == 0
        gx, gy = (g if fix else loc._last_fix) if gps_ok else (None, None)
        loc._last_fix = (gx, gy)
        out = loc.run(x + odo_drift * t, y, a, gx, gy, gps_ok, 0.5, None)
    return out


def test_fused_runs_on_odometry_while_the_fix_is_lost_and_its_uncertainty_grows():
    loc = Localizer("fused", odom_drift=0.02, fit_dist=5.0)
    loc._last_fix = (None, None)
    x, y, h, std, ok, source = _drive_circle(loc, 200, gps_ok=False)  # 10 m, no fix
    assert ok and source == "fused"
    a = 199 * 0.05 / 3
    assert (x, y) == pytest.approx((3 * math.sin(a), 3 * (1 - math.cos(a))), abs=1e-6)
    assert std == pytest.approx(0.01 + 0.02 * 9.95, rel=0.01)  # 1 cm at the start, 2 % of the 9.95 m driven
    loc.max_std = 0.1
    assert _drive_circle(loc, 1, gps_ok=False)[4] is False  # beyond LOC_MAX_STD: not trusted


def test_fused_gps_corrects_odometry_that_drifts():
    loc = Localizer("fused", odom_drift=0.05, fit_dist=5.0, gps_tau=10.0)
    loc._last_fix = (None, None)
    x, y, *_ = _drive_circle(loc, 2400, gps_ok=True, odo_drift=0.01)  # 2 min: odometry 1.2 m off
    a = 2399 * 0.05 / 3
    tx, ty = 3 * math.sin(a), 3 * (1 - math.cos(a))
    assert loc.fit_ready
    error = math.hypot(x - tx, y - ty)
    print(f"fused error {error:.3f} m, odometry's 1.2 m")
    assert error < 0.3  # a quarter of odometry's error


def test_localizer_keeps_the_part_contract():
    for source in ("odometry", "gps", "fused"):
        check_part(Localizer(source))
