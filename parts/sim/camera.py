"""Pinhole camera on the car, rendered by one perspective warp of the top-down track texture.

The ground is a plane, so the map from image pixels to ground points is a homography. The part
from image to the car's frame depends only on the camera mounting and is computed once; each
frame multiplies it by the car's pose and the texture's pixel mapping and calls
``cv2.warpPerspective`` on the ground rows only. Rows above the horizon (and ground further away
than ``max_distance``, which would only alias) get a precomputed sky gradient.
"""

from __future__ import annotations

import logging
import math

import cv2
import numpy as np

from parts.sim.texture import TrackTexture

logger = logging.getLogger(__name__)


class Camera:
    """A forward-looking pinhole camera fixed on the car.

    Args:
        width, height: image size in pixels.
        fov_deg: horizontal field of view in degrees.
        pitch_deg: tilt below the horizon in degrees.
        height_m: height above the ground in metres.
        forward_m: position ahead of the car's reference point (rear axle) in metres.
        max_distance: ground further than this (metres) is drawn as haze/sky.
    """

    def __init__(self, width: int = 160, height: int = 120, fov_deg: float = 100.0, pitch_deg: float = 20.0,
                 height_m: float = 0.2, forward_m: float = 0.2, max_distance: float = 12.0) -> None:
        if not (isinstance(width, int) and isinstance(height, int)) or width < 8 or height < 8:
            raise ValueError(f"camera size must be integers >= 8, got {width}x{height}")
        if not 10.0 <= fov_deg <= 170.0:
            raise ValueError(f"camera fov {fov_deg} deg out of range: use 10 .. 170")
        if not -10.0 <= pitch_deg <= 89.0:
            raise ValueError(f"camera pitch {pitch_deg} deg out of range: use -10 .. 89 (down)")
        if height_m <= 0:
            raise ValueError(f"camera height must be > 0 m, got {height_m}")
        self.width, self.height = width, height
        self.fov_deg, self.pitch_deg, self.height_m, self.forward_m = fov_deg, pitch_deg, height_m, forward_m
        f = (width / 2.0) / math.tan(math.radians(fov_deg) / 2.0)
        cx, cy = width / 2.0 - 0.5, height / 2.0 - 0.5
        k_inv = np.array([[1 / f, 0, -cx / f], [0, 1 / f, -cy / f], [0, 0, 1]])
        p = math.radians(pitch_deg)
        # columns: camera right, down, forward expressed in the car frame (x fwd, y left, z up)
        rot = np.array([[0.0, -math.sin(p), math.cos(p)],
                        [-1.0, 0.0, 0.0],
                        [0.0, -math.cos(p), -math.sin(p)]])
        a = rot @ k_inv  # pixel -> ray in the car frame
        h = height_m
        # ground point of ray r from camera C=(fwd, 0, h): C + r * h / (-r_z); homogeneous form
        # (fwd * w + r_x, r_y, w) with w = -r_z / h, linear in the pixel
        self.car_from_pixel = np.array([forward_m * (-a[2] / h) + a[0], a[1], -a[2] / h])
        # first image row whose ray meets the ground closer than max_distance
        rows = np.arange(height, dtype=float)
        rays = a @ np.stack([np.full(height, cx), rows, np.ones(height)])  # centre column
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.where(rays[2] < 0, h * np.hypot(rays[0], rays[1]) / -rays[2], np.inf)
        ground = np.flatnonzero(dist <= max_distance)
        self.ground_row = int(ground[0]) if ground.size else height
        # the warp writes rows ground_row.. only; shift the destination rows accordingly
        self._shift = np.array([[1.0, 0, 0], [0, 1.0, self.ground_row], [0, 0, 1.0]])
        self._sky_cache: dict[tuple[int, ...], np.ndarray] = {}

    def sky(self, texture: TrackTexture) -> np.ndarray:
        """The sky rows (ground_row x width x 3) for a texture's light, cached."""
        key = texture.sky_top + texture.sky_bottom + texture.ground_color
        if key not in self._sky_cache:
            n = self.ground_row
            t = np.linspace(0.0, 1.0, max(n, 1))[:, None]
            col = (1 - t) * np.array(texture.sky_top) + t * np.array(texture.sky_bottom)
            # a band of hazy far ground just above the rendered rows blends sky into ground
            horizon = max(0, n - max(1, self.height // 40))
            col[horizon:] = 0.5 * (np.array(texture.sky_bottom) + np.array(texture.ground_color))
            sky = np.repeat(col[:n, None, :], self.width, axis=1)
            self._sky_cache[key] = np.clip(sky, 0, 255).astype(np.uint8)
        return self._sky_cache[key]

    def matrix(self, texture: TrackTexture, x: float, y: float, heading: float) -> np.ndarray:
        """Homography from destination pixels (ground rows) to texture pixels for a car pose."""
        c, s = math.cos(heading), math.sin(heading)
        world_from_car = np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])
        return texture.world_to_pixel @ world_from_car @ self.car_from_pixel @ self._shift

    def render(self, texture: TrackTexture, x: float, y: float, heading: float,
               out: np.ndarray | None = None) -> np.ndarray:
        """The camera image (height x width x 3 uint8 RGB) for the car at (x, y, heading)."""
        if out is None:
            out = np.empty((self.height, self.width, 3), np.uint8)
        g = self.ground_row
        if g > 0:
            out[:g] = self.sky(texture)
        if g < self.height:
            cv2.warpPerspective(texture.image, self.matrix(texture, x, y, heading),
                                (self.width, self.height - g), dst=out[g:],
                                flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=texture.ground_color)
        return out


class ImageJitter:
    """Optional per-frame image degradation: brightness jitter, box blur and Gaussian noise.

    Args:
        noise: standard deviation of per-pixel noise (0..255 units), 0 = off.
        blur: box-blur kernel size in pixels, 0 or 1 = off.
        brightness: each frame is scaled by a factor drawn from [1 - b, 1 + b], 0 = off.
        seed: seed of the random draws.
    """

    def __init__(self, noise: float = 0.0, blur: int = 0, brightness: float = 0.0, seed: int = 0) -> None:
        if noise < 0 or blur < 0 or not 0 <= brightness < 1:
            raise ValueError(f"image jitter out of range (noise {noise} >= 0, blur {blur} >= 0, "
                             f"0 <= brightness {brightness} < 1)")
        self.noise, self.blur, self.brightness = float(noise), int(blur), float(brightness)
        self.rng = np.random.default_rng([seed & 0xFFFFFFFF, 0x1A7])

    @property
    def active(self) -> bool:
        """Whether any jitter is configured."""
        return self.noise > 0 or self.blur > 1 or self.brightness > 0

    def apply(self, image: np.ndarray) -> np.ndarray:
        """Degrade ``image`` in place (and return it)."""
        if self.blur > 1:
            cv2.blur(image, (self.blur, self.blur), dst=image)
        if self.brightness > 0 or self.noise > 0:
            img = image.astype(np.float32)
            if self.brightness > 0:
                img *= self.rng.uniform(1 - self.brightness, 1 + self.brightness)
            if self.noise > 0:
                img += self.rng.normal(0.0, self.noise, img.shape).astype(np.float32)
            np.clip(img, 0, 255, out=img)
            image[:] = img.astype(np.uint8)
        return image
