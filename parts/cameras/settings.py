"""Settings of the camera family (CAMERA_TYPE picks a row of :data:`parts.cameras.registry.CAMERAS`).

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated, Literal

from parts.cameras.registry import CAMERAS
from vehicle.config_checks import Range
from vehicle.settings import DRIVE_LOOP_HZ

# == Camera ==

# Width in pixels of the images the camera delivers and the tub records.
IMAGE_W: Annotated[int, Range(8, 4096, unit="pixels")] = 160
# Height in pixels of the camera images.
IMAGE_H: Annotated[int, Range(8, 4096, unit="pixels")] = 120
# Colour channels of the camera images (3 = RGB).
IMAGE_DEPTH: Literal[1, 3] = 3
# Frames per second asked of the camera; follows the loop rate unless set.
CAMERA_FRAMERATE: Annotated[int, Range(1, 1000, unit="Hz")] = DRIVE_LOOP_HZ
# Camera driver: "PICAM" (Raspberry Pi camera via picamera2), "CVCAM" or "WEBCAM" (USB camera via
# OpenCV/V4L2), "CSIC" (Jetson CSI camera via GStreamer), "VIDEO" (replays CAMERA_VIDEO_PATH),
# "IMAGE_LIST" (replays CAMERA_IMAGE_PATH: a folder of images or a tub), "MOCK" (a generated moving
# pattern: no hardware).
CAMERA_TYPE: Annotated[str, CAMERAS.choice()] = "PICAM"
# Which camera: N of /dev/videoN (CVCAM, WEBCAM), the sensor id (CSIC) or camera number (PICAM).
CAMERA_INDEX: Annotated[int, Range(0)] = 0
# Flip the image upside down (a camera mounted the other way round).
CAMERA_VFLIP: bool = False
# Mirror the image left-right.
CAMERA_HFLIP: bool = False
# No new frame for this many seconds: cam/ok goes False, an error is logged and a driving pilot is
# disengaged (user mode, throttle 0). A few frame periods; USB cameras stall for ~0.3 s at times.
CAMERA_TIMEOUT_S: Annotated[float, Range(0.1, 5, unit="s")] = 1.0
# CVCAM/WEBCAM: pixel format asked of the camera ("MJPG" gives full frame rates over USB 2;
# "YUYV" for cameras without MJPG); None = the driver's default.
CAMERA_FOURCC: str | None = "MJPG"
# CSIC: width of the sensor mode captured before the GPU scales it to IMAGE_W x IMAGE_H (IMX219:
# 1280x720 at 60, 1640x1232 at 30 frames per second).
CSIC_CAPTURE_WIDTH: Annotated[int, Range(8, 8192, unit="pixels")] = 1280
# CSIC: height of the captured sensor mode.
CSIC_CAPTURE_HEIGHT: Annotated[int, Range(8, 8192, unit="pixels")] = 720
# CSIC: frame rate of the captured sensor mode (must be one the sensor offers at that size).
CSIC_CAPTURE_FPS: Annotated[int, Range(1, 1000, unit="Hz")] = 60
# VIDEO: video file replayed as the camera, paced at CAMERA_FRAMERATE (relative to CAR_PATH).
CAMERA_VIDEO_PATH: str | None = None
# IMAGE_LIST: folder of images, or a tub, replayed as the camera in natural name order (relative to
# CAR_PATH).
CAMERA_IMAGE_PATH: str | None = None
# VIDEO / IMAGE_LIST: start again after the last frame (False: the camera stops and cam/ok goes
# False after CAMERA_TIMEOUT_S).
CAMERA_REPLAY_LOOP: bool = True
