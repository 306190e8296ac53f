"""OpenCV's lens distortion model, inverted robustly (Newton's method).

``cv2.undistortPoints`` inverts the distortion with a few fixed-point iterations, which do not
converge near the edges of a strongly distorted (wide-angle) image; ``cv2.getOptimalNewCameraMatrix``
inherits the error (black borders at ``alpha = 0``). :func:`undistort_points` solves the same
equations to 1e-12 and checks the answer by distorting it again.
"""

from __future__ import annotations

import numpy as np

from vehicle.errors import VehicleError


class LensError(VehicleError, ValueError):
    """The distortion model does not invert over the image (too strong, or it folds the image)."""


def _coefficients(dist: np.ndarray) -> np.ndarray:
    d = np.asarray(dist, float).reshape(-1)
    if d.size not in (4, 5, 8):
        raise LensError(f"distortion must be 4, 5 or 8 coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]), "
                        f"got {d.size}")
    c = np.zeros(8)
    c[:d.size] = d
    return c


def distort_normalized(x: np.ndarray, y: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's model: ideal normalized image coordinates -> distorted normalized coordinates."""
    k1, k2, p1, p2, k3, k4, k5, k6 = _coefficients(dist)
    r2 = x * x + y * y
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    return (x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y)


def undistort_points(k: np.ndarray, dist: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Where the ideal pinhole (camera matrix ``k``) would see what the lens shows at ``points``
    (pixels, (..., 2)): the undistorted pixel positions, same shape.

    Raises:
        LensError: the model does not invert at some point (too strong, or folding, distortion).
    """
    pts = np.asarray(points, float)
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    xd, yd = (pts[..., 0] - cx) / fx, (pts[..., 1] - cy) / fy
    x, y = xd.copy(), yd.copy()
    eps = 1e-7
    with np.errstate(all="ignore"):
        for _ in range(50):
            u, v = distort_normalized(x, y, dist)
            ru, rv = u - xd, v - yd
            if np.nanmax(np.abs(ru) + np.abs(rv)) < 1e-12:
                break
            ux, vx = distort_normalized(x + eps, y, dist)
            uy, vy = distort_normalized(x, y + eps, dist)
            a, b, c, d = (ux - u) / eps, (uy - u) / eps, (vx - v) / eps, (vy - v) / eps
            det = a * d - b * c
            sx, sy = (d * ru - b * rv) / det, (a * rv - c * ru) / det
            # damped: never step further than a quarter of the distance from the centre (plus one)
            scale = np.minimum(1.0, 0.25 * (1.0 + np.hypot(x, y)) / np.maximum(np.hypot(sx, sy), 1e-300))
            x, y = x - sx * scale, y - sy * scale
        rx, ry = distort_normalized(x, y, dist)
        err = np.hypot((rx - xd) * fx, (ry - yd) * fy)
    if not np.all(np.isfinite(err)) or (err.size and err.max() > 0.01):
        raise LensError(f"lens distortion {np.asarray(dist).reshape(-1).tolist()} cannot be inverted over the "
                        "image (too strong, or it folds the image): use smaller coefficients")
    return np.stack([x * fx + cx, y * fy + cy], axis=-1)


def undistort_grid(k: np.ndarray, dist: np.ndarray, width: int, height: int) -> np.ndarray:
    """Undistorted pixel positions (height, width, 2) of every pixel of a ``width`` x ``height`` image."""
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    return undistort_points(k, dist, np.stack([xs, ys], axis=-1))


def new_camera_matrix(k: np.ndarray, dist: np.ndarray, width: int, height: int, alpha: float) -> np.ndarray:
    """The camera matrix of the undistorted view, as ``cv2.getOptimalNewCameraMatrix`` means it:
    ``alpha`` 0 shows only valid pixels (the largest rectangle inside the undistorted image), 1
    shows every source pixel (the rectangle around it); in between, interpolated."""
    n = 64
    t = np.linspace(0.0, 1.0, n)
    w, h = width - 1.0, height - 1.0
    edges = {"left": np.stack([np.zeros(n), t * h], 1), "right": np.stack([np.full(n, w), t * h], 1),
             "top": np.stack([t * w, np.zeros(n)], 1), "bottom": np.stack([t * w, np.full(n, h)], 1)}
    und = {name: undistort_points(k, dist, pts) for name, pts in edges.items()}
    inner = (und["left"][:, 0].max(), und["top"][:, 1].max(), und["right"][:, 0].min(), und["bottom"][:, 1].min())
    allpts = np.concatenate(list(und.values()))
    outer = (allpts[:, 0].min(), allpts[:, 1].min(), allpts[:, 0].max(), allpts[:, 1].max())
    x0, y0, x1, y1 = ((1 - alpha) * a + alpha * b for a, b in zip(inner, outer, strict=True))
    # the chosen rectangle (in undistorted pixels of k) fills the output image, pixel centres 0 .. w
    sx, sy = w / (x1 - x0), h / (y1 - y0)
    return np.array([[k[0, 0] * sx, 0.0, (k[0, 2] - x0) * sx], [0.0, k[1, 1] * sy, (k[1, 2] - y0) * sy],
                     [0.0, 0.0, 1.0]])
