"""Pinhole camera on the car, rendered by one perspective warp of the top-down track texture.

The ground is a plane, so the map from image pixels to ground points is a homography. The part
from image to the car's frame depends only on the camera mounting and is computed once; each
frame multiplies it by the car's pose and the texture's pixel mapping and calls
``cv2.warpPerspective`` on the ground rows only. Rows above the horizon (and ground further away
than ``max_distance``, which would only alias) get a precomputed sky gradient. A camera with lens
distortion (``SIM_CAMERA_DISTORTION``) renders that pinhole image on a larger canvas and bends it
with one precomputed remap, so camera calibration can be tested against known coefficients.
What stands above the ground (walls, distractors, the car's shadow) is drawn on the pinhole canvas
before the lens by a :class:`parts.sim.scenery.Scenery`, with the projection helpers of this class.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np

from parts.sim.texture import TrackTexture
from parts.vision.lens import LensError, undistort_grid

logger = logging.getLogger(__name__)

#: pixels between the samples of the coarse ray grid used to draw backdrops
GRID = 4


class PinholeCamera:
    """A forward-looking camera fixed on the car: a pinhole, optionally with lens distortion.

    Args:
        width, height: image size in pixels.
        fov_deg: horizontal field of view of the pinhole (undistorted) model in degrees.
        pitch_deg: tilt below the horizon in degrees.
        height_m: height above the ground in metres.
        forward_m: position ahead of the car's reference point (rear axle) in metres.
        max_distance: ground further than this (metres) is drawn as haze/sky.
        distortion: OpenCV lens distortion coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]) applied
            to the pinhole image, with the camera matrix :attr:`intrinsics`; None or all zero = an
            ideal pinhole. Barrel distortion (a wide-angle lens) has k1 < 0.

    With distortion the scene is rendered by the pinhole model on a canvas large enough to hold
    every ray the lens sees, then one precomputed ``cv2.remap`` bends it: output pixel ``p`` shows
    what the pinhole sees at the undistorted position of ``p``. So an image rendered here and
    calibrated with :mod:`parts.vision.calibration` gives back :attr:`intrinsics` and
    ``distortion``.
    """

    def __init__(self, width: int = 160, height: int = 120, fov_deg: float = 100.0, pitch_deg: float = 20.0,
                 height_m: float = 0.2, forward_m: float = 0.2, max_distance: float = 12.0,
                 distortion: Sequence[float] | None = None) -> None:
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
        self.max_distance = max_distance
        f = (width / 2.0) / math.tan(math.radians(fov_deg) / 2.0)
        cx, cy = width / 2.0 - 0.5, height / 2.0 - 0.5
        #: camera matrix of the output image (pixel centres at integer coordinates, as OpenCV)
        self.intrinsics = np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])
        self.distortion = _check_distortion(distortion)
        self._lens_maps: tuple[np.ndarray, np.ndarray] | None = None
        #: size of the pinhole image rendered before the lens bends it (the output size without lens)
        self.canvas_size = (width, height)
        if self.distortion is not None:
            try:
                und = undistort_grid(self.intrinsics, self.distortion, width, height)
            except LensError as exc:
                raise ValueError(f"{exc} for a {width}x{height} camera with a {fov_deg} deg field of view") from None
            x0 = math.floor(float(und[..., 0].min())) - 1
            y0 = math.floor(float(und[..., 1].min())) - 1
            cw = math.ceil(float(und[..., 0].max())) - x0 + 2
            ch = math.ceil(float(und[..., 1].max())) - y0 + 2
            if cw > 4 * width or ch > 4 * height:
                raise ValueError(f"camera distortion {self.distortion.tolist()} is too strong for a "
                                 f"{fov_deg} deg field of view: the pinhole image would be {cw}x{ch}")
            cx, cy = cx - x0, cy - y0
            self.canvas_size = (cw, ch)
            mx = (und[..., 0] - x0).astype(np.float32)
            my = (und[..., 1] - y0).astype(np.float32)
            self._lens_maps = cv2.convertMaps(mx, my, cv2.CV_16SC2)
        cw, ch = self.canvas_size
        #: camera matrix of the pinhole canvas
        self.canvas_intrinsics = np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])
        k_inv = np.linalg.inv(self.canvas_intrinsics)
        p = math.radians(pitch_deg)
        # columns: camera right, down, forward expressed in the car frame (x fwd, y left, z up)
        rot = np.array([[0.0, -math.sin(p), math.cos(p)],
                        [-1.0, 0.0, 0.0],
                        [0.0, -math.cos(p), -math.sin(p)]])
        self.car_from_camera = rot
        a = rot @ k_inv  # canvas pixel -> ray in the car frame
        self._ray = a
        self.focal, self.centre = f, (cx, cy)  # of the canvas
        h = height_m
        # ground point of ray r from camera C=(fwd, 0, h): C + r * h / (-r_z); homogeneous form
        # (fwd * w + r_x, r_y, w) with w = -r_z / h, linear in the pixel
        #: homography canvas pixel -> ground point in the car frame (x ahead, y left), metres
        self.car_from_pixel = np.array([forward_m * (-a[2] / h) + a[0], a[1], -a[2] / h])
        self.pixel_from_car = np.linalg.inv(self.car_from_pixel)
        # first canvas row whose ray meets the ground closer than max_distance
        rows = np.arange(ch, dtype=float)
        rays = a @ np.stack([np.full(ch, cx), rows, np.ones(ch)])  # centre column
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.where(rays[2] < 0, h * np.hypot(rays[0], rays[1]) / -rays[2], np.inf)
        ground = np.flatnonzero(dist <= max_distance)
        self.ground_row = int(ground[0]) if ground.size else ch
        # the warp writes rows ground_row.. only; shift the destination rows accordingly
        self._shift = np.array([[1.0, 0, 0], [0, 1.0, self.ground_row], [0, 0, 1.0]])
        self._sky_cache: dict[tuple[int, ...], np.ndarray] = {}
        # what the backdrop pass needs: the farthest ground hit of each canvas row (inf above the
        # horizon), a field-of-view test for distractors, the coarse ray grid (made on first use)
        self._row_reach = self._reach().max(axis=1)
        self.half_width_slope = (cw / 2.0) / f * 1.3  # lateral / ahead at the canvas edge, with margin
        self._grid: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def _reach(self) -> np.ndarray:
        """Horizontal distance (m) from the camera to the ground hit of every canvas pixel."""
        cw, ch = self.canvas_size
        cols, rows = np.meshgrid(np.arange(cw, dtype=float), np.arange(ch, dtype=float))
        rays = self._ray @ np.stack([cols.ravel(), rows.ravel(), np.ones(cols.size)])
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.where(rays[2] < 0, self.height_m * np.hypot(rays[0], rays[1]) / -rays[2], np.inf)
        return dist.reshape(ch, cw)

    @property
    def distorted(self) -> bool:
        """Whether the camera has lens distortion."""
        return self._lens_maps is not None

    def sky(self, texture: TrackTexture) -> np.ndarray:
        """The sky rows (ground_row x canvas width x 3) for a texture's light, cached."""
        key = texture.sky_top + texture.sky_bottom + texture.ground_color
        if key not in self._sky_cache:
            n = self.ground_row
            t = np.linspace(0.0, 1.0, max(n, 1))[:, None]
            col = (1 - t) * np.array(texture.sky_top) + t * np.array(texture.sky_bottom)
            # a band of hazy far ground just above the rendered rows blends sky into ground
            horizon = max(0, n - max(1, self.canvas_size[1] // 40))
            col[horizon:] = 0.5 * (np.array(texture.sky_bottom) + np.array(texture.ground_color))
            sky = np.repeat(col[:n, None, :], self.canvas_size[0], axis=1)
            self._sky_cache[key] = np.clip(sky, 0, 255).astype(np.uint8)
        return self._sky_cache[key]

    def matrix(self, texture: TrackTexture, x: float, y: float, heading: float) -> np.ndarray:
        """Homography from canvas pixels (ground rows) to texture pixels for a car pose."""
        c, s = math.cos(heading), math.sin(heading)
        world_from_car = np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])
        return texture.world_to_pixel @ world_from_car @ self.car_from_pixel @ self._shift

    def lens(self, canvas: np.ndarray) -> np.ndarray:
        """Bend a pinhole canvas image (canvas_size) into the camera's image (a new array);
        without distortion the canvas is the image and is returned as is."""
        if self._lens_maps is None:
            return canvas
        return cv2.remap(canvas, self._lens_maps[0], self._lens_maps[1], cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)

    def render(self, texture: TrackTexture, x: float, y: float, heading: float,
               out: np.ndarray | None = None, scenery: Any = None) -> np.ndarray:
        """The camera image (height x width x 3 uint8 RGB) for the car at (x, y, heading); with a
        :class:`~parts.sim.scenery.Scenery`, its backdrop, distractors and car shadow too."""
        cw, ch = self.canvas_size
        canvas = out if out is not None and self._lens_maps is None else np.empty((ch, cw, 3), np.uint8)
        g = self.ground_row
        if g > 0:
            canvas[:g] = self.sky(texture)
        if g < ch:
            cv2.warpPerspective(texture.image, self.matrix(texture, x, y, heading),
                                (cw, ch - g), dst=canvas[g:],
                                flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=texture.ground_color)
        if scenery is not None:
            scenery.draw(self, canvas, x, y, heading)
        if self._lens_maps is None:
            return canvas
        image = self.lens(canvas)
        if out is not None:
            out[:] = image
            return out
        return image

    def project_ground(self, points: np.ndarray, intrinsics: np.ndarray | None = None) -> np.ndarray:
        """Image pixels (N, 2) of ground points (N, 2) given in the car frame (x ahead, y left),
        metres, through the lens; with ``intrinsics``, in the undistorted image of this camera
        matrix instead (an ideal pinhole, what :class:`parts.vision.undistort.Undistort` makes).
        Points behind the camera give NaN."""
        pts = np.asarray(points, float).reshape(-1, 2)
        cam = np.array([self.forward_m, 0.0, self.height_m])
        world = np.column_stack([pts, np.zeros(len(pts))]) - cam
        in_cam = world @ self.car_from_camera  # car frame -> camera frame (x right, y down, z fwd)
        out = np.full((len(pts), 2), np.nan)
        ahead = in_cam[:, 2] > 1e-6
        if ahead.any():
            if intrinsics is not None:
                k, dist = np.asarray(intrinsics, float), np.zeros(5)
            else:
                k, dist = self.intrinsics, self.distortion if self.distortion is not None else np.zeros(5)
            proj, _ = cv2.projectPoints(in_cam[ahead].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), k, dist)
            out[ahead] = proj.reshape(-1, 2)
        return out

    # -- projection helpers for what stands above the ground (canvas pixels, before the lens) --------
    def world_to_camera(self, x: float, y: float, heading: float) -> tuple[np.ndarray, np.ndarray]:
        """(M, t) with camera coordinates (right, down, forward) = world point @ M - t, for a car pose."""
        c, s = math.cos(heading), math.sin(heading)
        to_car = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # world row vector @ this = car frame
        offset = np.array([x * c + y * s + self.forward_m, -x * s + y * c, self.height_m])
        return to_car @ self.car_from_camera, offset @ self.car_from_camera

    def project_with(self, to_camera: tuple[np.ndarray, np.ndarray],
                     points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (N, 3) → canvas pixels (N, 2) and depth along the optical axis (N,), metres,
        with a :meth:`world_to_camera` transform."""
        m, t = to_camera
        cam = points @ m - t
        depth = cam[:, 2]
        uv = cam[:, :2] * (self.focal / np.maximum(depth, 1e-6))[:, None] + self.centre
        return uv, depth

    def project(self, points: np.ndarray, x: float, y: float, heading: float) -> tuple[np.ndarray, np.ndarray]:
        """World points (N, 3) → canvas pixels (N, 2) and depth along the optical axis (N,), metres."""
        return self.project_with(self.world_to_camera(x, y, heading), np.asarray(points, float))

    def ground_to_image(self, points: np.ndarray) -> np.ndarray | None:
        """Ground points (K, 2) in the car frame → canvas pixels (K, 2); None if one is behind the camera."""
        hom = np.column_stack([points, np.ones(len(points))]) @ self.pixel_from_car.T
        if np.any(hom[:, 2] <= 1e-9):
            return None
        return hom[:, :2] / hom[:, 2:3]

    def rows_reaching(self, distance: float) -> int:
        """How many top canvas rows hold a pixel whose ray does not meet the ground within ``distance`` m."""
        return int(np.searchsorted(-self._row_reach, -distance, side="left"))

    def ray_grid(self, rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rays of a grid of canvas pixels (every :data:`GRID`-th, at block centres) covering the top
        ``rows``: horizontal unit direction (dx, dy) in the car frame and rise per horizontal metre."""
        if self._grid is None:
            g = GRID
            cw, ch = self.canvas_size
            cols = np.arange((cw + g - 1) // g) * g + (g - 1) / 2
            rws = np.arange((ch + g - 1) // g) * g + (g - 1) / 2
            cc, rr = np.meshgrid(cols, rws)
            rays = self._ray @ np.stack([cc.ravel(), rr.ravel(), np.ones(cc.size)])
            horiz = np.maximum(np.hypot(rays[0], rays[1]), 1e-9)
            shape = cc.shape
            self._grid = ((rays[0] / horiz).reshape(shape), (rays[1] / horiz).reshape(shape),
                          (rays[2] / horiz).reshape(shape))
        n = min(self._grid[0].shape[0], (rows + GRID - 1) // GRID + 1)
        return self._grid[0][:n], self._grid[1][:n], self._grid[2][:n]

    def upsample(self, coarse: np.ndarray, rows: int) -> np.ndarray:
        """A value sampled on :meth:`ray_grid` → full canvas resolution for the top ``rows`` rows (float32)."""
        full = cv2.resize(coarse, (coarse.shape[1] * GRID, coarse.shape[0] * GRID), interpolation=cv2.INTER_LINEAR)
        return np.ascontiguousarray(full[:rows, :self.canvas_size[0]])


def _check_distortion(distortion: Sequence[float] | None) -> np.ndarray | None:
    if distortion is None:
        return None
    d = np.asarray(list(distortion), float).reshape(-1)
    if d.size not in (4, 5, 8) or not np.isfinite(d).all():
        raise ValueError(f"camera distortion must be 4, 5 or 8 finite numbers (k1, k2, p1, p2[, k3[, k4, k5, "
                         f"k6]]), got {list(distortion)!r}")
    return d if np.any(d != 0.0) else None


def camera_from_config(cfg: Any, *, height: float = 0.0, pitch: float = 0.0, fov: float = 0.0,
                       max_distance: float = 12.0) -> PinholeCamera:
    """The simulated camera of a Config (SIM_CAMERA_*), with offsets of height (m), pitch and field
    of view (degrees) as a randomised track draws them."""
    return PinholeCamera(cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_FOV + fov, cfg.SIM_CAMERA_PITCH + pitch,
                  cfg.SIM_CAMERA_HEIGHT + height, cfg.SIM_CAMERA_FORWARD, max_distance,
                  distortion=cfg.SIM_CAMERA_DISTORTION)


def lane_region_points(camera: PinholeCamera, near: float | None = None, far: float = 1.2, half_width: float = 0.5,
                       intrinsics: np.ndarray | None = None) -> dict[str, list[list[float]] | list[int]]:
    """Lane-extraction points for this camera (``LANE_SOURCE_POINTS``, ``LANE_DESTINATION_POINTS``,
    ``LANE_POINTS_SIZE``) that make a rectangle of ground a true bird's-eye view.

    The rectangle spans ``near`` .. ``far`` metres ahead of the rear axle and ±``half_width``
    metres to the sides (``near`` default: the nearest ground the image shows, plus 2 cm). Its
    corners map to the thesis's destination rectangle, scaled to the camera size, so the
    bird's-eye image has the thesis's layout. Point order: bottom left, top left, top right,
    bottom right. ``intrinsics``: the points are for the undistorted frames of a car with
    CAMERA_UNDISTORT, whose camera matrix this is (``Undistort.output_camera_matrix``); without
    it they are for the frames as the lens bends them.
    """
    if near is None:
        # ground seen by the bottom-centre pixel, a little further so the bottom edge stays in view
        pixel = np.array([[camera.width / 2.0 - 0.5, camera.height - 1.0]])
        if intrinsics is not None:  # undistorted frame -> ray -> pinhole canvas pixel
            ray = np.linalg.inv(np.asarray(intrinsics, float)) @ np.array([*pixel[0], 1.0])
            canvas = camera.canvas_intrinsics @ ray
        elif camera.distortion is not None:
            undone = cv2.undistortPoints(pixel.reshape(-1, 1, 2), camera.intrinsics, camera.distortion,
                                         P=camera.canvas_intrinsics)
            canvas = np.array([*undone.reshape(2), 1.0])
        else:
            canvas = np.array([*pixel[0], 1.0])
        bottom = camera.car_from_pixel @ canvas
        near = float(bottom[0] / bottom[2]) + 0.02
    if not 0 < near < far or half_width <= 0:
        raise ValueError(f"lane region needs 0 < near < far metres and half_width > 0, got near {near:.3g} m, "
                         f"far {far:.3g} m, half_width {half_width:.3g} m")
    pts = camera.project_ground(np.array([[near, half_width], [far, half_width], [far, -half_width],
                                          [near, -half_width]]), intrinsics)
    if not np.isfinite(pts).all():
        raise ValueError("the lane region is not in front of the camera: lower near/far")
    # the thesis's destination rectangle (x 80..230, y 0.25..180 of 320x180), scaled
    sx, sy = camera.width / 320.0, camera.height / 180.0
    dest = [[80 * sx, 180 * sy], [80 * sx, 0.25 * sy], [230 * sx, 0.25 * sy], [230 * sx, 180 * sy]]
    return {"LANE_SOURCE_POINTS": [[round(float(x), 2), round(float(y), 2)] for x, y in pts],
            "LANE_DESTINATION_POINTS": [[round(x, 2), round(y, 2)] for x, y in dest],
            "LANE_POINTS_SIZE": [camera.width, camera.height]}
