"""The camera part: a frame source read in its own thread, latest frame + capture time + health.

Every camera type is a *frame source* (:class:`FrameSource`: ``open()``, ``read() -> RGB frame or
None``, ``close()``) wrapped by :class:`Camera`, which keeps only the latest frame (a slow loop
never reads stale queued frames), stamps it with its capture time (``time.time()``), resizes and
flips it, and reports ``cam/ok`` False when no frame arrived for ``timeout_s`` seconds.

Outputs: ``cam/image_array`` (H×W×3 uint8 RGB, None before the first frame), ``cam/timestamp``
(float seconds, time.time()), ``cam/ok`` (bool).
"""

from __future__ import annotations

import logging
import time
from typing import Any, ClassVar, NamedTuple, Protocol

import numpy as np

from vehicle.config import check_settings
from vehicle.errors import VehicleError
from vehicle.part import ThreadedPart

logger = logging.getLogger(__name__)


class CameraError(VehicleError, RuntimeError):
    """A camera could not be opened or failed; the message names the device and a fix."""


class FrameSource(Protocol):
    """Where frames come from. ``paced`` sources return at once (files, mock) and are paced to fps."""

    name: str
    paced: bool

    def open(self) -> None: ...

    def read(self) -> np.ndarray | None: ...

    def close(self) -> None: ...


class Frame(NamedTuple):
    """One delivered frame."""

    image: np.ndarray
    timestamp: float  # time.time() at capture, seconds
    seq: int  # 1 for the first frame of this camera


def fit_frame(image: np.ndarray, width: int, height: int, vflip: bool = False,
              hflip: bool = False) -> np.ndarray:
    """Resize to ``width`` × ``height`` (area interpolation) and flip as asked; uint8 RGB out."""
    if image.ndim == 2:  # grey source: replicate to 3 channels so every consumer sees HxWx3
        image = np.repeat(image[:, :, None], 3, axis=2)
    if image.shape[1] != width or image.shape[0] != height:
        import cv2

        image = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    if vflip:
        image = image[::-1]
    if hflip:
        image = image[:, ::-1]
    return np.ascontiguousarray(image, dtype=np.uint8)


class Camera(ThreadedPart):
    """Threaded camera part around a :class:`FrameSource`.

    Args:
        source: the frame source.
        width, height: size of the delivered frames (IMAGE_W, IMAGE_H).
        fps: frames per second for paced sources (files, mock); device sources deliver at their rate.
        vflip, hflip: flip the image vertically / horizontally (camera mounted upside down).
        timeout_s: no frame for this long means ``cam/ok`` False (CAMERA_TIMEOUT_S).
    """

    #: no inputs: the frame source is the camera's own
    INPUTS: ClassVar[tuple[str, ...]] = ()
    OUTPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array", "cam/timestamp", "cam/ok")

    @property
    def OUTPUT_SHAPES(self) -> dict[str, tuple[int, ...]]:  # noqa: N802 - the part declaration
        """The frames' shape (IMAGE_H, IMAGE_W, 3), for the wiring check (:mod:`vehicle.shapes`)."""
        return {"cam/image_array": (self.height, self.width, 3)}

    def __init__(self, source: FrameSource, width: int = 160, height: int = 120, fps: float = 20.0,
                 vflip: bool = False, hflip: bool = False, timeout_s: float = 1.0) -> None:
        super().__init__()
        check_settings(IMAGE_W=width, IMAGE_H=height, CAMERA_FRAMERATE=fps, CAMERA_TIMEOUT_S=timeout_s)
        self.source = source
        self.width, self.height = width, height
        self.fps = fps
        self.vflip, self.hflip = vflip, hflip
        self.timeout_s = timeout_s
        self.period = 1.0 / fps if source.paced else None
        self.name = f"Camera({source.name})"
        self._seq = 0
        self._started_at: float | None = None
        self._was_ok = False
        self._reported_missing = False

    def open(self) -> None:
        """Open the source (in the camera thread)."""
        self._started_at = time.monotonic()
        self.source.open()
        logger.info("camera %s opened (%dx%d out)", self.source.name, self.width, self.height)

    def poll(self) -> Any:
        """Read one frame; an empty read rests a frame period instead of spinning."""
        image = self.source.read()
        if image is None:
            if not self.source.paced:
                self.stop_event.wait(1.0 / self.fps)
            return self.NOTHING
        timestamp = time.time()
        self._seq += 1
        return Frame(fit_frame(image, self.width, self.height, self.vflip, self.hflip), timestamp, self._seq)

    def close(self) -> None:
        """Close the source."""
        self.source.close()

    def _outputs(self) -> tuple[np.ndarray | None, float | None, bool]:
        frame: Frame | None = self.latest()
        age = self.age()
        ok = frame is not None and age is not None and age <= self.timeout_s and self.error is None
        if ok != self._was_ok:
            if ok:
                logger.info("camera %s delivering frames", self.source.name)
            else:
                logger.error("camera %s stopped delivering frames (none for %.1f s > "
                             "CAMERA_TIMEOUT_S=%.1f)%s",
                             self.source.name, age or 0.0, self.timeout_s,
                             f": {self.error}" if self.error else "")
            self._was_ok = ok
        elif (frame is None and not self._reported_missing and self._started_at is not None
              and time.monotonic() - self._started_at > self.timeout_s):
            logger.error("camera %s: no frame within %.1f s of starting%s", self.source.name,
                         self.timeout_s, f": {self.error}" if self.error else "")
            self._reported_missing = True
        if frame is None:
            return None, None, False
        return frame.image, frame.timestamp, ok

    def run_threaded(self, *inputs: Any) -> tuple[np.ndarray | None, float | None, bool]:
        """(cam/image_array, cam/timestamp, cam/ok) of the latest frame; never blocks."""
        with self._lock:
            self._inputs = inputs
        return self._outputs()

    def run(self, *inputs: Any) -> tuple[np.ndarray | None, float | None, bool]:
        """Non-threaded use: read one frame inline, then report like run_threaded."""
        self._ensure_open()
        value = self.poll()
        if value is not self.NOTHING:
            self.publish(value)
        return self._outputs()

    def frame(self) -> Frame | None:
        """The latest Frame (image, timestamp, seq), or None before the first."""
        return self.latest()
