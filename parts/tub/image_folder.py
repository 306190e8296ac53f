"""drive.py's image folder: every driven frame saved as a timestamped JPEG (seed 001).

The Udacity behavioural-cloning project's ``drive.py model.h5 IMAGE_FOLDER`` recreated the folder
and saved each frame it drove as ``YYYY_MM_DD_HH_MM_SS_mmm.jpg`` (UTC), which its ``video.py``
turned into a video. :class:`ImageFolderWriter` does the same as a part; a tub (``vehicle udacity
drive MODEL DIR``) keeps more (the commands and the speed), this keeps the document's format.
"""

from __future__ import annotations

import logging
import shutil
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

logger = logging.getLogger(__name__)


def prepare_folder(folder: Path) -> Path:
    """Create ``folder`` empty, as drive.py does; an existing folder is emptied only when it holds
    nothing but JPEG files (a folder of anything else is refused, never deleted)."""
    folder = Path(folder)
    if folder.exists():
        if not folder.is_dir():
            raise ValueError(f"{folder} is a file: give a folder for the frames")
        others = [p.name for p in folder.iterdir() if p.suffix.lower() != ".jpg" or not p.is_file()]
        if others:
            raise ValueError(f"{folder} holds other files than frames ({', '.join(sorted(others)[:3])}): "
                             "give a new or empty folder (drive.py would delete them, this does not)")
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    return folder


class ImageFolderWriter:
    """Part: save each new frame as ``FOLDER/<UTC timestamp>.jpg``.

    ``run(image, frame_id)``: a frame is written once, when ``frame_id`` changes (the Udacity bridge
    numbers the frames it receives). JPEG quality 95, PIL's (drive.py saved the simulator's JPEG
    with PIL's ``Image.save``).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array", "cam/frame_id")

    def __init__(self, folder: str | Path, quality: int = 95) -> None:
        self.folder = Path(folder)
        self.quality = int(quality)
        self.written = 0
        self._last_frame: Any = None

    def run(self, image: np.ndarray | None, frame_id: Any) -> None:
        """Write ``image`` if it is a new frame."""
        if image is None or frame_id is None or frame_id == self._last_frame:
            return
        from PIL import Image

        self._last_frame = frame_id
        stamp = datetime.now(UTC).strftime("%Y_%m_%d_%H_%M_%S_%f")[:-3]
        Image.fromarray(image).save(self.folder / f"{stamp}.jpg", quality=self.quality)
        self.written += 1

    def shutdown(self) -> None:
        logger.info("saved %d frames in %s", self.written, self.folder)
