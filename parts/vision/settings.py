"""Settings of the vision parts: lens calibration, undistortion and lane extraction.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated, Literal

from vehicle.config_checks import Length, Range, Rule, ordered_pair

# == Vision ==

# Remove lens distortion from every camera frame with the car's calibration (Undistort part, one
# precomputed remap per frame). Make the calibration first: `vehicle camera calibrate`.
CAMERA_UNDISTORT: bool = False
# The camera calibration file (camera matrix, distortion coefficients, reprojection error),
# relative to CAR_PATH; written by `vehicle camera calibrate`.
CAMERA_CALIBRATION_PATH: str = "camera_calibration.json"
# Undistorted view: 0 = zoom so that only valid pixels show (no black border), 1 = keep every
# source pixel (black corners with a wide lens).
CAMERA_UNDISTORT_ALPHA: Annotated[float, Range(0, 1)] = 0.0
# Chessboard used for calibration: inner corners per row and per column (where four squares
# meet; the thesis's board: 10 x 7, an 11 x 8 squares print). The counts must differ.
CAMERA_CALIB_BOARD: Annotated[tuple[int, int], Range(2, 100)] = (10, 7)
# Side of one chessboard square as printed, in millimetres (only the board poses depend on it).
CAMERA_CALIB_SQUARE_MM: Annotated[float, Range(0, 1000, lo_open=True, unit="mm")] = 25.0
# Distortion model fitted: "standard" = k1, k2, p1, p2, k3 (the thesis's code); "rational" adds
# k4..k6 for very wide lenses (the thesis's equation 6.3).
CAMERA_CALIB_MODEL: Literal["standard", "rational"] = "standard"
# Lane extraction (thesis chapter 7), used by the `lanes` model type and the LaneExtraction part:
# the region of interest on the road as four (x, y) pixel points of a LANE_POINTS_SIZE frame,
# bottom left, top left, top right, bottom right. Default: the thesis's points for its 320x180
# simulator camera; tune them for your camera with `vehicle lanes preview`.
LANE_SOURCE_POINTS: Annotated[list[tuple[float, float]], Length(min=4, max=4), Range(unit="pixels")] = [
    (0.0, 180.0), (112.5, 87.5), (200.0, 87.5), (307.5, 180.0)]
# Where the source points go in the bird's-eye image, same order and frame size (the thesis's).
LANE_DESTINATION_POINTS: Annotated[list[tuple[float, float]], Length(min=4, max=4), Range(unit="pixels")] = [
    (80.0, 180.0), (80.0, 0.25), (230.0, 0.25), (230.0, 180.0)]
# (width, height) of the frame the lane points are given for; they are scaled to the real
# camera size (same field of view assumed).
LANE_POINTS_SIZE: Annotated[tuple[int, int], Range(8, 8192, unit="pixels")] = (320, 180)
# HLS saturation range of lane pixels after the warp: S in (low, high] (thesis: 65, 255, i.e.
# S > 65); None leaves the S threshold out (then LANE_COLOR_MASK must be set).
LANE_S_THRESHOLD: Annotated[tuple[int, int] | None, Range(0, 255)] = (65, 255)
# Also count white and/or yellow pixels as lane pixels: white tape has almost no saturation, so
# the S threshold alone misses it. None, "white", "yellow" or "white_yellow".
LANE_COLOR_MASK: Literal["white", "yellow", "white_yellow"] | None = None
# HLS lightness (0-255, after LANE_NORMALIZE) from which a pixel is white (LANE_COLOR_MASK).
LANE_WHITE_MIN_LIGHTNESS: Annotated[int, Range(0, 255)] = 200
# OpenCV hue range (0-180) of yellow lane pixels (LANE_COLOR_MASK).
LANE_YELLOW_HUE: Annotated[tuple[int, int], Range(0, 180)] = (15, 35)
# Least HLS saturation (0-255) of a yellow lane pixel (LANE_COLOR_MASK).
LANE_YELLOW_MIN_SATURATION: Annotated[int, Range(0, 255)] = 80
# Stretch the warped image to the full 0-255 range before thresholding (the thesis does).
LANE_NORMALIZE: bool = True


#: rules across this module's settings, run after every setting passed its own range
RULES: tuple[Rule, ...] = (ordered_pair("LANE_YELLOW_HUE"),)
