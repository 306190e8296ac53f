"""Raspberry Pi CSI camera through picamera2 (libcamera); picamera2 is imported when it opens."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from parts.cameras.base import CameraError
from vehicle.config import check_settings

logger = logging.getLogger(__name__)


class PiCamera2Source:
    """A Pi camera (v1/v2/v3/HQ) via picamera2, delivering RGB frames of ``width``×``height``.

    picamera2's format names are inverted: "BGR888" yields an RGB-ordered array, which is what we
    want. libcamera may align the size (a Pi 5 turns 160×120 into 128×120): the actual size is
    logged and :class:`~parts.cameras.base.Camera` resizes to the asked size.
    Install: ``sudo apt install python3-picamera2`` and a venv made with ``--system-site-packages``.
    """

    paced = False

    def __init__(self, width: int = 160, height: int = 120, fps: int = 20, camera_num: int = 0,
                 picamera2_class: Any = None) -> None:
        check_settings(IMAGE_W=width, IMAGE_H=height, CAMERA_FRAMERATE=fps, CAMERA_INDEX=camera_num)
        self.width, self.height, self.fps = width, height, fps
        self.camera_num = camera_num
        self._cls = picamera2_class
        self._cam: Any = None
        self.name = f"picamera2 {camera_num}"

    @classmethod
    def from_config(cls, cfg: Any) -> PiCamera2Source:
        """CAMERA_TYPE = "PICAM": camera CAMERA_INDEX at IMAGE_W x IMAGE_H, CAMERA_FRAMERATE."""
        return cls(cfg.IMAGE_W, cfg.IMAGE_H, cfg.CAMERA_FRAMERATE, cfg.CAMERA_INDEX)

    def open(self) -> None:
        """Configure and start the camera."""
        cls = self._cls
        if cls is None:
            try:
                from picamera2 import Picamera2 as cls  # noqa: N813 - library class name
            except ImportError as exc:
                raise CameraError(
                    "CAMERA_TYPE 'PICAM' needs picamera2: `sudo apt install python3-picamera2` and a "
                    "virtual environment created with --system-site-packages") from exc
        try:
            cam = cls(self.camera_num)
            frame_us = int(1_000_000 / self.fps)
            config = cam.create_preview_configuration(
                main={"size": (self.width, self.height), "format": "BGR888"},
                controls={"FrameDurationLimits": (frame_us, frame_us)}, queue=False)
            cam.configure(config)
            cam.start()
        except Exception as exc:  # libcamera raises RuntimeError/IndexError for a missing camera
            raise CameraError(f"cannot start {self.name}: {exc}. Check the ribbon cable and that "
                              "`rpicam-hello --list-cameras` (or `libcamera-hello`) lists it") from exc
        self._cam = cam
        size = config.get("main", {}).get("size") if isinstance(config, dict) else None
        logger.info("picamera2 started, main stream %s", size)

    def read(self) -> np.ndarray | None:
        """The next RGB frame (blocks until the camera delivers it)."""
        if self._cam is None:
            raise CameraError(f"{self.name} is not open")
        frame = self._cam.capture_array("main")
        if frame is None:
            return None
        return frame[:, :, :3] if frame.ndim == 3 and frame.shape[2] == 4 else frame

    def close(self) -> None:
        """Stop and close the camera."""
        cam, self._cam = self._cam, None
        if cam is not None:
            try:
                cam.stop()
            finally:
                cam.close()
