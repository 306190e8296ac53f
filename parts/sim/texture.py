"""Top-down texture of a track: textured ground and road, painted lines, per-track lighting.

The texture is an RGB image of the ground plane at ``res`` metres per pixel; the camera renders
views of it by a perspective warp. Ground and road carry multi-scale noise so that a network
cannot recognise the road by a flat colour alone, and every track gets its own palette and light
(brightness, contrast, tint and large soft shadows) drawn from the track's seed.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import cv2
import numpy as np

from parts.sim.track import Track

logger = logging.getLogger(__name__)

#: metres of ground drawn around the road (what the camera sees beyond the road edge)
MARGIN = 3.0
#: dash pattern of the centre line, metres on / off
DASH_ON, DASH_OFF = 0.2, 0.2
#: 1/16 pixel precision for cv2 drawing
_SHIFT = 4

# ground palettes (RGB): grass, dry grass, concrete, carpet, dirt
_GROUNDS = ((70, 120, 50), (120, 130, 70), (150, 150, 140), (95, 80, 110), (140, 110, 80))


@dataclass(frozen=True)
class TrackTexture:
    """A track's texture and the mapping from ground metres to its pixels."""

    image: np.ndarray  # (H, W, 3) uint8 RGB
    res: float  # metres per pixel
    x0: float  # ground x of the left edge of column 0
    y1: float  # ground y of the top edge of row 0 (rows grow southwards)
    ground_color: tuple[int, int, int]  # mean ground colour, used beyond the texture's edge
    sky_top: tuple[int, int, int]
    sky_bottom: tuple[int, int, int]

    @property
    def world_to_pixel(self) -> np.ndarray:
        """3x3 matrix taking homogeneous ground metres (x, y, 1) to pixel (col, row, 1)."""
        r = 1.0 / self.res
        return np.array([[r, 0.0, -self.x0 * r - 0.5], [0.0, -r, self.y1 * r - 0.5], [0.0, 0.0, 1.0]])

    def to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """Ground points (N, 2) in metres → pixel coordinates (N, 2) as floats."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return np.stack([(xy[:, 0] - self.x0) / self.res - 0.5, (self.y1 - xy[:, 1]) / self.res - 0.5], 1)


def render_texture(track: Track, *, res: float = 0.01, lighting: float = 0.25,
                   margin: float = MARGIN) -> TrackTexture:
    """Draw the texture of ``track`` (deterministic for the track's seed).

    Args:
        track: the track.
        res: metres per pixel.
        lighting: strength of the per-track lighting variation (0 = neutral light).
        margin: metres of ground around the road.
    """
    if not 0.001 <= res <= 0.1:
        raise ValueError(f"texture resolution {res} m/px out of range: use 0.001 .. 0.1 (e.g. 0.01)")
    if lighting < 0:
        raise ValueError(f"lighting variation must be >= 0, got {lighting}")
    rng = np.random.default_rng([track.seed & 0xFFFFFFFF, 0x7E47])
    xmin, ymin, xmax, ymax = track.bounds(margin)
    w = int(np.ceil((xmax - xmin) / res))
    h = int(np.ceil((ymax - ymin) / res))
    tex = TrackTexture(np.empty(0), res, xmin, ymax, (0, 0, 0), (0, 0, 0), (0, 0, 0))

    ground_base = np.array(_GROUNDS[rng.integers(len(_GROUNDS))], float) * rng.uniform(0.85, 1.15, 3)
    ground = _noise_layer(rng, h, w, ground_base, grain=18.0, blotch=25.0)
    road_base = np.full(3, rng.uniform(55, 95)) + rng.uniform(-6, 6, 3)
    road = _noise_layer(rng, h, w, road_base, grain=12.0, blotch=10.0)

    def poly(line: np.ndarray) -> np.ndarray:
        return np.round(tex.to_pixels(line) * (1 << _SHIFT)).astype(np.int32).reshape(-1, 1, 2)

    def px(metres: float) -> int:
        return max(1, int(round(metres / res)))

    mask = np.zeros((h, w), np.uint8)
    cv2.polylines(mask, [poly(track.points)], True, 255, px(track.width), cv2.LINE_AA, _SHIFT)
    alpha = (mask.astype(np.float32) / 255.0)[..., None]
    img = ground * (1.0 - alpha) + road * alpha

    paint = np.zeros((h, w), np.uint8)
    edge = track.width / 2 - track.line_width / 2 - 0.01
    for side in (edge, -edge):
        cv2.polylines(paint, [poly(track.offset_line(side))], True, 255, px(track.line_width),
                      cv2.LINE_AA, _SHIFT)
    centre = np.zeros((h, w), np.uint8)
    period = DASH_ON + DASH_OFF
    on = (track.s % period) < DASH_ON
    starts = np.flatnonzero(on & ~np.roll(on, 1))
    for a in starts:
        idx = [a]
        while on[(idx[-1] + 1) % track.n] and len(idx) < track.n:
            idx.append((idx[-1] + 1) % track.n)
        cv2.polylines(centre, [poly(track.points[idx])], False, 255, px(track.line_width * 0.8),
                      cv2.LINE_AA, _SHIFT)
    white = np.array([235.0, 235.0, 230.0])
    centre_colour = white if track.lanes == 2 else np.array([230.0, 190.0, 40.0])
    for layer, colour in ((paint, white), (centre, centre_colour)):
        a = (layer.astype(np.float32) / 255.0)[..., None] * rng.uniform(0.8, 0.95)
        img = img * (1.0 - a) + colour * a

    # lighting: global brightness / contrast / tint, plus soft large-scale shadows
    brightness = 1.0 + lighting * rng.uniform(-1.0, 1.0)
    contrast = 1.0 + 0.6 * lighting * rng.uniform(-1.0, 1.0)
    tint = 1.0 + 0.3 * lighting * rng.uniform(-1.0, 1.0, 3)
    shade = 1.0 + 1.2 * lighting * _smooth_noise(rng, h, w, cells=4)
    mean = img.mean(axis=(0, 1))
    img = ((img - mean) * contrast + mean) * brightness * tint * shade[..., None]
    image = np.clip(img, 0, 255).astype(np.uint8)

    ground_colour = tuple(int(c) for c in np.clip(ground_base * brightness * tint, 0, 255))
    sky_top = np.clip(np.array([90, 140, 220]) * brightness * tint, 0, 255)
    sky_bottom = np.clip(np.array([200, 215, 235]) * brightness * tint, 0, 255)
    return TrackTexture(image, res, xmin, ymax, ground_colour,  # type: ignore[arg-type]
                        tuple(int(c) for c in sky_top), tuple(int(c) for c in sky_bottom))


def _smooth_noise(rng: np.random.Generator, h: int, w: int, cells: int) -> np.ndarray:
    """Zero-mean noise in about [-1, 1] with ``cells`` blobs across the larger side (float32 HxW)."""
    ch = max(2, int(round(cells * h / max(h, w))) + 1)
    cw = max(2, int(round(cells * w / max(h, w))) + 1)
    small = rng.uniform(-1.0, 1.0, (ch, cw)).astype(np.float32)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


def _noise_layer(rng: np.random.Generator, h: int, w: int, base: np.ndarray, grain: float,
                 blotch: float) -> np.ndarray:
    """A float32 HxWx3 surface: base colour + blotches (tens of cm) + fine grain (per pixel)."""
    layer = np.empty((h, w, 3), np.float32)
    layer[:] = base
    blotches = _smooth_noise(rng, h, w, cells=max(4, int(max(h, w) / 40)))
    layer += (blotch * blotches)[..., None]
    fine = rng.normal(0.0, grain, (h, w)).astype(np.float32)
    fine = cv2.GaussianBlur(fine, (3, 3), 0.8)
    layer += fine[..., None] * np.array([1.0, 0.95, 0.9], np.float32)
    return layer
