"""Camera calibration from chessboard views (thesis seed 002, §6 and Appendix 1), with OpenCV.

The thesis's procedure, made robust: find the inner corners of a printed chessboard in views taken
from different angles (``cv2.findChessboardCorners``; here refined to sub-pixel accuracy with
``cv2.cornerSubPix``), then let ``cv2.calibrateCamera`` (Zhang's method + Levenberg-Marquardt)
find the camera matrix and the distortion coefficients that minimise the reprojection error.

Differences from the thesis's Appendix 1 code, and why:

- sub-pixel corner refinement (the thesis used the raw detections; refinement lowers the
  reprojection error several-fold on small images);
- views whose board is too small or too blurred to detect are reported, not silently skipped;
- the result is a JSON file in the car folder (:class:`CameraCalibration`), with the RMS and
  per-view reprojection errors, the board and the image size it belongs to, instead of module
  globals.

The distortion model is OpenCV's: ``standard`` = (k1, k2, p1, p2, k3) as the thesis's code
(``calibrateCamera`` without flags); ``rational`` adds k4..k6 (``CALIB_RATIONAL_MODEL``), the
form of the thesis's equation 6.3, for wide lenses. Note OpenCV's sign: barrel distortion (a wide
lens, straight lines bowing outwards) has k1 < 0 in this model.
"""

from __future__ import annotations

import errno
import json
import logging
import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, ClassVar

import cv2
import numpy as np

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

#: distortion models: name -> (number of coefficients, cv2 flags)
MODELS: dict[str, tuple[int, int]] = {"standard": (5, 0), "rational": (8, cv2.CALIB_RATIONAL_MODEL)}
#: views below which the result is unreliable (the thesis: "at least ten different angles")
RECOMMENDED_VIEWS = 10
#: fewest views calibrateCamera is given
MIN_VIEWS = 3
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".gif")
#: phone photo formats OpenCV cannot read: listed (as unreadable, with a hint), never silently skipped
UNREADABLE_SUFFIXES = (".heic", ".heif")
#: a view whose corners moved less than this (mean, fraction of the image diagonal) from a kept
#: view's is a near-duplicate of it (a burst of photos, the same pose twice): it adds no information
#: and would weigh that pose twice
DUPLICATE_MOVE = 0.02
#: a fit this uncertain (one standard deviation) is reported: fx relative, k1 absolute
UNCERTAIN_FX = 0.01
UNCERTAIN_K1 = 0.01
#: the file format version written by :meth:`CameraCalibration.save`
FORMAT_VERSION = 1


class CalibrationError(VehicleError, ValueError):
    """Calibration is impossible with the given views or a calibration file is unusable."""


@dataclass(frozen=True)
class Chessboard:
    """A printed chessboard: inner corners per row and per column, and the square size.

    The thesis's board has 10 x 7 inner corners (an 11 x 8 squares print). Only the square size's
    unit matters for the extrinsics (board poses); the intrinsics do not depend on it.
    """

    columns: int = 10
    rows: int = 7
    square_mm: float = 25.0

    def __post_init__(self) -> None:
        for name in ("columns", "rows"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 2:
                raise CalibrationError(f"chessboard {name} = {value!r}: count the inner corners "
                                       "(where four squares meet), at least 2")
        if self.columns == self.rows:
            # a square pattern is ambiguous under 90 degree rotations: corners would be mislabelled
            raise CalibrationError(f"chessboard has {self.columns} x {self.rows} inner corners: use a board "
                                   "with different counts per row and per column (e.g. 10 x 7)")
        if not self.square_mm > 0:
            raise CalibrationError(f"chessboard square size must be > 0 mm, got {self.square_mm}")

    @property
    def pattern(self) -> tuple[int, int]:
        """(columns, rows) as OpenCV's ``patternSize``."""
        return self.columns, self.rows

    def object_points(self) -> np.ndarray:
        """The inner corners on the board plane (z = 0), row by row, in millimetres: (N, 3) float32."""
        grid = np.mgrid[0:self.columns, 0:self.rows].T.reshape(-1, 2)
        pts = np.zeros((self.columns * self.rows, 3), np.float32)
        pts[:, :2] = grid * self.square_mm
        return pts


def _gray(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return image
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    raise CalibrationError(f"expected a grey or RGB image, got shape {image.shape}")


def find_corners(image: np.ndarray, board: Chessboard, *, fast_check: bool = False) -> np.ndarray | None:
    """The board's inner corners in ``image`` (RGB or grey uint8), sub-pixel, shape (N, 1, 2)
    float32 in OpenCV's order, or None when the whole board is not visible.

    Images wider than 1280 px are searched at half size first (the thesis's note: the detector
    struggles with large images), then refined at full size. ``fast_check`` rejects images
    without a board quickly (for live video).
    """
    gray = _gray(image)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    if fast_check:
        flags |= cv2.CALIB_CB_FAST_CHECK
    scale = 1
    small = gray
    while small.shape[1] > 1280:
        small = cv2.resize(small, (small.shape[1] // 2, small.shape[0] // 2), interpolation=cv2.INTER_AREA)
        scale *= 2
    found, corners = cv2.findChessboardCorners(small, board.pattern, None, flags)
    if not found or corners is None:
        return None
    corners = corners.astype(np.float32) * scale
    # refinement window: a third of the smallest distance between neighbouring corners, so it never
    # reaches the next corner; at least 2 px (tiny boards), at most 11 px
    pts = corners.reshape(board.rows, board.columns, 2)
    step = min(np.linalg.norm(np.diff(pts, axis=0), axis=2).min(),
               np.linalg.norm(np.diff(pts, axis=1), axis=2).min())
    win = int(max(2, min(11, step / 3)))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.001)
    refined = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2), (win, win), (-1, -1), criteria)
    return np.asarray(refined, np.float32).reshape(-1, 1, 2)


def draw_corners(image: np.ndarray, board: Chessboard, corners: np.ndarray | None) -> np.ndarray:
    """A copy of ``image`` (RGB) with the detected corners drawn (OpenCV's coloured zig-zag)."""
    out = image.copy() if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2RGB)
    if corners is not None:
        cv2.drawChessboardCorners(out, board.pattern, corners, True)
    return out


@dataclass
class CameraCalibration:
    """A camera's intrinsics and lens distortion at one image size, and how well they fit.

    Attributes:
        image_size: (width, height) in pixels of the frames it was made from.
        camera_matrix: 3x3 [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels.
        dist_coeffs: OpenCV's distortion coefficients (k1, k2, p1, p2, k3[, k4, k5, k6]).
        rms: RMS reprojection error over all corners of all views, pixels.
        view_errors: RMS reprojection error of each view, pixels (same order as ``views``).
        views: names of the views used.
        board: the chessboard.
        model: "standard" or "rational".
        created: ISO time of the calibration.
        dropped_views: views left out as outliers (wrongly detected corners).
        std_devs: one standard deviation of the fitted intrinsics ("fx", "fy", "cx", "cy", "k1",
            ...), from ``cv2.calibrateCameraExtended``; empty when unknown.
    """

    image_size: tuple[int, int]
    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    rms: float
    view_errors: list[float] = field(default_factory=list)
    views: list[str] = field(default_factory=list)
    board: Chessboard = field(default_factory=Chessboard)
    model: str = "standard"
    created: str = ""
    dropped_views: list[str] = field(default_factory=list)
    std_devs: dict[str, float] = field(default_factory=dict)

    @property
    def uncertain(self) -> str | None:
        """A sentence saying which fitted values are uncertain (UNCERTAIN_FX, UNCERTAIN_K1), or None."""
        fx, sd_fx, sd_k1 = self.camera_matrix[0, 0], self.std_devs.get("fx"), self.std_devs.get("k1")
        shaky = []
        if sd_fx is not None and sd_fx > UNCERTAIN_FX * fx:
            shaky.append(f"fx {fx:.1f} ± {sd_fx:.1f} px")
        if sd_k1 is not None and sd_k1 > UNCERTAIN_K1:
            shaky.append(f"k1 {float(self.dist_coeffs[0]):+.3f} ± {sd_k1:.3f}")
        if not shaky:
            return None
        return (f"the fit is uncertain ({', '.join(shaky)}, one standard deviation): add views with the board tilted "
                "at different angles and near the image's corners")

    @property
    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view of the pinhole model, degrees."""
        w, h = self.image_size
        fx, fy = self.camera_matrix[0, 0], self.camera_matrix[1, 1]
        return (math.degrees(2 * math.atan(w / (2 * fx))), math.degrees(2 * math.atan(h / (2 * fy))))

    def scaled_to(self, width: int, height: int) -> CameraCalibration:
        """The calibration for frames resized to ``width`` x ``height`` (same aspect ratio).

        Raises:
            CalibrationError: the aspect ratio differs (a crop cannot be told from a resize).
        """
        w0, h0 = self.image_size
        if (w0, h0) == (width, height):
            return self
        if abs(width / height - w0 / h0) > 0.01:
            raise CalibrationError(f"the camera calibration was made at {w0}x{h0} but the frames are "
                                   f"{width}x{height} (another aspect ratio): calibrate again at this size "
                                   "(vehicle camera calibrate)")
        sx, sy = width / w0, height / h0
        k = self.camera_matrix.astype(np.float64).copy()
        # pixel centres: x' + 0.5 = (x + 0.5) * s
        k[0, 0] *= sx
        k[1, 1] *= sy
        k[0, 2] = (k[0, 2] + 0.5) * sx - 0.5
        k[1, 2] = (k[1, 2] + 0.5) * sy - 0.5
        std = dict(self.std_devs)
        for name, scale in (("fx", sx), ("fy", sy), ("cx", sx), ("cy", sy)):
            if name in std:
                std[name] *= scale
        return CameraCalibration((width, height), k, self.dist_coeffs.copy(), self.rms * sx, list(self.view_errors),
                                 list(self.views), self.board, self.model, self.created, list(self.dropped_views), std)

    # -- storage
    def to_dict(self) -> dict[str, Any]:
        """Plain JSON values."""
        return {"format": FORMAT_VERSION, "image_size": list(self.image_size),
                "camera_matrix": np.asarray(self.camera_matrix, float).round(6).tolist(),
                "dist_coeffs": np.asarray(self.dist_coeffs, float).reshape(-1).round(8).tolist(),
                "model": self.model, "rms_px": round(float(self.rms), 5),
                "view_errors_px": [round(float(e), 5) for e in self.view_errors], "views": list(self.views),
                "dropped_views": list(self.dropped_views),
                "board": {"columns": self.board.columns, "rows": self.board.rows,
                          "square_mm": self.board.square_mm},
                "fov_deg": [round(v, 2) for v in self.fov_deg], "created": self.created,
                "std_devs": {k: float(f"{v:.4g}") for k, v in self.std_devs.items()}}

    def save(self, path: str | Path) -> Path:
        """Write the calibration as JSON (the folder is created); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        tmp.replace(path)  # atomic: a crash never leaves half a calibration
        return path

    @classmethod
    def from_dict(cls, d: dict[str, Any], source: str = "calibration") -> CameraCalibration:
        """Inverse of :meth:`to_dict`; CalibrationError naming ``source`` for anything malformed."""
        try:
            size = tuple(int(v) for v in d["image_size"])
            k = np.asarray(d["camera_matrix"], np.float64)
            dist = np.asarray(d["dist_coeffs"], np.float64).reshape(-1)
            model = str(d.get("model", "standard"))
            b = d.get("board") or {}
            board = Chessboard(int(b.get("columns", 10)), int(b.get("rows", 7)), float(b.get("square_mm", 25.0)))
            out = cls(size, k, dist, float(d.get("rms_px", math.nan)),  # type: ignore[arg-type]
                      [float(e) for e in d.get("view_errors_px", [])], [str(v) for v in d.get("views", [])],
                      board, model, str(d.get("created", "")), [str(v) for v in d.get("dropped_views", [])],
                      {str(k): float(v) for k, v in (d.get("std_devs") or {}).items()})
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f"{source}: not a camera calibration ({type(exc).__name__}: {exc}); "
                                   "make one with `vehicle camera calibrate`") from None
        if len(size) != 2 or min(size) < 1:
            raise CalibrationError(f"{source}: image_size must be [width, height], got {d['image_size']!r}")
        if k.shape != (3, 3) or not np.isfinite(k).all() or k[0, 0] <= 0 or k[1, 1] <= 0:
            raise CalibrationError(f"{source}: camera_matrix must be 3x3 with positive focal lengths")
        if model not in MODELS or dist.size != MODELS[model][0] or not np.isfinite(dist).all():
            raise CalibrationError(f"{source}: model {model!r} needs {MODELS.get(model, ('?',))[0]} finite "
                                   f"dist_coeffs, got {dist.size}")
        return out

    @classmethod
    def load(cls, path: str | Path) -> CameraCalibration:
        """Read a file written by :meth:`save`.

        Raises:
            CalibrationError: missing or malformed file (the message says how to make one).
        """
        path = Path(path)
        if not path.is_file():
            raise CalibrationError(f"no camera calibration at {path}: make one with `vehicle camera calibrate` "
                                   "or set CAMERA_UNDISTORT = False")
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise CalibrationError(f"{path}: cannot read the camera calibration ({exc})") from None
        if not isinstance(data, dict):
            raise CalibrationError(f"{path}: not a camera calibration (expected a JSON object)")
        return cls.from_dict(data, str(path))


@dataclass
class View:
    """Corners found in one image."""

    name: str
    corners: np.ndarray  # (N, 1, 2) float32


def calibrate(views: Sequence[View], board: Chessboard, image_size: tuple[int, int],
              model: str = "standard") -> CameraCalibration:
    """Fit the camera matrix and distortion to the corners of ``views`` (images of ``image_size``
    = (width, height)). A view whose reprojection error is more than OUTLIER_FACTOR times the
    others' median (and over OUTLIER_MIN_PX) is left out and the fit repeated; the names are in
    the result's ``dropped_views``.

    Raises:
        CalibrationError: fewer than :data:`MIN_VIEWS` views, or an unknown model.
    """
    if model not in MODELS:
        raise CalibrationError(f"unknown distortion model {model!r}: use one of {', '.join(MODELS)}")
    if len(views) < MIN_VIEWS:
        raise CalibrationError(f"only {len(views)} view(s) with the whole {board.columns}x{board.rows} board: need "
                               f"at least {MIN_VIEWS}, better {RECOMMENDED_VIEWS}+ from different angles")
    if len(views) < RECOMMENDED_VIEWS:
        logger.warning("calibrating from %d views; %d or more from different angles give a more reliable result",
                       len(views), RECOMMENDED_VIEWS)
    views = list(views)
    dropped: list[str] = []
    while True:
        cal = _fit(views, board, image_size, model)
        errors = np.asarray(cal.view_errors)
        worst = int(np.argmax(errors))
        # a view far worse than the others is a corner detection gone wrong (a grid laid over the
        # wrong squares, seen in steep views), not a property of the lens: leave it out and refit
        limit = max(OUTLIER_MIN_PX, OUTLIER_FACTOR * float(np.median(errors)))
        if errors[worst] <= limit or len(views) <= MIN_VIEWS:
            break
        logger.warning("view %s left out: reprojection error %.2f px, the others' median %.2f px (corners "
                       "detected wrongly?)", views[worst].name, errors[worst], float(np.median(errors)))
        dropped.append(views[worst].name)
        del views[worst]
    cal.dropped_views = dropped
    if cal.uncertain:
        logger.warning("%s", cal.uncertain)
    return cal


#: a view whose reprojection error exceeds this many times the median (and OUTLIER_MIN_PX) is dropped
OUTLIER_FACTOR = 4.0
OUTLIER_MIN_PX = 1.0


def _fit(views: Sequence[View], board: Chessboard, image_size: tuple[int, int], model: str) -> CameraCalibration:
    """One ``cv2.calibrateCamera`` over ``views`` and the per-view RMS reprojection errors."""
    obj = board.object_points()
    object_points = [obj] * len(views)
    image_points = [v.corners.astype(np.float32) for v in views]
    n_coeffs, flags = MODELS[model]
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-9)
    rms, k, dist, rvecs, tvecs, std, _, _ = cv2.calibrateCameraExtended(
        object_points, image_points, tuple(int(v) for v in image_size), None, None, flags=flags, criteria=criteria)
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")[:4 + n_coeffs]
    std_devs = {n: float(v) for n, v in zip(names, np.asarray(std).reshape(-1), strict=False) if np.isfinite(v)}
    errors = []
    for pts, rvec, tvec in zip(image_points, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(obj, rvec, tvec, k, dist)
        errors.append(float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - pts.reshape(-1, 2)) ** 2, axis=1)))))
    return CameraCalibration((int(image_size[0]), int(image_size[1])), k, np.asarray(dist).reshape(-1)[:n_coeffs],
                             float(rms), errors, [v.name for v in views], board, model,
                             datetime.now(UTC).isoformat(timespec="seconds"), std_devs=std_devs)


def image_files(folder: str | Path) -> list[Path]:
    """Image files of ``folder`` in name order (annotated ``corners_*`` copies left out); phone
    photos OpenCV cannot read (HEIC) are included, so that they are reported, not skipped."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CalibrationError(f"no such folder {folder}: give the folder of chessboard photos")
    return sorted(p for p in folder.iterdir()
                  if p.suffix.lower() in IMAGE_SUFFIXES + UNREADABLE_SUFFIXES and not p.name.startswith("corners_"))


def read_rgb(path: Path) -> np.ndarray:
    """An image file as RGB uint8 (CalibrationError if it cannot be read)."""
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise CalibrationError(f"{path}: not an image OpenCV can read")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def write_rgb(path: Path, image: np.ndarray) -> None:
    """Write an RGB image (PNG or JPEG by suffix); OSError naming the path when it cannot."""
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        raise OSError(errno.EINVAL, f"not an image file name: use .png or .jpg (one of {', '.join(IMAGE_SUFFIXES)})",
                      str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        written = cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    except cv2.error as exc:  # OpenCV raises for some formats instead of returning False
        raise OSError(errno.EIO, f"the image could not be written ({str(exc).strip().splitlines()[-1]})",
                      str(path)) from None
    if not written:
        raise OSError(errno.EIO, "the image could not be written", str(path))


def is_novel(corners: np.ndarray, kept: Sequence[np.ndarray], min_move: float, diagonal: float) -> bool:
    """Whether ``corners`` moved, on average, at least ``min_move`` x ``diagonal`` pixels from each of
    the ``kept`` views' corners (all (N, 2) or (N, 1, 2)): a new position or angle of the board."""
    pts = corners.reshape(-1, 2)
    return all(np.linalg.norm(pts - k.reshape(-1, 2), axis=1).mean() >= min_move * diagonal for k in kept)


@dataclass
class ViewSet:
    """What :func:`collect_views` found in a set of images.

    Attributes:
        views: the views used (board found, not a near-duplicate), in order.
        rejected: names of images without the whole board.
        duplicates: names of near-duplicates of an earlier view (left out).
        unreadable: names of files that are not images OpenCV reads (left out).
        size: (width, height) of the images, None without any.
    """

    views: list[View]
    rejected: list[str] = field(default_factory=list)
    duplicates: list[str] = field(default_factory=list)
    unreadable: list[str] = field(default_factory=list)
    size: tuple[int, int] | None = None


def collect_views(images: Iterable[tuple[str, np.ndarray | None]], board: Chessboard,
                  annotate_to: Path | None = None, min_move: float = DUPLICATE_MOVE) -> ViewSet:
    """Corners of every named image (None: a file that could not be read). A view whose corners lie
    within ``min_move`` of the image diagonal of an earlier view's is a near-duplicate and left out
    (the live collector's test, :func:`is_novel`).

    Raises:
        CalibrationError: images of different sizes.
        OSError: an annotated copy cannot be written to ``annotate_to``.
    """
    found = ViewSet([])
    for name, image in images:
        if image is None:
            found.unreadable.append(name)
            continue
        this = (int(image.shape[1]), int(image.shape[0]))
        if found.size is None:
            found.size = this
        elif this != found.size:
            size = found.size
            raise CalibrationError(f"{name} is {this[0]}x{this[1]} but the first image is {size[0]}x{size[1]}: "
                                   "calibrate with images of one size (the size the car's camera delivers)")
        corners = find_corners(image, board)
        if corners is None:
            found.rejected.append(name)
            continue
        if not is_novel(corners, [v.corners for v in found.views], min_move, math.hypot(*this)):
            found.duplicates.append(name)
            continue
        found.views.append(View(name, corners))
        if annotate_to is not None:
            write_rgb(annotate_to / f"corners_{Path(name).stem}.png", draw_corners(image, board, corners))
    if found.duplicates:
        logger.warning("left out as near-duplicates of an earlier view (the board moved less than %.0f %% of the "
                       "image diagonal): %s", 100 * min_move, ", ".join(found.duplicates))
    return found


@dataclass
class FolderResult:
    """What :func:`calibrate_files` found: the calibration and the images left out, by reason."""

    calibration: CameraCalibration
    rejected: list[str]
    duplicates: list[str] = field(default_factory=list)
    unreadable: list[str] = field(default_factory=list)


def _read_or_none(files: Sequence[Path]) -> Iterable[tuple[str, np.ndarray | None]]:
    for path in files:
        try:
            yield path.name, read_rgb(path)
        except CalibrationError:
            logger.warning("%s: not an image OpenCV can read, left out", path)
            yield path.name, None


def calibrate_files(files: Sequence[Path], board: Chessboard, *, model: str = "standard",
                    annotate_to: str | Path | None = None, source: str = "the images") -> FolderResult:
    """Calibrate from chessboard photos ``files`` (the thesis's workflow).

    Args:
        files: images of the printed board from different angles, all of one size. Files that are
            not images OpenCV reads (HEIC phone photos, a broken file) are listed and left out.
        board: the board's inner corner counts and square size.
        model: "standard" or "rational".
        annotate_to: folder for ``corners_NAME.png`` copies with the detected corners drawn.
        source: what the files are, for messages (e.g. the folder).

    Raises:
        CalibrationError: no images, images of several sizes, too few views with a board.
        OSError: an annotated copy cannot be written.
    """
    if not files:
        raise CalibrationError(f"no images ({', '.join(IMAGE_SUFFIXES)}) in {source}")
    t0 = time.perf_counter()
    found = collect_views(_read_or_none(files), board, Path(annotate_to) if annotate_to is not None else None)
    views = found.views
    logger.info("chessboard found in %d of %d images of %s (%.1f s)", len(views) + len(found.duplicates), len(files),
                source, time.perf_counter() - t0)
    if len(views) < MIN_VIEWS:
        why = (f"the {board.columns}x{board.rows} inner-corner board was found in only "
               f"{len(views) + len(found.duplicates)} of {len(files)} images of {source}")
        if found.duplicates:
            why += f" ({len(found.duplicates)} of them near-duplicates)"
        if found.unreadable:
            why += f"; unreadable: {', '.join(found.unreadable)}{unreadable_hint(found.unreadable)}"
        raise CalibrationError(f"{why}: check the corner counts (CAMERA_CALIB_BOARD; inner corners, where four squares "
                               "meet, not squares) and that the whole board is in view and sharp")
    assert found.size is not None
    return FolderResult(calibrate(views, board, found.size, model), found.rejected, found.duplicates,
                        found.unreadable)


def calibrate_folder(folder: str | Path, board: Chessboard, *, model: str = "standard",
                     annotate_to: str | Path | None = None) -> FolderResult:
    """Calibrate from the chessboard photos in ``folder`` (see :func:`calibrate_files`)."""
    return calibrate_files(image_files(folder), board, model=model, annotate_to=annotate_to, source=str(folder))


def unreadable_hint(names: Sequence[str]) -> str:
    """A hint for files OpenCV cannot read: HEIC/HEIF phone photos need converting."""
    if any(Path(n).suffix.lower() in UNREADABLE_SUFFIXES for n in names):
        return " (HEIC/HEIF phone photos: export them as JPEG, or set the phone's camera to 'most compatible')"
    return ""


class ChessboardCollector:
    """Part: collect chessboard views from a live camera for calibration.

    Input ``cam/image_array``; outputs (annotated frame, views collected, board seen now). Each
    frame is searched (with OpenCV's fast check, so frames without a board cost little); a view is
    kept when the board is seen and differs enough from every kept view (its corners moved by at
    least ``min_move`` of the image diagonal on average, i.e. a new position or angle) and
    ``min_interval`` seconds passed since the last one. Kept views are written to ``folder`` as
    ``view_NNN.png`` (the raw frame, what :func:`calibrate_folder` reads) and
    ``corners_NNN.png`` (with the corners drawn, for the user to check).

    Args:
        folder: where views are written (created).
        board: the chessboard.
        target: views wanted; :attr:`done` turns True when reached.
        min_move: least mean corner displacement to a kept view, fraction of the image diagonal.
        min_interval: least seconds between two kept views.
        clock: seconds (injectable for tests).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("calib/image", "calib/views", "calib/found")

    def __init__(self, folder: str | Path, board: Chessboard, *, target: int = 15, min_move: float = 0.05,
                 min_interval: float = 0.5, clock: Any = time.monotonic) -> None:
        if target < MIN_VIEWS:
            raise CalibrationError(f"collect at least {MIN_VIEWS} views (better {RECOMMENDED_VIEWS}+), got {target}")
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.board = board
        self.target = int(target)
        self.min_move = float(min_move)
        self.min_interval = float(min_interval)
        self.clock = clock
        self.kept: list[np.ndarray] = []
        #: the view files this collector wrote (what to calibrate from: not older runs' views)
        self.written: list[Path] = []
        self._last = -math.inf
        self._index = len(list(self.folder.glob("view_*.png")))  # continue numbering in a used folder

    @property
    def done(self) -> bool:
        """Whether ``target`` views were collected."""
        return len(self.kept) >= self.target

    def run(self, image: np.ndarray | None) -> tuple[np.ndarray | None, int, bool]:
        """One frame: (frame with corners drawn, views kept so far, whether the board is in view)."""
        if image is None:
            return None, len(self.kept), False
        corners = find_corners(image, self.board, fast_check=True)
        shown = draw_corners(image, self.board, corners)
        if corners is None:
            return shown, len(self.kept), False
        now = self.clock()
        diag = math.hypot(image.shape[0], image.shape[1])
        novel = is_novel(corners, self.kept, self.min_move, diag)
        if not self.done and now - self._last >= self.min_interval and novel:
            self._index += 1
            write_rgb(self.folder / f"view_{self._index:03d}.png", image)
            self.written.append(self.folder / f"view_{self._index:03d}.png")
            write_rgb(self.folder / f"corners_{self._index:03d}.png", shown)
            self.kept.append(corners.reshape(-1, 2).copy())
            self._last = now
            logger.info("calibration view %d of %d kept (%s)", len(self.kept), self.target,
                        self.folder / f"view_{self._index:03d}.png")
        return shown, len(self.kept), True
