"""A printed chessboard held in front of the simulated camera, for testing camera calibration.

The thesis (§5.4) calibrates its simulator's camera like the real one: a chessboard object in the
scene, photographed from at least ten angles. Here the board is a plane at any pose in front of
the camera (:class:`parts.sim.camera.PinholeCamera`), rendered through the same pinhole canvas and lens
remap as the track, so calibrating these views must give back the camera's intrinsics and its
``distortion`` coefficients.

Board coordinates are OpenCV's calibration convention: the first inner corner is the origin, x
along a row of inner corners, y down the columns, millimetres, z = 0 on the board.
"""

from __future__ import annotations

import functools
import logging
import math
import time
from typing import ClassVar

import cv2
import numpy as np

from parts.sim.camera import PinholeCamera

logger = logging.getLogger(__name__)

#: texture pixels per board square (the texture is downsampled by the warp; 48 keeps edges crisp)
TEXTURE_PX = 48
#: supersampling of the rendered canvas (anti-aliased square edges, as a real camera integrates light)
SUPERSAMPLE = 3


@functools.lru_cache(maxsize=4)
def board_texture(columns: int, rows: int, px: int = TEXTURE_PX, margin: int = 1) -> np.ndarray:
    """RGB image of a board with ``columns`` x ``rows`` inner corners ((columns + 1) x (rows + 1)
    squares, top-left black) on white paper with ``margin`` squares of border (cached: read only)."""
    nx, ny = columns + 1, rows + 1
    yy, xx = np.mgrid[0:ny, 0:nx]
    squares = np.where((xx + yy) % 2 == 0, 20, 235).astype(np.uint8)
    img = np.kron(squares, np.ones((px, px), np.uint8))
    img = np.pad(img, margin * px, constant_values=245)
    out = np.repeat(img[:, :, None], 3, axis=2)
    out.flags.writeable = False
    return out


def _board_to_texture(square_mm: float, px: int, margin: int) -> np.ndarray:
    """Homography board millimetres -> texture pixel (pixel centres at integers)."""
    s = px / square_mm
    origin = (margin + 1) * px - 0.5  # the first inner corner, in pixel-centre coordinates
    return np.array([[s, 0.0, origin], [0.0, s, origin], [0.0, 0.0, 1.0]])


def render_board_view(camera: PinholeCamera, columns: int, rows: int, rvec: np.ndarray, tvec: np.ndarray, *,
                      square_mm: float = 25.0, background: np.ndarray | None = None) -> np.ndarray:
    """The camera's image (height x width x 3 uint8 RGB) of the board at pose (rvec, tvec) in the
    camera frame (x right, y down, z forward; millimetres, Rodrigues rotation), over ``background``
    (a canvas-sized RGB image; default a grey wall with a gradient)."""
    cw, ch = camera.canvas_size
    texture = board_texture(columns, rows)
    rot, _ = cv2.Rodrigues(np.asarray(rvec, np.float64).reshape(3, 1))
    board_to_canvas = camera.canvas_intrinsics @ np.column_stack([rot[:, 0], rot[:, 1],
                                                                   np.asarray(tvec, float).reshape(3)])
    ss = SUPERSAMPLE
    # supersampled pixel u_s and canvas pixel u cover the same spot when u_s + 0.5 = ss * (u + 0.5)
    up = np.array([[ss, 0.0, (ss - 1) / 2], [0.0, ss, (ss - 1) / 2], [0.0, 0.0, 1.0]])
    h = up @ board_to_canvas @ np.linalg.inv(_board_to_texture(square_mm, TEXTURE_PX, 1))
    if background is None:
        ramp = np.linspace(120, 170, cw * ss, dtype=np.float32)[None, :, None]
        big = np.broadcast_to(ramp, (ch * ss, cw * ss, 3)).astype(np.uint8)
    else:
        if background.shape[:2] != (ch, cw):
            raise ValueError(f"background must be the camera's canvas size {cw}x{ch}, got "
                             f"{background.shape[1]}x{background.shape[0]}")
        big = cv2.resize(background, (cw * ss, ch * ss), interpolation=cv2.INTER_LINEAR)
    big = np.ascontiguousarray(big)
    cv2.warpPerspective(texture, h, (cw * ss, ch * ss), dst=big, flags=cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_TRANSPARENT)
    canvas = cv2.resize(big, (cw, ch), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(camera.lens(canvas))


def project_corners(camera: PinholeCamera, columns: int, rows: int, rvec: np.ndarray, tvec: np.ndarray,
                    square_mm: float = 25.0) -> np.ndarray:
    """Image positions (N, 2) of the inner corners (row by row, as OpenCV orders them) through
    the lens; the ground truth for a rendered view."""
    grid = np.mgrid[0:columns, 0:rows].T.reshape(-1, 2) * square_mm
    obj = np.column_stack([grid, np.zeros(len(grid))]).astype(np.float64)
    dist = camera.distortion if camera.distortion is not None else np.zeros(5)
    pts, _ = cv2.projectPoints(obj, np.asarray(rvec, float), np.asarray(tvec, float), camera.intrinsics, dist)
    return pts.reshape(-1, 2)


def random_board_poses(camera: PinholeCamera, columns: int, rows: int, n: int, *, seed: int = 0,
                       square_mm: float = 25.0, max_tilt_deg: float = 40.0,
                       size: tuple[float, float] = (0.5, 0.95), margin_px: float = 4.0,
                       min_step_px: float = 8.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` varied board poses (rvec, tvec) whose whole board is in the image: tilted up to
    ``max_tilt_deg`` about both board axes, turned in-plane, spanning ``size`` (fraction of the
    image width) and placed all over the image, including its distorted corners. Poses whose
    neighbouring corners come closer than ``min_step_px`` (too small or too oblique a board for a
    corner detector, as for a person holding the board) are skipped."""
    rng = np.random.default_rng([seed & 0xFFFFFFFF, 0xC4E55])
    f = float(camera.intrinsics[0, 0])
    board_w = (columns + 1) * square_mm
    board_h = (rows + 1) * square_mm
    centre = np.array([(columns - 1) * square_mm / 2, (rows - 1) * square_mm / 2, 0.0])
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    tries = 0
    while len(poses) < n:
        tries += 1
        if tries > 500 * n:
            raise ValueError(f"cannot place a {columns}x{rows} board fully in a {camera.width}x{camera.height} view")
        ax, ay = np.radians(rng.uniform(-max_tilt_deg, max_tilt_deg, 2))
        az = np.radians(rng.uniform(-25, 25))
        rot = _rot_z(az) @ _rot_y(ay) @ _rot_x(ax)
        frac = rng.uniform(*size)
        z = f * max(board_w, board_h) / (frac * camera.width)
        # aim the board's centre at a random point of the image (undistorted ray)
        u = rng.uniform(0.1, 0.9) * camera.width
        v = rng.uniform(0.1, 0.9) * camera.height
        ray = np.linalg.inv(camera.intrinsics) @ np.array([u, v, 1.0])
        t = ray / ray[2] * z - rot @ centre
        rvec, _ = cv2.Rodrigues(rot)
        # the board must face the camera: its normal points away from it (towards +z)
        if (rot @ np.array([0.0, 0.0, 1.0]))[2] <= 0.2:
            continue
        pts = project_corners(camera, columns, rows, rvec, t, square_mm)
        outline = project_corners(camera, columns + 2, rows + 2, rvec, t - rot @ np.array([square_mm, square_mm, 0]),
                                  square_mm)
        inside = np.all((outline >= margin_px) & (outline <= [camera.width - 1 - margin_px,
                                                               camera.height - 1 - margin_px]))
        grid = pts.reshape(rows, columns, 2)
        step = min(np.linalg.norm(np.diff(grid, axis=0), axis=2).min(),
                   np.linalg.norm(np.diff(grid, axis=1), axis=2).min()) if np.isfinite(pts).all() else 0.0
        if inside and step >= min_step_px:
            poses.append((rvec.reshape(3), t.reshape(3)))
    return poses


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


class ChessboardCamera:
    """Part: a camera filming someone who moves a chessboard in front of it (for live calibration
    in the simulator). Output ``cam/image_array``; the board changes pose every ``hold`` frames,
    with a board-free frame in between (as when the person moves it).

    Args:
        camera: the simulated camera (size, field of view, lens distortion).
        columns, rows: inner corners of the board.
        poses: how many poses to cycle through.
        hold: frames per pose.
        seed: seed of the poses.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ()
    OUTPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array", "cam/timestamp")

    def __init__(self, camera: PinholeCamera, columns: int = 10, rows: int = 7, *, poses: int = 30, hold: int = 3,
                 seed: int = 0, square_mm: float = 25.0) -> None:
        if hold < 1:
            raise ValueError(f"hold must be >= 1 frame, got {hold}")
        self.camera = camera
        self.columns, self.rows, self.square_mm = columns, rows, square_mm
        self.poses = random_board_poses(camera, columns, rows, poses, seed=seed, square_mm=square_mm)
        self.hold = int(hold)
        self.frame = 0
        cw, ch = camera.canvas_size
        self._empty = camera.lens(np.full((ch, cw, 3), 140, np.uint8))

    def run(self) -> tuple[np.ndarray, float]:
        """The next frame and its timestamp."""
        period = self.hold + 1
        i, k = divmod(self.frame, period)
        self.frame += 1
        if k == self.hold:  # the board is being moved: nothing to detect
            return self._empty.copy(), time.time()
        rvec, tvec = self.poses[i % len(self.poses)]
        image = render_board_view(self.camera, self.columns, self.rows, rvec, tvec, square_mm=self.square_mm)
        return image, time.time()
