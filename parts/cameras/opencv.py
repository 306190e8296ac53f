"""OpenCV frame sources: USB/UVC cameras on V4L2, and the Jetson CSI camera through GStreamer."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np

from parts.cameras.base import CameraError
from vehicle.config import check_settings

logger = logging.getLogger(__name__)

# cv2 property ids (stable across OpenCV 4/5): used so the fake capture in tests needs no cv2
CAP_PROP_FRAME_WIDTH = 3
CAP_PROP_FRAME_HEIGHT = 4
CAP_PROP_FPS = 5
CAP_PROP_FOURCC = 6
CAP_PROP_BUFFERSIZE = 38
CAP_V4L2 = 200
CAP_GSTREAMER = 1800


def fourcc_code(fourcc: str) -> int:
    """The int OpenCV uses for a four-character code such as ``MJPG``."""
    if len(fourcc) != 4:
        raise ValueError(f"FOURCC {fourcc!r} must be four characters, e.g. 'MJPG' or 'YUYV'")
    return sum(ord(c) << (8 * i) for i, c in enumerate(fourcc))


class OpenCVSource:
    """A camera opened with ``cv2.VideoCapture`` (V4L2 by default), delivering RGB frames.

    Asks for MJPG at ``width``×``height``@``fps`` with a driver buffer of one frame (so a read
    returns a fresh frame, not one queued long ago), and logs what the driver actually chose.

    Args:
        device: camera index (``/dev/videoN``), device path or a GStreamer pipeline string.
        capture_factory: ``cv2.VideoCapture`` (tests pass a fake with the same methods).
    """

    paced = False

    def __init__(self, device: int | str = 0, width: int = 160, height: int = 120, fps: int = 20,
                 backend: int = CAP_V4L2, fourcc: str | None = "MJPG",
                 capture_factory: Callable[..., Any] | None = None) -> None:
        # a CSI camera's pipeline comes here with its CSIC_CAPTURE_FPS, checked first (the same bound)
        check_settings(IMAGE_W=width, IMAGE_H=height, CAMERA_FRAMERATE=fps,
                       **({"CAMERA_INDEX": device} if isinstance(device, int) else {}))
        self.device = device
        self.width, self.height, self.fps = width, height, fps
        self.backend = backend
        self.fourcc = fourcc
        self._factory = capture_factory
        self._cap: Any = None
        self._cv2: Any = None
        self.failed_reads = 0
        self.name = f"/dev/video{device}" if isinstance(device, int) else str(device)[:40]

    @classmethod
    def from_config(cls, cfg: Any) -> OpenCVSource:
        """CAMERA_TYPE = "CVCAM" or "WEBCAM": /dev/video<CAMERA_INDEX> at IMAGE_W x IMAGE_H."""
        return cls(cfg.CAMERA_INDEX, cfg.IMAGE_W, cfg.IMAGE_H, cfg.CAMERA_FRAMERATE, fourcc=cfg.CAMERA_FOURCC)

    def _set(self, prop: int, value: float, what: str) -> None:
        if not self._cap.set(prop, value):
            logger.info("camera %s: the driver refused %s = %s", self.name, what, value)

    def open(self) -> None:
        """Open and configure the camera. Raises CameraError with a hint if it does not open."""
        import cv2

        self._cv2 = cv2
        factory = self._factory or cv2.VideoCapture
        self._cap = factory(self.device, self.backend)
        if not self._cap.isOpened():
            raise CameraError(
                f"cannot open camera {self.name}: check it is plugged in (`v4l2-ctl --list-devices`), "
                "that no other program uses it, and CAMERA_INDEX")
        if self.backend == CAP_V4L2:
            if self.fourcc:  # FOURCC before the size: the size list depends on the pixel format
                self._set(CAP_PROP_FOURCC, fourcc_code(self.fourcc), "FOURCC")
            self._set(CAP_PROP_FRAME_WIDTH, self.width, "width")
            self._set(CAP_PROP_FRAME_HEIGHT, self.height, "height")
            self._set(CAP_PROP_FPS, self.fps, "fps")
            self._set(CAP_PROP_BUFFERSIZE, 1, "buffer size")
            got = (self._cap.get(CAP_PROP_FRAME_WIDTH), self._cap.get(CAP_PROP_FRAME_HEIGHT),
                   self._cap.get(CAP_PROP_FPS))
            logger.info("camera %s: driver mode %dx%d @ %.0f fps (asked %dx%d @ %d; frames are resized)",
                        self.name, got[0], got[1], got[2], self.width, self.height, self.fps)

    def read(self) -> np.ndarray | None:
        """One RGB frame, or None when the driver returned none this time."""
        if self._cap is None:
            raise CameraError(f"camera {self.name} is not open")
        ok, frame = self._cap.read()
        if not ok or frame is None:
            self.failed_reads += 1
            if self.failed_reads in (1, 10, 100) or self.failed_reads % 1000 == 0:
                logger.warning("camera %s: read failed (%d times)", self.name, self.failed_reads)
            return None
        self.failed_reads = 0
        if frame.ndim == 2:
            return frame
        return self._cv2.cvtColor(frame, self._cv2.COLOR_BGR2RGB)

    def close(self) -> None:
        """Release the camera."""
        cap, self._cap = self._cap, None
        if cap is not None:
            cap.release()


def csi_pipeline(sensor_id: int = 0, capture_width: int = 1280, capture_height: int = 720,
                 framerate: int = 60, output_width: int = 160, output_height: int = 120,
                 flip_method: int = 0) -> str:
    """The GStreamer pipeline for a Jetson CSI camera (nvarguscamerasrc, e.g. IMX219).

    Captures at a real sensor mode and lets ``nvvidconv`` scale and flip on the GPU; the appsink
    keeps one buffer and drops the rest so reads are fresh. ``flip_method``: 0 none, 1 ccw 90,
    2 180, 3 cw 90, 4 horizontal, 6 vertical.
    """
    if flip_method not in range(8):
        raise ValueError(f"flip_method {flip_method} must be 0..7 (0 none, 2 = 180 degrees)")
    for label, v in (("capture_width", capture_width), ("capture_height", capture_height),
                     ("framerate", framerate), ("output_width", output_width),
                     ("output_height", output_height)):
        if v <= 0:
            raise ValueError(f"{label} = {v} must be > 0")
    return (f"nvarguscamerasrc sensor-id={sensor_id} ! "
            f"video/x-raw(memory:NVMM), width={capture_width}, height={capture_height}, "
            f"format=NV12, framerate={framerate}/1 ! "
            f"nvvidconv flip-method={flip_method} ! "
            f"video/x-raw, width={output_width}, height={output_height}, format=BGRx ! "
            "videoconvert ! video/x-raw, format=BGR ! appsink drop=true max-buffers=1")


def flip_method_for(vflip: bool, hflip: bool) -> int:
    """nvvidconv flip-method for the flips asked (both = rotate 180)."""
    return {(False, False): 0, (True, True): 2, (False, True): 4, (True, False): 6}[(vflip, hflip)]


class CSISource(OpenCVSource):
    """Jetson CSI camera: :func:`csi_pipeline` opened with ``cv2.CAP_GSTREAMER``.

    Needs an OpenCV built with GStreamer (JetPack's system cv2; pip wheels have none).
    """

    def __init__(self, width: int = 160, height: int = 120, fps: int = 60, sensor_id: int = 0,
                 capture_width: int = 1280, capture_height: int = 720, flip_method: int = 0,
                 capture_factory: Callable[..., Any] | None = None) -> None:
        check_settings(CSIC_CAPTURE_FPS=fps, CAMERA_INDEX=sensor_id, CSIC_CAPTURE_WIDTH=capture_width,
                       CSIC_CAPTURE_HEIGHT=capture_height)
        self.pipeline = csi_pipeline(sensor_id, capture_width, capture_height, fps, width, height,
                                     flip_method)
        super().__init__(self.pipeline, width, height, fps, CAP_GSTREAMER, None, capture_factory)
        self.name = f"CSI camera {sensor_id}"

    #: the GStreamer pipeline flips (on the GPU): the Camera part must not flip again
    flips_itself = True

    @classmethod
    def from_config(cls, cfg: Any) -> CSISource:
        """CAMERA_TYPE = "CSIC": sensor CAMERA_INDEX captured at CSIC_CAPTURE_*, flipped on the GPU."""
        return cls(cfg.IMAGE_W, cfg.IMAGE_H, cfg.CSIC_CAPTURE_FPS, cfg.CAMERA_INDEX, cfg.CSIC_CAPTURE_WIDTH,
                   cfg.CSIC_CAPTURE_HEIGHT, flip_method_for(cfg.CAMERA_VFLIP, cfg.CAMERA_HFLIP))

    def open(self) -> None:
        """Open the pipeline; the error explains the GStreamer requirement."""
        try:
            super().open()
        except CameraError as exc:
            raise CameraError(
                f"cannot open {self.name} with GStreamer: OpenCV must be built with GStreamer "
                "(use JetPack's python3-opencv, not the pip wheel), the ribbon cable seated, and "
                f"`nvgstcapture-1.0` working. Pipeline: {self.pipeline}") from exc
