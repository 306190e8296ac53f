"""Seeded random closed tracks: a smooth centre line with bounded curvature and no self-intersection.

Coordinates are metres in a right-handed ground frame (x east, y north, headings counter-clockwise
from +x). The centre line is a star-shaped closed curve ``r(θ) = R (1 + Σ a_k cos(kθ + φ_k))``
(a polar curve with r > 0 never crosses itself), stretched and rotated at random, then resampled
at equal arc length. Candidates whose curvature or clearance between distant parts of the road is
out of bounds are rejected, so every seed gives a drivable track.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

#: arc-length spacing of the centre-line samples, metres
SAMPLE_SPACING = 0.05
#: candidates tried per seed before giving up
MAX_ATTEMPTS = 400


class TrackError(VehicleError, ValueError):
    """The track parameters cannot give a valid track."""


class Projection(NamedTuple):
    """Where a point lies relative to the centre line."""

    s: float  # arc length of the nearest centre-line point, metres in [0, length)
    cte: float  # signed cross-track error, metres, positive = right of the centre line
    heading: float  # track heading at s, radians
    index: int  # index of the nearest sample


@dataclass(frozen=True)
class Track:
    """A closed track: centre-line samples at equal arc length plus road geometry."""

    seed: int
    points: np.ndarray  # (N, 2) centre line, metres
    width: float  # road width, metres
    lanes: int = 1
    line_width: float = 0.04
    heading: np.ndarray = field(init=False, repr=False)  # (N,) radians, direction of travel
    curvature: np.ndarray = field(init=False, repr=False)  # (N,) 1/m, positive = left turn
    s: np.ndarray = field(init=False, repr=False)  # (N,) arc length at each sample
    length: float = field(init=False)

    def __post_init__(self) -> None:
        pts = self.points
        seg = np.roll(pts, -1, axis=0) - pts
        seglen = np.hypot(seg[:, 0], seg[:, 1])
        heading = np.arctan2(seg[:, 1], seg[:, 0])
        # central difference of heading over two segments gives curvature at each sample
        dh = np.angle(np.exp(1j * (heading - np.roll(heading, 1))))
        curv = dh / (0.5 * (seglen + np.roll(seglen, 1)))
        object.__setattr__(self, "heading", heading)
        object.__setattr__(self, "curvature", curv)
        object.__setattr__(self, "s", np.concatenate([[0.0], np.cumsum(seglen)[:-1]]))
        object.__setattr__(self, "length", float(seglen.sum()))
        object.__setattr__(self, "_seg", seg)
        object.__setattr__(self, "_seglen2", np.maximum(seglen**2, 1e-12))

    @property
    def n(self) -> int:
        """Number of centre-line samples."""
        return len(self.points)

    @property
    def min_radius(self) -> float:
        """Tightest turn radius of the centre line, metres."""
        return float(1.0 / max(np.abs(self.curvature).max(), 1e-9))

    def curvature_ahead(self, s: float, distance: float) -> float:
        """Largest |curvature| (1/m) of the centre line from arc length ``s`` to ``distance`` m ahead."""
        n = max(1, int(distance / self.length * self.n))
        i = int(s / self.length * self.n)
        idx = (i + np.arange(n + 1)) % self.n
        return float(np.abs(self.curvature[idx]).max())

    def lane_offset(self, lane: str) -> float:
        """Lateral offset (metres, positive = left) of a lane's centre: center, left or right."""
        if lane == "center":
            return 0.0
        if lane in ("left", "right"):
            quarter = self.width / 4.0
            return quarter if lane == "left" else -quarter
        raise ValueError(f"unknown lane {lane!r}: use 'center', 'left' or 'right'")

    def project(self, xy: tuple[float, float] | np.ndarray) -> Projection:
        """Nearest point of the centre line to ``xy``: arc length, signed CTE and track heading."""
        p = np.asarray(xy, dtype=float)
        d2 = np.einsum("ij,ij->i", self.points - p, self.points - p)
        i = int(np.argmin(d2))
        best: tuple[float, int, float] | None = None
        for j in ((i - 1) % self.n, i):  # the two segments touching sample i
            a = self.points[j]
            t = float(np.clip(np.dot(p - a, self._seg[j]) / self._seglen2[j], 0.0, 1.0))
            q = a + t * self._seg[j]
            dist2 = float(np.dot(p - q, p - q))
            if best is None or dist2 < best[0]:
                best = (dist2, j, t)
        assert best is not None
        _, j, t = best
        seg = self._seg[j]
        seglen = float(np.sqrt(self._seglen2[j]))
        rel = p - self.points[j]
        # cross(seg, rel) > 0 means left of the direction of travel; CTE is positive to the right
        cte = -float(seg[0] * rel[1] - seg[1] * rel[0]) / seglen
        s = (float(self.s[j]) + t * seglen) % self.length
        return Projection(s, cte, float(self.heading[j]), i)

    def pose_at(self, s: float, offset: float = 0.0) -> tuple[float, float, float]:
        """Point ``offset`` metres left of the centre line at arc length ``s``, and its heading."""
        s = s % self.length
        j = int(np.searchsorted(self.s, s, side="right") - 1)
        t = (s - self.s[j]) / np.sqrt(self._seglen2[j])
        x, y = self.points[j] + t * self._seg[j]
        h = float(self.heading[j])
        return float(x - offset * np.sin(h)), float(y + offset * np.cos(h)), h

    def offset_line(self, offset: float) -> np.ndarray:
        """The centre line shifted ``offset`` metres to the left, (N, 2)."""
        # normals from the averaged heading of the two neighbouring segments (smooth at samples)
        h_prev = np.roll(self.heading, 1)
        mid = h_prev + 0.5 * np.angle(np.exp(1j * (self.heading - h_prev)))
        normal = np.stack([-np.sin(mid), np.cos(mid)], axis=1)
        return self.points + offset * normal

    def bounds(self, margin: float = 0.0) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the road plus ``margin`` metres."""
        lo = self.points.min(axis=0) - self.width / 2 - margin
        hi = self.points.max(axis=0) + self.width / 2 + margin
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def make_track(seed: int, *, size: float = 8.0, width: float = 0.8, min_radius: float = 1.2,
               lanes: int = 1, line_width: float = 0.04) -> Track:
    """Generate the track of ``seed``: same seed and parameters, same track.

    Args:
        seed: any integer; picks the shape.
        size: rough mean diameter of the loop in metres.
        width: road width in metres.
        min_radius: tightest allowed turn radius of the centre line in metres.
        lanes: 1 or 2.
        line_width: width of the painted lines in metres.

    Raises:
        TrackError: the parameters leave no room for a track (e.g. min_radius close to size / 2).
    """
    if not isinstance(seed, int | np.integer) or isinstance(seed, bool):
        raise TypeError(f"track seed must be an int, got {type(seed).__name__}")
    if lanes not in (1, 2):
        raise TrackError(f"lanes must be 1 or 2, got {lanes!r}")
    if width <= 0 or size <= 0 or min_radius <= 0:
        raise TrackError(f"size, width and min_radius must be > 0 (got {size}, {width}, {min_radius})")
    if min_radius < width / 2 + 0.05:
        raise TrackError(f"min_radius {min_radius} m is too tight for a {width} m road: "
                         f"use at least {width / 2 + 0.05:.2f} m")
    if min_radius > size / 2:
        raise TrackError(f"min_radius {min_radius} m does not fit a track of size {size} m: "
                         "make SIM_TRACK_SIZE larger or SIM_TRACK_MIN_RADIUS smaller")
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x7EAC])
    radius = size / 2
    for attempt in range(MAX_ATTEMPTS):
        # amplitudes shrink with failed attempts, so a smooth (eventually round) shape always fits
        wiggle = 1.0 * (1.0 - attempt / MAX_ATTEMPTS)
        pts = _candidate(rng, radius, wiggle)
        track = Track(int(seed), pts, width, lanes, line_width)
        if track.min_radius >= min_radius and _clear(track):
            logger.debug("track %d: %.1f m after %d attempts", seed, track.length, attempt + 1)
            return track
    raise TrackError(f"no valid track for seed {seed} with size {size} m, width {width} m, "
                     f"min_radius {min_radius} m: make SIM_TRACK_SIZE larger")


def track_from_points(points: np.ndarray, *, seed: int, width: float = 0.8, lanes: int = 1,
                      line_width: float = 0.04, min_radius: float | None = None) -> Track:
    """A track from your own closed centre line (``(N, 2)`` metres, in driving order).

    The points are resampled at equal arc length; ``seed`` is the number the track is known by
    (register it with :func:`parts.sim.simulator.register_track`). Checks that the road does not
    overlap itself and, when given, that no turn is tighter than ``min_radius`` metres.

    Raises:
        TrackError: too few points, overlapping road or too tight a turn.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 8:
        raise TrackError(f"a track needs an (N, 2) array of at least 8 centre-line points in metres, "
                         f"got shape {pts.shape}")
    if lanes not in (1, 2):
        raise TrackError(f"lanes must be 1 or 2, got {lanes!r}")
    if np.hypot(*(pts[0] - pts[-1])) < 1e-9:
        pts = pts[:-1]  # the loop was closed explicitly
    # smooth the corners of the given polyline (two passes of a 0.2 m moving average) so that
    # curvature is that of the intended curve, not of its vertices
    fine = _resample(pts, 0.01)
    kernel = np.ones(21) / 21
    for _ in range(2):
        padded = np.concatenate([fine[-10:], fine, fine[:10]])
        fine = np.stack([np.convolve(padded[:, k], kernel, mode="valid") for k in (0, 1)], axis=1)
    track = Track(int(seed), _resample(fine, SAMPLE_SPACING), width, lanes, line_width)
    if track.min_radius < width / 2:
        raise TrackError(f"track {seed}: a turn of radius {track.min_radius:.2f} m is tighter than half "
                         f"the road width ({width / 2:.2f} m): smooth the centre line")
    if min_radius is not None and track.min_radius < min_radius:
        raise TrackError(f"track {seed}: tightest turn {track.min_radius:.2f} m < min_radius {min_radius} m")
    if not _clear(track):
        raise TrackError(f"track {seed}: parts of the road overlap or come closer than the road width "
                         "plus 0.6 m: move them apart")
    return track


def _candidate(rng: np.random.Generator, radius: float, wiggle: float) -> np.ndarray:
    theta = np.linspace(0.0, 2 * np.pi, 4000, endpoint=False)
    r = np.ones_like(theta)
    for k in range(2, 6):
        r += wiggle * rng.uniform(0.0, 1.0) / k * np.cos(k * theta + rng.uniform(0, 2 * np.pi))
    r = np.maximum(r, 0.2)
    radius = radius * rng.uniform(0.85, 1.15)  # track lengths vary by about +-15 %
    stretch = rng.uniform(0.75, 1.3)
    rot = rng.uniform(0, 2 * np.pi)
    x = radius * r * np.cos(theta) * stretch
    y = radius * r * np.sin(theta) / stretch
    xy = np.stack([x * np.cos(rot) - y * np.sin(rot), x * np.sin(rot) + y * np.cos(rot)], axis=1)
    if rng.uniform() < 0.5:  # drive clockwise on half the tracks
        xy = xy[::-1].copy()
    return _resample(xy, SAMPLE_SPACING)


def _resample(xy: np.ndarray, spacing: float) -> np.ndarray:
    """Resample a closed polyline at (nearly) equal arc length."""
    closed = np.vstack([xy, xy[:1]])
    seglen = np.hypot(*np.diff(closed, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seglen)])
    n = max(int(round(s[-1] / spacing)), 16)
    target = np.linspace(0.0, s[-1], n, endpoint=False)
    return np.stack([np.interp(target, s, closed[:, 0]), np.interp(target, s, closed[:, 1])], axis=1)


def _clear(track: Track) -> bool:
    """Whether parts of the road that are far apart along the track are also apart in space."""
    pts = track.points[::2]
    n = len(pts)
    d = np.sqrt(((pts[:, None, :] - pts[None, :, :]) ** 2).sum(-1))
    idx = np.arange(n)
    gap = np.abs(idx[:, None] - idx[None, :])
    gap = np.minimum(gap, n - gap) * (track.length / n)  # distance along the track
    # points further apart along the track than half a turn of the tightest circle must keep
    # a full road width plus a verge between the road edges
    far = gap > np.pi * track.min_radius
    return bool(np.all(d[far] > track.width + 0.6))
