"""``vehicle tub hist`` (PNG histograms, matplotlib Agg) and ``vehicle tub movie`` (MP4 or WebM, OpenCV)."""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from parts.tub.codec import cv2
from parts.tub.errors import TubError
from parts.tub.reader import TubRecord, iter_images, iter_records
from parts.tub.tools import check_fields

logger = logging.getLogger(__name__)

DEFAULT_FIELDS = ("user/angle", "user/throttle")


def _values(records: Iterable[TubRecord], key: str) -> np.ndarray:
    vals = []
    for rec in records:
        v = rec.angle if key in ("user/angle", "user/steering") else rec.get(key)
        if isinstance(v, int | float) and not isinstance(v, bool):
            vals.append(float(v))
    return np.asarray(vals, dtype=np.float64)


def write_histograms(paths: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str],
                     fields: Sequence[str] = DEFAULT_FIELDS, bins: int = 50) -> Path:
    """Histograms of numeric ``fields`` over the (not deleted) records of ``paths`` -> PNG file."""
    import matplotlib

    matplotlib.use("Agg")  # no display needed; imported here so the CLI stays light
    import matplotlib.pyplot as plt

    if isinstance(bins, bool) or not isinstance(bins, int) or bins < 1:
        raise ValueError(f"bins must be a whole number >= 1, got {bins!r}")
    records = list(iter_records(paths, check_images=False))
    if not records:
        raise TubError(f"{', '.join(map(str, paths))}: no records to plot")
    known = dict.fromkeys(k for rec in records for k in rec.data)
    check_fields([f for f in fields if f != "user/steering"], known, str(paths[0]) if len(paths) == 1 else "the tubs")
    fig, axes = plt.subplots(1, len(fields), figsize=(5 * len(fields), 3.6), squeeze=False)
    for ax, key in zip(axes[0], fields, strict=True):
        vals = _values(records, key)
        if vals.size:
            ax.hist(vals, bins=bins, color="#3572a5")
            ax.set_title(f"{key}  (n={vals.size}, mean {vals.mean():+.3f}, sd {vals.std():.3f})", fontsize=9)
        else:
            ax.set_title(f"{key}: no numeric values", fontsize=9)
        ax.set_xlabel(key)
        ax.set_ylabel("records")
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out


#: what a movie frame may show beside the recording: called with the RGB frame and its record, it
#: returns the picture to film (e.g. with a saliency overlay, possibly wider) and the model's
#: steering for the frame (None: no model)
FrameView = Callable[[np.ndarray, TubRecord], tuple[np.ndarray, float | None]]
#: OpenCV's codec per file type: MPEG-4 part 2 for .mp4 (plays in desktop players), VP8 for .webm
#: (plays in every browser, for the console)
CODECS = {".mp4": "mp4v", ".webm": "VP80"}


def _overlay(img: np.ndarray, rec: TubRecord, model_angle: float | None = None) -> np.ndarray:
    """Draw steering (horizontal bar), throttle (vertical bar) and values on a BGR frame; with
    ``model_angle``, the model's steering as an orange bar above the recorded (green) one."""
    cv = cv2()
    h, w = img.shape[:2]
    angle, throttle = rec.angle, rec.throttle
    cx, by = w // 2, h - 8
    cv.line(img, (8, by), (w - 8, by), (80, 80, 80), 3)
    if isinstance(angle, int | float):
        x = int(cx + float(np.clip(angle, -1, 1)) * (w // 2 - 8))
        cv.line(img, (cx, by), (x, by), (0, 220, 0), 3)
    if model_angle is not None and np.isfinite(model_angle):
        my = by - 7
        cv.line(img, (8, my), (w - 8, my), (80, 80, 80), 3)
        x = int(cx + float(np.clip(model_angle, -1, 1)) * (w // 2 - 8))
        cv.line(img, (cx, my), (x, my), (0, 140, 255), 3)
    pilot = rec.get("pilot/angle")
    if isinstance(pilot, int | float):
        x = int(cx + float(np.clip(pilot, -1, 1)) * (w // 2 - 8))
        cv.circle(img, (x, by), 4, (0, 140, 255), -1)
    bx, cy = w - 10, h // 2
    cv.line(img, (bx, 8), (bx, h - 20), (80, 80, 80), 3)
    if isinstance(throttle, int | float):
        y = int(cy - float(np.clip(throttle, -1, 1)) * (h // 2 - 20))
        cv.line(img, (bx, cy), (bx, y), (0, 200, 255), 3)
    text = f"{rec.index}  a {angle if angle is None else f'{angle:+.2f}'}" \
           f"  t {throttle if throttle is None else f'{throttle:+.2f}'}"
    if model_angle is not None:
        text += f"  model {model_angle:+.2f}"
    cv.putText(img, text, (6, 16), cv.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3, cv.LINE_AA)
    cv.putText(img, text, (6, 16), cv.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv.LINE_AA)
    return img


def write_movie(path: str | os.PathLike[str], out: str | os.PathLike[str], *, start: int = 0,
                end: int | None = None, fps: float = 20.0, scale: int = 2, key: str = "cam/image_array",
                progress: bool = False, view: FrameView | None = None) -> tuple[Path, int]:
    """MP4 (or WebM: ``out`` ending in .webm) of a tub's images (records ``start`` <= index < ``end``)
    with steering/throttle overlay; ``view`` changes each frame (a pilot's saliency, see
    :class:`parts.pilots.saliency.SalientView`) and adds the model's steering bar.

    Returns (file, frames written).
    """
    from tqdm import tqdm

    if scale < 1:
        raise ValueError(f"scale must be >= 1, got {scale}")
    if not fps > 0:
        raise ValueError(f"fps must be > 0 frames per second, got {fps}")
    cv = cv2()
    codec = CODECS.get(Path(out).suffix.lower())
    if codec is None:
        raise ValueError(f"{out}: the movie file must end in {' or '.join(CODECS)}")
    records = [r for r in iter_records([path]) if r.index >= start and (end is None or r.index < end)]
    if not records:
        raise TubError(f"{path}: no records in the range {start}..{end if end is not None else 'end'}")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    writer = None
    frames = 0
    try:
        decoders = max(1, (os.cpu_count() or 2) - 1)  # a core left to draw and encode the video
        for rec, img in tqdm(iter_images(records, key, workers=decoders), total=len(records), desc="movie",
                             unit="frame", disable=not progress, leave=False):
            model_angle = None
            if view is not None:
                img, model_angle = view(img if img.ndim == 3 else np.repeat(img[:, :, None], 3, 2), rec)
            frame = cv.cvtColor(img, cv.COLOR_RGB2BGR) if img.ndim == 3 else cv.cvtColor(img, cv.COLOR_GRAY2BGR)
            if scale != 1:
                frame = cv.resize(frame, (frame.shape[1] * scale, frame.shape[0] * scale),
                                  interpolation=cv.INTER_NEAREST)
            if writer is None:
                size = (frame.shape[1], frame.shape[0])
                writer = cv.VideoWriter(str(out), cv.VideoWriter_fourcc(*codec), float(fps), size)
                if not writer.isOpened():
                    raise TubError(f"OpenCV cannot write {out} ({codec}): check the folder can be written")
            elif (frame.shape[1], frame.shape[0]) != size:
                frame = cv.resize(frame, size)
            writer.write(_overlay(frame, rec, model_angle))
            frames += 1
    finally:
        if writer is not None:
            writer.release()
    return out, frames
