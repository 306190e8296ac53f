"""Memory keys of the vision parts: lane images and camera calibration.

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "vision/lane_image": KeyInfo("ndarray HxW uint8", "binary lane image (bird's-eye, 255 = lane pixel)"),
    "calib/image": KeyInfo("ndarray HxWx3 uint8 RGB", "camera frame with the chessboard corners drawn"),
    "calib/views": KeyInfo("int", "chessboard views kept for camera calibration"),
    "calib/found": KeyInfo("bool", "whether the chessboard is in the current frame"),
}
