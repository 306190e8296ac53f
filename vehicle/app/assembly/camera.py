"""Assembly of the camera: the frame source CAMERA_TYPE picks in the camera table, wrapped in the threaded
Camera."""

from __future__ import annotations

import logging
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def make_frame_source(cfg: Config) -> Any:
    """The frame source for ``cfg.CAMERA_TYPE`` (not opened yet): its row of the camera table."""
    from parts.cameras.registry import CAMERAS

    return CAMERAS.from_config(cfg)


def add_camera(V: Any, cfg: Config) -> Any:
    """Add the camera (threaded): -> ``cam/image_array``, ``cam/timestamp``, ``cam/ok``.

    ``cam/ok`` is False until the first frame and whenever frames stop;
    :func:`vehicle.app.assembly.drive.add_camera_watchdog` uses it to keep pilots from driving blind.
    The CSI pipeline flips on the GPU, every other source is flipped by the Camera part.
    """
    from parts.cameras.base import Camera

    source = make_frame_source(cfg)
    gpu_flips = getattr(source, "flips_itself", False)
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
