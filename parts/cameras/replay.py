"""Replay sources: a video file, a folder of images, or the images of a tub."""

from __future__ import annotations

import logging
import re
from pathlib import Path
from typing import Any

import numpy as np

from parts.cameras.base import CameraError
from vehicle.config import ConfigError

logger = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")


def _required_path(cfg: Any, kind: str, setting: str, example: str) -> Path:
    """``cfg.path(setting)``; a ConfigError saying what to set when it is empty."""
    if not cfg[setting]:
        raise ConfigError(f'CAMERA_TYPE = "{kind}" needs {setting} = "{example}" in myconfig.py')
    return cfg.path(setting)


class VideoFileSource:
    """Frames of a video file (anything FFMPEG reads), RGB, optionally looping."""

    paced = True

    def __init__(self, path: str | Path, loop: bool = True) -> None:
        self.path = Path(path).expanduser()
        self.loop = loop
        self.name = self.path.name
        self._cap: Any = None
        self._cv2: Any = None
        self.frame_count = 0
        self.ended = False

    @classmethod
    def from_config(cls, cfg: Any) -> VideoFileSource:
        """CAMERA_TYPE = "VIDEO": CAMERA_VIDEO_PATH (relative to the car), CAMERA_REPLAY_LOOP."""
        return cls(_required_path(cfg, "VIDEO", "CAMERA_VIDEO_PATH", "path/to/video.mp4"), loop=cfg.CAMERA_REPLAY_LOOP)

    def open(self) -> None:
        """Open the file. CameraError if it is missing or not a video."""
        import cv2

        if not self.path.is_file():
            raise CameraError(f"no video file at {self.path}; set CAMERA_VIDEO_PATH to an existing file")
        self._cv2 = cv2
        self._cap = cv2.VideoCapture(str(self.path))
        if not self._cap.isOpened():
            raise CameraError(f"OpenCV cannot decode {self.path}; convert it to MP4 (H.264) or MJPG AVI")
        self.frame_count = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.ended = False

    def read(self) -> np.ndarray | None:
        """The next frame; at the end rewinds (loop) or returns None from then on."""
        if self._cap is None:
            raise CameraError(f"video {self.path} is not open")
        if self.ended:
            return None
        ok, frame = self._cap.read()
        if not ok and self.loop:
            self._cap.set(self._cv2.CAP_PROP_POS_FRAMES, 0)
            ok, frame = self._cap.read()
        if not ok:
            self.ended = True
            logger.info("video %s: end of file", self.path)
            return None
        return self._cv2.cvtColor(frame, self._cv2.COLOR_BGR2RGB)

    def close(self) -> None:
        """Release the file."""
        cap, self._cap = self._cap, None
        if cap is not None:
            cap.release()


def _natural_key(path: Path) -> list[Any]:
    # "img_10.jpg" after "img_9.jpg"; tub images "12_cam_image_array_.jpg" sort by record index
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name)]


def list_images(folder: str | Path) -> list[Path]:
    """Image files of a folder (or of a tub's images/ folder) in natural order."""
    root = Path(folder).expanduser()
    if (root / "images").is_dir() and (root / "manifest.json").is_file():
        root = root / "images"  # a tub: replay its camera images in record order
    if not root.is_dir():
        raise CameraError(f"no image folder at {root}; set CAMERA_IMAGE_PATH to a folder of images or a tub")
    files = sorted((p for p in root.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES), key=_natural_key)
    if not files:
        raise CameraError(f"{root} holds no images ({', '.join(IMAGE_SUFFIXES)})")
    return files


class ImageFolderSource:
    """Frames from the images of a folder or a tub, RGB, in natural name order, optionally looping."""

    paced = True

    def __init__(self, folder: str | Path, loop: bool = True) -> None:
        self.folder = Path(folder).expanduser()
        self.loop = loop
        self.name = self.folder.name or str(self.folder)
        self.files: list[Path] = []
        self.index = 0

    @classmethod
    def from_config(cls, cfg: Any) -> ImageFolderSource:
        """CAMERA_TYPE = "IMAGE_LIST": CAMERA_IMAGE_PATH (a folder of images or a tub), CAMERA_REPLAY_LOOP."""
        return cls(_required_path(cfg, "IMAGE_LIST", "CAMERA_IMAGE_PATH", "folder/or/tub"), loop=cfg.CAMERA_REPLAY_LOOP)

    def open(self) -> None:
        """List the images. CameraError if there are none."""
        self.files = list_images(self.folder)
        self.index = 0
        logger.info("replaying %d images from %s", len(self.files), self.folder)

    def read(self) -> np.ndarray | None:
        """The next image (unreadable files are skipped with a warning); None after the last."""
        import cv2

        for _ in range(len(self.files)):
            if self.index >= len(self.files):
                if not self.loop:
                    return None
                self.index = 0
            path = self.files[self.index]
            self.index += 1
            image = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if image is not None:
                return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
            logger.warning("cannot read image %s; skipped", path)
        if self.index >= len(self.files) and not self.loop:
            return None
        raise CameraError(f"none of the images in {self.folder} can be read")

    def close(self) -> None:
        """Nothing to release."""
