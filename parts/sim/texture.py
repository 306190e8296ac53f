"""Top-down texture of a track: the ground and road materials, painted lines, light and shadows.

The texture is an RGB image of the ground plane at ``res`` metres per pixel; the camera renders
views of it by a perspective warp. What is drawn comes from the track's :class:`~parts.sim.themes.Look`
(materials, colours, line styles of its theme) and :class:`~parts.sim.randomize.Conditions`
(light level, colour temperature, contrast, soft large-scale shade, shadows cast across the track),
all baked in once per track so that they cost nothing per frame.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from parts.sim.randomize import Conditions
from parts.sim.surfaces import SURFACES, smooth_noise
from parts.sim.themes import Look, Paint
from parts.sim.track import Track

logger = logging.getLogger(__name__)

#: metres of ground drawn around the road (what the camera sees beyond the road edge; the walls of
#: the indoor theme and the park's tree line stand at its edge)
MARGIN = 3.0
#: 1/16 pixel precision for cv2 drawing
_SHIFT = 4
#: the shadow mask is drawn this many times coarser than the texture (shadows are soft anyway)
_SHADOW_SCALE = 4


@dataclass(frozen=True)
class TrackTexture:
    """A track's texture and the mapping from ground metres to its pixels."""

    image: np.ndarray  # (H, W, 3) uint8 RGB
    res: float  # metres per pixel
    x0: float  # ground x of the left edge of column 0
    y1: float  # ground y of the top edge of row 0 (rows grow southwards)
    ground_color: tuple[int, int, int]  # mean ground colour, used beyond the texture's edge
    sky_top: tuple[int, int, int]  # sky (or ceiling) colour at the top of the image
    sky_bottom: tuple[int, int, int]  # ... and at the horizon

    @property
    def world_to_pixel(self) -> np.ndarray:
        """3x3 matrix taking homogeneous ground metres (x, y, 1) to pixel (col, row, 1)."""
        r = 1.0 / self.res
        return np.array([[r, 0.0, -self.x0 * r - 0.5], [0.0, -r, self.y1 * r - 0.5], [0.0, 0.0, 1.0]])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the textured ground, metres."""
        h, w = self.image.shape[:2]
        return self.x0, self.y1 - h * self.res, self.x0 + w * self.res, self.y1

    def to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """Ground points (N, 2) in metres → pixel coordinates (N, 2) as floats."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return np.stack([(xy[:, 0] - self.x0) / self.res - 0.5, (self.y1 - xy[:, 1]) / self.res - 0.5], 1)


def texture_bounds(track: Track, margin: float = MARGIN) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of a track's texture: the road plus ``margin`` metres."""
    return track.bounds(margin)


def render_texture(track: Track, look: Look, conditions: Conditions, *, res: float = 0.01,
                   margin: float = MARGIN, ragged_edge: float = 0.0,
                   shadows: Sequence[np.ndarray] = (), shadow_blur: float = 0.03,
                   line_wear: float = 0.0) -> TrackTexture:
    """Draw the texture of ``track`` (deterministic for the track, look and conditions).

    Args:
        track: the track.
        look: materials, colours and lines (``Theme.draw_look``).
        conditions: light, contrast, shade and shadow darkness.
        res: metres per pixel.
        margin: metres of ground around the road.
        ragged_edge: metres of irregularity of the road's edge (0 = a clean edge).
        shadows: polygons (K, 2) in ground metres that lie in shadow.
        shadow_blur: metres of soft shadow edge.
        line_wear: lines fade in patches (a metre or two long) by up to this fraction.
    """
    if not 0.001 <= res <= 0.1:
        raise ValueError(f"texture resolution {res} m/px out of range: use 0.001 .. 0.1 (e.g. 0.01)")
    rng = np.random.default_rng([track.seed & 0xFFFFFFFF, (conditions.randomize or 0) & 0xFFFFFFFF, 0x7E48])
    xmin, ymin, xmax, ymax = texture_bounds(track, margin)
    w = int(np.ceil((xmax - xmin) / res))
    h = int(np.ceil((ymax - ymin) / res))
    tex = TrackTexture(np.empty((h, w, 3), np.uint8), res, xmin, ymax, (0, 0, 0), (0, 0, 0), (0, 0, 0))

    def poly(line: np.ndarray, scale: float = 1.0) -> np.ndarray:
        return np.round(tex.to_pixels(line) * scale * (1 << _SHIFT)).astype(np.int32).reshape(-1, 1, 2)

    def px(metres: float) -> int:
        return max(1, int(round(metres / res)))

    img = SURFACES[look.ground](rng, h, w, np.asarray(look.ground_rgb, np.float32), res)
    if look.road is not None:
        alpha = _road_alpha(track, rng, (h, w), poly, px, ragged_edge, res)
        road = SURFACES[look.road](rng, h, w, np.asarray(look.road_rgb, np.float32), res)
        _blend(img, road, alpha)
    edge = track.width / 2 - track.line_width / 2 - 0.01
    wear = None
    if line_wear > 0 and (look.edge is not None or look.centre is not None):
        # 1 where the paint is intact, down to 1 - line_wear in worn stretches (a coarse field)
        patches = smooth_noise(rng, (h + 15) // 16, (w + 15) // 16, cells=max(2, int(max(h, w) * res / 1.5)))
        wear = 1.0 - line_wear * np.clip(0.5 + 1.2 * patches, 0.0, 1.0)
    if look.edge is not None:
        for side in (edge, -edge):
            _paint_line(img, track, side, look.edge, poly, px, wear)
    if look.centre is not None:
        _paint_line(img, track, 0.0, look.centre, poly, px, wear)

    # light: contrast, soft large-scale shade, cast shadows, level x colour temperature x tint
    mean = img.reshape(-1, 3)[:: max(1, h * w // 4096)].mean(axis=0)
    if conditions.contrast != 1.0:
        img -= mean
        img *= np.float32(conditions.contrast)
        img += mean
    light = 1.0 + conditions.shade * smooth_noise(rng, h, w, cells=4)
    if len(shadows) and conditions.shadow_darkness > 0:
        light *= 1.0 - conditions.shadow_darkness * _shadow_mask(tex, shadows, shadow_blur)
    gains = conditions.gains.astype(np.float32)
    for k in range(3):
        img[..., k] *= light * gains[k]
    np.clip(img, 0, 255, out=img)
    image = img.astype(np.uint8)

    ground_colour = tuple(int(c) for c in np.clip(np.asarray(look.ground_rgb) * conditions.gains, 0, 255))
    sky_top = tuple(int(c) for c in np.clip(np.asarray(look.sky_top) * conditions.gains, 0, 255))
    sky_bottom = tuple(int(c) for c in np.clip(np.asarray(look.sky_bottom) * conditions.gains, 0, 255))
    return TrackTexture(image, res, xmin, ymax, ground_colour, sky_top, sky_bottom)  # type: ignore[arg-type]


def _blend(img: np.ndarray, top: np.ndarray, alpha: np.ndarray) -> None:
    """img = img * (1 - alpha) + top * alpha, in place (alpha HxW float32)."""
    top -= img
    top *= alpha[..., None]
    img += top


def _road_alpha(track: Track, rng: np.random.Generator, shape: tuple[int, int], poly, px, ragged: float,
                res: float) -> np.ndarray:
    """Coverage (float32 HxW in [0, 1]) of the road surface, with a ragged edge if asked."""
    mask = np.zeros(shape, np.uint8)
    if ragged <= 0:
        cv2.polylines(mask, [poly(track.points)], True, 255, px(track.width), cv2.LINE_AA, _SHIFT)
        return mask.astype(np.float32) / 255.0
    # the edges wander by up to `ragged` metres along the track, and grass grows over them in tufts
    n = track.n
    wander = np.interp(np.arange(n), np.linspace(0, n, 13), rng.uniform(-1, 1, 13)) * ragged
    sides = []
    for sign in (1.0, -1.0):
        offset = sign * (track.width / 2 + wander * rng.uniform(0.5, 1.0))
        h_prev = np.roll(track.heading, 1)
        mid = h_prev + 0.5 * np.angle(np.exp(1j * (track.heading - h_prev)))
        sides.append(track.points + offset[:, None] * np.stack([-np.sin(mid), np.cos(mid)], axis=1))
    areas = [abs(_area(s)) for s in sides]
    outer, inner = (sides[0], sides[1]) if areas[0] > areas[1] else (sides[1], sides[0])
    cv2.fillPoly(mask, [poly(outer)], 255, cv2.LINE_AA, _SHIFT)
    cv2.fillPoly(mask, [poly(inner)], 0, cv2.LINE_AA, _SHIFT)
    alpha = cv2.GaussianBlur(mask, (0, 0), max(0.5, ragged / 4 / res)).astype(np.float32) / 255.0
    tufts = smooth_noise(rng, *shape, cells=max(4, int(max(shape) * res / 0.04)))
    alpha += 0.35 * tufts
    alpha -= 0.5
    alpha *= 4.0
    alpha += 0.5
    np.clip(alpha, 0.0, 1.0, out=alpha)
    return alpha


def _area(points: np.ndarray) -> float:
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _paint_line(img: np.ndarray, track: Track, offset: float, paint: Paint, poly, px,
                wear: np.ndarray | None = None) -> None:
    """Paint one line ``offset`` metres left of the centre line: solid or dashed, with its opacity
    (times ``wear``, a field 16 times coarser than the texture, where given)."""
    h, w = img.shape[:2]
    layer = np.zeros((h, w), np.uint8)
    points = track.offset_line(offset) if offset else track.points
    width = px(track.line_width * paint.width)
    if paint.pattern == "solid":
        cv2.polylines(layer, [poly(points)], True, 255, width, cv2.LINE_AA, _SHIFT)
    else:
        on_m, off_m = paint.dash
        on = (track.s % (on_m + off_m)) < on_m
        starts = np.flatnonzero(on & ~np.roll(on, 1))
        dashes = []
        for a in starts:
            idx = [a]
            while on[(idx[-1] + 1) % track.n] and len(idx) < track.n:
                idx.append((idx[-1] + 1) % track.n)
            dashes.append(poly(points[idx]))
        cv2.polylines(layer, dashes, False, 255, width, cv2.LINE_AA, _SHIFT)
    ys, xs = np.nonzero(layer)  # blend only where the line is: a few percent of the texture
    a = (layer[ys, xs].astype(np.float32) * (paint.opacity / 255.0))[:, None]
    if wear is not None:
        a *= wear[ys // 16, xs // 16][:, None]
    colour = np.asarray(paint.colour, np.float32)
    img[ys, xs] = img[ys, xs] * (1.0 - a) + colour * a


def _shadow_mask(tex: TrackTexture, shadows: Sequence[np.ndarray], blur: float) -> np.ndarray:
    """Float32 HxW in [0, 1]: 1 where the ground lies in one of the shadow polygons (soft edges)."""
    h, w = tex.image.shape[:2]
    s = _SHADOW_SCALE
    small = np.zeros(((h + s - 1) // s, (w + s - 1) // s), np.uint8)
    polys = [np.round((tex.to_pixels(p) + 0.5) / s * (1 << _SHIFT) - 0.5 * (1 << _SHIFT)).astype(np.int32)
             .reshape(-1, 1, 2) for p in shadows]
    for p in polys:  # one at a time: overlapping shadows are no darker than one
        cv2.fillPoly(small, [p], 255, cv2.LINE_AA, _SHIFT)
    sigma = blur / (tex.res * s)
    if sigma > 0.3:
        small = cv2.GaussianBlur(small, (0, 0), sigma)
    mask = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    return mask.astype(np.float32) / 255.0
