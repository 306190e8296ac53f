from __future__ import annotations

import math

import numpy as np
import pytest

from parts.sim.track import Track, TrackError, make_track


@pytest.mark.parametrize("seed", [0, 1, 7, 123, 99999])
def test_track_is_closed_smooth_and_simple(seed):
    t = make_track(seed, size=8.0, width=0.8, min_radius=1.2)
    # closed: the last sample is one spacing away from the first
    gap = np.hypot(*(t.points[0] - t.points[-1]))
    assert gap == pytest.approx(t.length / t.n, rel=0.05)
    assert t.min_radius >= 1.2
    # no self-intersection of the road: samples far apart along the track are > road width apart
    d = np.hypot(*(t.points[:, None, :] - t.points[None, :, :]).transpose(2, 0, 1))
    idx = np.arange(t.n)
    along = np.minimum(abs(idx[:, None] - idx[None]), t.n - abs(idx[:, None] - idx[None])) * t.length / t.n
    assert d[along > 2 * math.pi * 1.2].min() > 0.8
    # headings are continuous: no kink bigger than what the curvature bound allows
    dh = np.abs(np.angle(np.exp(1j * np.diff(np.append(t.heading, t.heading[0])))))
    assert dh.max() < (t.length / t.n) / 1.2 * 1.5
    assert 15.0 < t.length < 45.0


def test_same_seed_same_track_other_seed_other_track():
    a, b, c = make_track(5), make_track(5), make_track(6)
    np.testing.assert_array_equal(a.points, b.points)
    assert a.points.shape != c.points.shape or not np.allclose(a.points, c.points)


def test_project_gives_signed_cte_and_arc_length():
    t = make_track(3)
    x, y, h = t.pose_at(5.0)
    left = (x - 0.2 * math.sin(h), y + 0.2 * math.cos(h))
    right = (x + 0.3 * math.sin(h), y - 0.3 * math.cos(h))
    pl, pr = t.project(left), t.project(right)
    assert pl.cte == pytest.approx(-0.2, abs=1e-3)  # left of the centre line is negative
    assert pr.cte == pytest.approx(0.3, abs=1e-3)
    assert pl.s == pytest.approx(5.0, abs=0.02)
    assert pl.heading == pytest.approx(h, abs=0.05)
    # pose_at with an offset lands on that offset
    assert t.project(t.pose_at(12.0, 0.15)[:2]).cte == pytest.approx(-0.15, abs=1e-3)
    # arc length wraps around the loop
    assert t.pose_at(t.length + 1.0)[:2] == pytest.approx(t.pose_at(1.0)[:2])


def test_lanes_and_offset_lines():
    t = make_track(4, width=1.2, lanes=2)
    assert t.lane_offset("left") == pytest.approx(0.3)
    assert t.lane_offset("right") == pytest.approx(-0.3)
    edge = t.offset_line(0.6)
    ctes = [t.project(p).cte for p in edge[::25]]
    assert np.allclose(ctes, -0.6, atol=0.01)
    with pytest.raises(ValueError, match="unknown lane"):
        t.lane_offset("middle")


def test_bad_parameters_are_explained():
    with pytest.raises(TrackError, match="too tight"):
        make_track(1, width=2.0, min_radius=0.5)
    with pytest.raises(TrackError, match="does not fit"):
        make_track(1, size=2.0, min_radius=1.5)
    with pytest.raises(TrackError, match="lanes"):
        make_track(1, lanes=3)
    with pytest.raises(TypeError, match="seed"):
        make_track("1")  # type: ignore[arg-type]
    assert isinstance(make_track(np.int64(2)), Track)


def test_hand_made_track_from_points_can_be_registered_and_driven(cfg):
    from parts.sim.simulator import SimCar, register_track
    from parts.sim.track import track_from_points
    from parts.sim.world import _CUSTOM
    from vehicle.app.evaluate import evaluate

    theta = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    oval = np.stack([4.0 * np.cos(theta), 2.5 * np.sin(theta)], axis=1)  # 4 m x 2.5 m ellipse
    track = track_from_points(oval, seed=90001, width=0.8)
    assert track.length == pytest.approx(20.6, abs=0.2)  # ellipse perimeter
    assert track.min_radius == pytest.approx(2.5**2 / 4.0, rel=0.02)  # b^2 / a
    try:
        register_track(track)
        assert SimCar.from_config(cfg, seeds=[90001]).track is track
        r = evaluate("expert", [90001], laps=1, cfg=cfg)
        assert r["tracks"][0]["autonomy"] == 100.0 and r["tracks"][0]["track_length_m"] == pytest.approx(20.6, abs=0.2)
    finally:
        _CUSTOM.pop(90001, None)
    with pytest.raises(TrackError, match="overlap"):
        track_from_points(stadium(straight=4.0, radius=0.3), seed=1, width=0.3)  # straights 0.6 m apart
    assert track_from_points(stadium(straight=4.0, radius=1.0), seed=1, width=0.3).min_radius > 0.9
    with pytest.raises(TrackError, match="at least 8"):
        track_from_points(oval[:3], seed=1)


def stadium(straight: float, radius: float) -> np.ndarray:
    """Centre line of a stadium: two straights joined by half circles, counter-clockwise."""
    arc = np.linspace(-np.pi / 2, np.pi / 2, 40)
    xs = np.linspace(0, straight, 40, endpoint=False)
    right = np.stack([straight + radius * np.cos(arc), radius * np.sin(arc)], 1)
    top = np.stack([straight - xs, np.full_like(xs, radius)], 1)[1:]
    left = np.stack([-radius * np.cos(arc), -radius * np.sin(arc)], 1)
    bottom = np.stack([xs, np.full_like(xs, -radius)], 1)[1:]
    return np.concatenate([bottom, right, top, left])
