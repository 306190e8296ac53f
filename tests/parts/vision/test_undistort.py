"""The Undistort part: straightens what the simulated lens bent, at any frame size of the same aspect."""

from __future__ import annotations

import numpy as np
import pytest

from parts.sim.camera import PinholeCamera
from parts.sim.chessboard import random_board_poses, render_board_view
from parts.vision.calibration import CalibrationError, CameraCalibration, Chessboard, find_corners
from parts.vision.undistort import Undistort
from vehicle.config import Config

DIST = (-0.25, 0.07, 0.001, -0.0015, 0.0)


def _straightness(corners: np.ndarray, rows: int, columns: int) -> float:
    """Largest distance (px) of a corner from the straight line fitted through its row."""
    worst = 0.0
    for row in corners.reshape(rows, columns, 2):
        centre = row.mean(axis=0)
        _, _, vt = np.linalg.svd(row - centre)
        worst = max(worst, float(np.abs((row - centre) @ vt[1]).max()))
    return worst


def test_undistorted_board_rows_are_straight_again(tmp_path):
    camera = PinholeCamera(320, 240, distortion=DIST)
    cal = CameraCalibration((320, 240), camera.intrinsics.copy(), np.array(DIST), 0.1)
    path = cal.save(tmp_path / "camera_calibration.json")
    part = Undistort(path, alpha=0.0)
    board = Chessboard(10, 7)
    bent, straight = [], []
    for r, t in random_board_poses(camera, 10, 7, 4, seed=3, max_tilt_deg=20):
        image = render_board_view(camera, 10, 7, r, t)
        out = part.run(image)
        assert out.shape == image.shape and out.dtype == np.uint8
        before, after = find_corners(image, board), find_corners(out, board)
        assert before is not None
        if after is not None:  # alpha 0 zooms in: a board near the edge may leave the view
            bent.append(_straightness(before, 7, 10))
            straight.append(_straightness(after, 7, 10))
    assert len(straight) >= 2
    assert max(straight) < 0.35 < min(bent)  # the lens bows the rows; undistorted they are lines
    assert part.run(None) is None


def test_frames_of_another_size_are_undistorted_with_the_scaled_calibration_and_other_aspects_fail():
    """A 320x240 calibration undistorts 640x480 frames of the same lens: the board's rows come out
    straight (as at the calibration's own size)."""
    cal = CameraCalibration((320, 240), PinholeCamera(320, 240, distortion=DIST).intrinsics.copy(), np.array(DIST), 0.1)
    part = Undistort(cal, alpha=0.0)
    camera = PinholeCamera(640, 480, distortion=DIST)  # the same lens, frames twice the size
    board = Chessboard(10, 7)
    bent, straight = [], []
    for r, t in random_board_poses(camera, 10, 7, 4, seed=3, max_tilt_deg=20):
        image = render_board_view(camera, 10, 7, r, t)
        out = part.run(image)
        assert out.shape == (480, 640, 3)
        before, after = find_corners(image, board), find_corners(out, board)
        assert before is not None
        if after is not None:
            bent.append(_straightness(before, 7, 10))
            straight.append(_straightness(after, 7, 10))
    assert set(part._maps) == {(640, 480)}
    assert len(straight) >= 2
    assert max(straight) < 0.35 < min(bent)
    with pytest.raises(CalibrationError, match="aspect ratio"):
        part.run(np.zeros((90, 160, 3), np.uint8))
    with pytest.raises(CalibrationError, match="alpha"):
        Undistort(cal, alpha=2.0)


def test_from_config_reads_the_car_folder_and_says_how_to_make_a_calibration(tmp_path):
    cfg = Config.defaults(CAR_PATH=str(tmp_path), CAMERA_UNDISTORT=True)
    with pytest.raises(CalibrationError, match="vehicle camera calibrate"):
        Undistort.from_config(cfg)
    CameraCalibration((160, 120), PinholeCamera(160, 120).intrinsics, np.zeros(5), 0.1).save(
        tmp_path / "camera_calibration.json")
    assert Undistort.from_config(cfg).calibration.image_size == (160, 120)
