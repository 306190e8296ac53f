"""What stands around the track: the walls of a room, or a tree line, as one unrolled panorama.

A backdrop is drawn on the vertical sides of the texture's rectangle (the edge of the floor or
lawn). Its image is the four sides unrolled, each seen from inside: column ``u`` (metres along
the perimeter, clockwise seen from above, starting at the corner (x1, y0)) and row 0 at the top
(``height`` metres above the ground). The camera casts rays onto it (:mod:`parts.sim.scenery`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from parts.sim.surfaces import smooth_noise

#: metres per panorama pixel
BACKDROP_RES = 0.025


@dataclass(frozen=True)
class Backdrop:
    """An unrolled panorama of the four sides of the box ``bounds`` (x0, y0, x1, y1), metres."""

    image: np.ndarray  # (H, 2 * W, 3) uint8: the perimeter twice, so a view across the seam is one slice
    res: float  # metres per pixel
    height: float  # metres above the ground of row 0
    bounds: tuple[float, float, float, float]

    @property
    def perimeter(self) -> float:
        """Length of the unrolled sides, metres."""
        x0, y0, x1, y1 = self.bounds
        return 2.0 * ((x1 - x0) + (y1 - y0))


def _sides(bounds: tuple[float, float, float, float]) -> list[float]:
    """Lengths of the four sides in panorama order (bottom, left, top, right), metres."""
    x0, y0, x1, y1 = bounds
    return [x1 - x0, y1 - y0, x1 - x0, y1 - y0]


def _finish(canvas: np.ndarray, res: float, height: float, bounds: tuple[float, float, float, float],
            gains: np.ndarray) -> Backdrop:
    img = np.clip(canvas * gains.astype(np.float32), 0, 255).astype(np.uint8)
    return Backdrop(np.ascontiguousarray(np.concatenate([img, img], axis=1)), res, height, bounds)


_WALLS = ((232, 228, 218), (215, 200, 175), (200, 202, 205), (185, 200, 215), (190, 205, 185), (165, 165, 160))
_TRIM = ((240, 240, 236), (95, 65, 45), (120, 120, 120), (40, 40, 40))
_DOORS = ((150, 105, 65), (235, 235, 230), (120, 125, 130), (90, 60, 40))
_FURNITURE = ((150, 110, 70), (200, 200, 195), (90, 95, 100), (60, 60, 65), (180, 150, 110))


def room(rng: np.random.Generator, bounds: tuple[float, float, float, float], gains: np.ndarray,
         res: float = BACKDROP_RES) -> Backdrop:
    """The walls of a room around the floor: paint, skirting board, doors, windows, pictures,
    cupboards and radiators, each wall lit a little differently."""
    height = 2.6
    sides = _sides(bounds)
    w = int(round(sum(sides) / res))
    h = int(round(height / res))
    wall = np.asarray(_WALLS[int(rng.integers(len(_WALLS)))], np.float32) * rng.uniform(0.92, 1.05, 3)
    canvas = np.empty((h, w, 3), np.float32)
    canvas[:] = wall
    canvas += (6.0 * smooth_noise(rng, h, w, max(2, w // 40)))[..., None]
    canvas += rng.standard_normal((h, w, 1), dtype=np.float32) * 2.5

    def px(metres: float) -> int:
        return int(round(metres / res))

    def rect(u0: float, z0: float, u1: float, z1: float, colour: np.ndarray) -> None:
        canvas[px(height - z1):px(height - z0), px(u0):px(u1)] = colour

    trim = np.asarray(_TRIM[int(rng.integers(len(_TRIM)))], np.float32)
    start = 0.0
    for length in sides:
        u = start + rng.uniform(0.3, 1.5)
        while True:
            kind = rng.choice(("door", "window", "picture", "cupboard", "radiator", "gap"),
                              p=(0.18, 0.14, 0.2, 0.2, 0.1, 0.18))
            width = {"door": 0.9, "window": rng.uniform(1.0, 1.8), "picture": rng.uniform(0.4, 1.0),
                     "cupboard": rng.uniform(0.6, 2.0), "radiator": rng.uniform(0.8, 1.4),
                     "gap": rng.uniform(0.5, 2.0)}[kind]
            if u + width > start + length - 0.3:
                break
            if kind == "door":
                colour = np.asarray(_DOORS[int(rng.integers(len(_DOORS)))], np.float32)
                rect(u - 0.06, 0.0, u + width + 0.06, 2.1, trim * 0.9)
                rect(u, 0.0, u + width, 2.04, colour)
                rect(u + width - 0.15, 1.0, u + width - 0.08, 1.04, np.float32([70, 70, 70]))  # handle
            elif kind == "window":
                rect(u - 0.05, 0.85, u + width + 0.05, 2.15, trim)
                sky = np.float32([200, 220, 240]) * rng.uniform(0.85, 1.1)
                rect(u, 0.9, u + width, 2.1, sky)
                rect(u + width / 2 - 0.02, 0.9, u + width / 2 + 0.02, 2.1, trim)
            elif kind == "picture":
                z0 = rng.uniform(1.1, 1.5)
                rect(u, z0, u + width, z0 + width * rng.uniform(0.6, 1.3), rng.uniform(20, 235, 3).astype(np.float32))
            elif kind == "cupboard":
                colour = np.asarray(_FURNITURE[int(rng.integers(len(_FURNITURE)))], np.float32)
                top = rng.uniform(0.8, 2.0)
                rect(u, 0.0, u + width, top, colour)
                for z in np.arange(0.35, top, rng.uniform(0.3, 0.45)):  # shelves or drawer lines
                    rect(u, z, u + width, z + 0.02, colour * 0.7)
            elif kind == "radiator":
                rect(u, 0.15, u + width, 0.7, np.float32([235, 235, 232]))
                for k in np.arange(u + 0.04, u + width, 0.08):
                    rect(k, 0.15, k + 0.015, 0.7, np.float32([205, 205, 202]))
            u += width + rng.uniform(0.3, 1.5)
        # skirting board, and a faint shadow in the corner where two walls meet
        canvas[h - px(rng.uniform(0.06, 0.12)):, px(start):px(start + length)] = trim
        canvas[:, px(start):px(start + length)] *= rng.uniform(0.82, 1.04)
        canvas[:, px(start):px(start) + 2] *= 0.7
        start += length
    return _finish(canvas, res, height, bounds, gains)


def treeline(rng: np.random.Generator, bounds: tuple[float, float, float, float], gains: np.ndarray,
             sky: tuple[tuple[int, int, int], tuple[int, int, int]], lawn: tuple[int, int, int],
             res: float = 0.04) -> Backdrop:
    """Trees and bushes around the lawn in front of hazy distant woods, with sky above them."""
    height = 10.0
    w = int(round(sum(_sides(bounds)) / res))
    h = int(round(height / res))
    t = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None]
    top, horizon = np.asarray(sky[0], np.float32), np.asarray(sky[1], np.float32)
    canvas = np.empty((h, w, 3), np.float32)
    canvas[:] = ((1 - t) * top + t * horizon)[:, None, :]

    def row(z: float) -> int:
        return int(round((height - z) / res))

    # distant woods: a hazy band whose top is bumpy at the scale of tree crowns
    far = np.asarray(horizon, np.float32) * 0.4 + np.float32([40, 72, 42]) * 0.6
    tops = (2.0 + 0.8 * smooth_noise(rng, 1, w, max(2, w // 60))[0]
            + 0.35 * smooth_noise(rng, 1, w, max(2, int(w * res / 0.8)))[0])
    zs = (height - (np.arange(h, dtype=np.float32) + 0.5) * res)[:, None]
    canvas[zs < tops[None, :]] = far
    # trees: trunk and a crown of overlapping discs, dark greens with leafy noise; bushes below
    foliage = np.zeros((h, w), np.uint8)
    shade = np.zeros((h, w), np.float32)
    u = rng.uniform(0.5, 2.0)
    trunks = []
    while u < w * res - 1.0:
        crown = rng.uniform(2.2, 4.5)
        radius = rng.uniform(1.0, 2.0)
        trunks.append((u, rng.uniform(0.2, 0.45), crown))
        for _ in range(int(rng.integers(4, 8))):
            cu = u + rng.uniform(-radius, radius) * 0.8
            cz = crown + rng.uniform(-radius, radius) * 0.5
            r = radius * rng.uniform(0.5, 0.9)
            cv2.circle(foliage, (int(cu / res), row(cz)), int(r / res), 255, -1, cv2.LINE_AA)
            cv2.circle(shade, (int(cu / res), row(cz)), int(r / res), float(rng.uniform(0.6, 1.1)), -1)
        u += rng.uniform(2.0, 5.0)
    for _ in range(int(w * res / 2.5)):  # bushes along the bottom
        cu, width, tall = rng.uniform(0, w * res), rng.uniform(0.8, 3.0), rng.uniform(0.4, 1.4)
        cv2.ellipse(foliage, (int(cu / res), row(0.0)), (int(width / 2 / res), int(tall / res)), 0, 180, 360,
                    255, -1, cv2.LINE_AA)
        cv2.ellipse(shade, (int(cu / res), row(0.0)), (int(width / 2 / res), int(tall / res)), 0, 180, 360,
                    float(rng.uniform(0.7, 1.0)), -1)
    bark = np.float32([85, 70, 55]) * rng.uniform(0.8, 1.2)
    for cu, width, z1 in trunks:
        canvas[row(z1):row(0.0), int((cu - width / 2) / res):int((cu + width / 2) / res) + 1] = bark
    leaf = np.asarray((35, 75, 35), np.float32) * rng.uniform(0.8, 1.25, 3)
    leafy = 0.75 + 0.5 * np.clip(smooth_noise(rng, h, w, max(2, int(w * res / 0.3))), -0.5, 0.5)
    alpha = (foliage.astype(np.float32) / 255.0)[..., None]
    canopy = leaf * (np.where(shade > 0, shade, 1.0) * leafy)[..., None]
    canvas = canvas * (1 - alpha) + canopy * alpha
    canvas[row(0.05):] = np.asarray(lawn, np.float32)
    return _finish(canvas, res, height, bounds, gains)
