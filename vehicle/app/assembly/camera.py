"""Assembly of the camera: the frame source chosen by CAMERA_TYPE, wrapped in the threaded Camera."""

from __future__ import annotations

import logging
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def make_frame_source(cfg: Config) -> Any:
    """The frame source for ``cfg.CAMERA_TYPE`` (not opened yet)."""
    kind = cfg.CAMERA_TYPE
    w, h, fps = cfg.IMAGE_W, cfg.IMAGE_H, cfg.CAMERA_FRAMERATE
    if kind in ("CVCAM", "WEBCAM"):
        from parts.cameras.opencv import OpenCVSource

        return OpenCVSource(cfg.CAMERA_INDEX, w, h, fps, fourcc=cfg.CAMERA_FOURCC)
    if kind == "CSIC":
        from parts.cameras.opencv import CSISource, flip_method_for

        return CSISource(w, h, cfg.CSIC_CAPTURE_FPS, cfg.CAMERA_INDEX, cfg.CSIC_CAPTURE_WIDTH,
                         cfg.CSIC_CAPTURE_HEIGHT, flip_method_for(cfg.CAMERA_VFLIP, cfg.CAMERA_HFLIP))
    if kind == "PICAM":
        from parts.cameras.picam import PiCamera2Source

        return PiCamera2Source(w, h, fps, cfg.CAMERA_INDEX)
    if kind == "VIDEO":
        from parts.cameras.replay import VideoFileSource

        if not cfg.CAMERA_VIDEO_PATH:
            raise UserError('CAMERA_TYPE = "VIDEO" needs CAMERA_VIDEO_PATH = "path/to/video.mp4" in myconfig.py')
        return VideoFileSource(cfg.path("CAMERA_VIDEO_PATH"), loop=cfg.CAMERA_REPLAY_LOOP)
    if kind == "IMAGE_LIST":
        from parts.cameras.replay import ImageFolderSource

        if not cfg.CAMERA_IMAGE_PATH:
            raise UserError('CAMERA_TYPE = "IMAGE_LIST" needs CAMERA_IMAGE_PATH = "folder/or/tub" in myconfig.py')
        return ImageFolderSource(cfg.path("CAMERA_IMAGE_PATH"), loop=cfg.CAMERA_REPLAY_LOOP)
    if kind == "MOCK":
        from parts.cameras.mock import MockSource

        return MockSource(w, h)
    raise UserError(f"unknown CAMERA_TYPE {kind!r}; use PICAM, CVCAM, WEBCAM, CSIC, VIDEO, IMAGE_LIST or MOCK")


def add_camera(V: Any, cfg: Config) -> Any:
    """Add the camera (threaded): -> ``cam/image_array``, ``cam/timestamp``, ``cam/ok``.

    ``cam/ok`` is False until the first frame and whenever frames stop;
    :func:`vehicle.app.assembly.drive.add_camera_watchdog` uses it to keep pilots from driving blind.
    The CSI pipeline flips on the GPU, every other source is flipped by the Camera part.
    """
    from parts.cameras.base import Camera

    source = make_frame_source(cfg)
    gpu_flips = cfg.CAMERA_TYPE == "CSIC"
    camera = Camera(source, cfg.IMAGE_W, cfg.IMAGE_H, fps=cfg.CAMERA_FRAMERATE,
                    vflip=cfg.CAMERA_VFLIP and not gpu_flips, hflip=cfg.CAMERA_HFLIP and not gpu_flips,
                    timeout_s=cfg.CAMERA_TIMEOUT_S)
    V.add(camera, threaded=True)
    logger.info("camera: %s (%dx%d)", cfg.CAMERA_TYPE, cfg.IMAGE_W, cfg.IMAGE_H)
    add_undistort(V, cfg)
    return camera


def make_undistort(cfg: Config, frame_size: tuple[int, int] | None = None,
                   size_settings: str = "IMAGE_W x IMAGE_H") -> Any:
    """With CAMERA_UNDISTORT: the Undistort part with the car's calibration (CAMERA_CALIBRATION_PATH),
    its remap tables made for the frames the camera delivers; None when off.

    ``frame_size`` is the (width, height) of those frames (default IMAGE_W x IMAGE_H), named by the
    settings ``size_settings``: a calibration that cannot serve them (another aspect ratio) is an
    error here, not a failure at the first frame.

    Raises:
        CalibrationError: no usable calibration file (the message says how to make one).
        UserError: the calibration does not fit the frame size.
    """
    if not cfg.CAMERA_UNDISTORT:
        return None
    from parts.vision.calibration import CalibrationError
    from parts.vision.undistort import Undistort

    part = Undistort.from_config(cfg)
    width, height = frame_size if frame_size is not None else (cfg.IMAGE_W, cfg.IMAGE_H)
    try:
        part.maps(width, height)
    except CalibrationError as exc:
        raise UserError(f"{cfg.path('CAMERA_CALIBRATION_PATH')}: {exc}; the frames' size is {size_settings} "
                        f"in myconfig.py") from None
    return part


def add_undistort(V: Any, cfg: Config, frame_size: tuple[int, int] | None = None,
                  size_settings: str = "IMAGE_W x IMAGE_H") -> Any:
    """With CAMERA_UNDISTORT: add the Undistort part (``cam/image_array`` in place) right after the
    camera (see :func:`make_undistort`). Returns it, or None when off."""
    part = make_undistort(cfg, frame_size, size_settings)
    if part is None:
        return None
    V.add(part)
    cal = part.calibration
    logger.info("camera: undistorting with %s (made at %dx%d, RMS %.2f px)", cfg.path("CAMERA_CALIBRATION_PATH"),
                *cal.image_size, cal.rms)
    return part
