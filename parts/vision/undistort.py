"""The Undistort part: removes lens distortion from every camera frame with one precomputed remap.

The thesis (§6.2, Appendix 1.3) calls ``cv2.undistort`` per frame, which recomputes the
undistortion map every time. Here the map is computed once per frame size
(``cv2.initUndistortRectifyMap``, fixed-point maps) and each frame costs one ``cv2.remap``.

``alpha`` chooses the output camera (as ``cv2.getOptimalNewCameraMatrix``, computed with a
converging inverse of the lens model, :mod:`parts.vision.lens`): 0 keeps only valid pixels (the
image is zoomed so no black border shows; what a pilot should see), 1 keeps every source pixel
(black corners appear with barrel distortion).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any, ClassVar

import cv2
import numpy as np

from parts.vision.calibration import CalibrationError, CameraCalibration
from parts.vision.lens import LensError, new_camera_matrix

logger = logging.getLogger(__name__)


class Undistort:
    """Part: ``cam/image_array`` -> the same frame without lens distortion (same size).

    Args:
        calibration: a :class:`CameraCalibration`, or the path of its JSON file.
        alpha: 0 (crop to valid pixels) .. 1 (keep all source pixels).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array",)

    def __init__(self, calibration: CameraCalibration | str | Path, alpha: float = 0.0) -> None:
        if not isinstance(calibration, CameraCalibration):
            calibration = CameraCalibration.load(calibration)
        if not 0.0 <= alpha <= 1.0:
            raise CalibrationError(f"undistort alpha {alpha} out of range: use 0 (crop) .. 1 (keep all)")
        self.calibration = calibration
        self.alpha = float(alpha)
        self._maps: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        self._new_k: dict[tuple[int, int], np.ndarray] = {}
        #: camera matrix of the undistorted frames of the last size mapped (see :meth:`output_camera_matrix`)
        self.new_camera_matrix: np.ndarray | None = None

    @classmethod
    def from_config(cls, cfg: Any) -> Undistort:
        """An Undistort from CAMERA_CALIBRATION_PATH and CAMERA_UNDISTORT_ALPHA."""
        return cls(cfg.path("CAMERA_CALIBRATION_PATH"), cfg.CAMERA_UNDISTORT_ALPHA)

    def maps(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """The fixed-point remap tables for frames of ``width`` x ``height`` (computed once)."""
        key = (width, height)
        if key not in self._maps:
            cal = self.calibration.scaled_to(width, height)
            try:
                new_k = new_camera_matrix(cal.camera_matrix, cal.dist_coeffs, width, height, self.alpha)
            except LensError as exc:
                raise CalibrationError(f"the camera calibration cannot be used: {exc}; calibrate again") from None
            self.new_camera_matrix = self._new_k[key] = new_k
            self._maps[key] = cv2.initUndistortRectifyMap(cal.camera_matrix, cal.dist_coeffs, None, new_k,
                                                          (width, height), cv2.CV_16SC2)
            logger.info("undistort: maps for %dx%d frames (alpha %.2f)", width, height, self.alpha)
        return self._maps[key]

    def output_camera_matrix(self, width: int, height: int) -> np.ndarray:
        """The camera matrix of the undistorted ``width`` x ``height`` frames: they are the images of
        an ideal pinhole with this matrix and no distortion (what lane-extraction points of a
        undistorting car are computed with)."""
        self.maps(width, height)
        return self._new_k[(width, height)].copy()

    def undistort(self, image: np.ndarray) -> np.ndarray:
        """A new undistorted copy of ``image`` (HxWx3 or HxW uint8)."""
        m1, m2 = self.maps(image.shape[1], image.shape[0])
        return cv2.remap(image, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

    def run(self, image: np.ndarray | None) -> np.ndarray | None:
        """Part entry point; None (no frame yet) passes through."""
        if image is None:
            return None
        return self.undistort(image)
