"""Lane-line extraction (thesis seed 002, §7 and Appendix 4.1): bird's-eye warp, HLS, threshold.

The thesis's procedure for every frame:

1. warp the region of interest (a trapezoid on the road, the *source points*) to a rectangle (the
   *destination points*) with ``cv2.getPerspectiveTransform`` + ``cv2.warpPerspective``
   (bilinear), so lane lines become parallel (a bird's-eye view);
2. stretch the warped image to the full 0..255 range (``cv2.normalize``, NORM_MINMAX over all
   channels);
3. convert to HLS and keep the S (saturation) channel;
4. threshold it: ``cv2.threshold(S, 65, 255, THRESH_BINARY)``, i.e. S > 65 -> lane pixel.

The thesis's points are given for 320x180 frames (:data:`THESIS_SOURCE`,
:data:`THESIS_DESTINATION`); here points are given for a reference size (``points_size``) and
scaled to the frame size and to the output size, so the same settings work for any camera
resolution with the same field of view. The thesis's camera sees the road differently from
yours: tune the source points on a frame of a straight road with ``vehicle lanes preview``.

Additions to the thesis, all off by default except where noted:

- the second threshold value is an upper bound (S in (low, high]); at the thesis's 255 this is
  exactly its ``cv2.threshold`` call, whose 255 was the output value;
- ``color_mask``: white (HLS lightness >= ``white_min_lightness``) and/or yellow (hue in
  ``yellow_hue``, saturation >= ``yellow_min_saturation``) pixels are lane pixels too. White tape
  has almost no saturation, so the S threshold alone misses it (the simulator's white lines,
  most tape tracks); ``s_threshold=None`` leaves the S threshold out;
- the frame is converted from RGB (what every camera part delivers); the thesis converted with
  ``COLOR_BGR2HLS``, which swaps red and blue for the hue only. S and L do not depend on channel
  order, so the thesis's S-channel result is the same.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, ClassVar

import cv2
import numpy as np

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

#: the frame size (width, height) the thesis's points are given for
THESIS_SIZE: tuple[int, int] = (320, 180)
#: the thesis's region of interest: bottom left, top left, top right, bottom right (pixels of 320x180)
THESIS_SOURCE: tuple[tuple[float, float], ...] = ((0.0, 180.0), (112.5, 87.5), (200.0, 87.5), (307.5, 180.0))
#: where the thesis maps them: bottom left, top left, top right, bottom right (pixels of 320x180)
THESIS_DESTINATION: tuple[tuple[float, float], ...] = ((80.0, 180.0), (80.0, 0.25), (230.0, 0.25), (230.0, 180.0))
#: the thesis's S-channel threshold: S > 65
THESIS_S_THRESHOLD: tuple[int, int] = (65, 255)
COLOR_MASKS = ("white", "yellow", "white_yellow")


class LaneSettingsError(VehicleError, ValueError):
    """A lane-extraction setting is out of range; the message names the LANE_* setting."""


def _points(value: Any, name: str) -> tuple[tuple[float, float], ...]:
    try:
        pts = tuple((float(p[0]), float(p[1])) for p in value)
    except (TypeError, ValueError, IndexError):
        raise LaneSettingsError(f"{name} must be four (x, y) pixel points, got {value!r}") from None
    if len(pts) != 4 or not np.isfinite(np.asarray(pts)).all():
        raise LaneSettingsError(f"{name} must be four finite (x, y) points (bottom left, top left, top right, "
                         f"bottom right), got {value!r}")
    # the quadrilateral must be convex and not degenerate, or the perspective transform is singular
    p = np.asarray(pts)
    edges = np.roll(p, -1, axis=0) - p
    nxt = np.roll(edges, -1, axis=0)
    cross = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]
    if not (all(c > 1e-6 for c in cross) or all(c < -1e-6 for c in cross)):
        raise LaneSettingsError(f"{name} {list(pts)} do not form a convex quadrilateral: give them in the order "
                         "bottom left, top left, top right, bottom right")
    return pts


def _range(value: Any, name: str, low: int = 0, high: int = 255) -> tuple[int, int]:
    try:
        lo, hi = (int(v) for v in value)
    except (TypeError, ValueError):
        raise LaneSettingsError(f"{name} must be (low, high), got {value!r}") from None
    if not low <= lo < hi <= high:
        raise LaneSettingsError(f"{name} = ({lo}, {hi}) must satisfy {low} <= low < high <= {high}")
    return lo, hi


@dataclass(frozen=True)
class LaneSettings:
    """How lane lines are extracted (see the module docstring); defaults are the thesis's.

    Attributes:
        source: region of interest, four (x, y) points in pixels of a ``points_size`` frame:
            bottom left, top left, top right, bottom right.
        destination: where the source points go in the bird's-eye image (pixels of ``points_size``).
        points_size: (width, height) the points are given for; they are scaled to the real sizes.
        s_threshold: (low, high) of the S channel (S in (low, high] is a lane pixel), or None.
        color_mask: None, "white", "yellow" or "white_yellow" (lane pixels in addition to S).
        white_min_lightness: HLS lightness (0..255) from which a pixel is white.
        yellow_hue: OpenCV hue range (0..180) of yellow.
        yellow_min_saturation: least HLS saturation of a yellow pixel.
        normalize: stretch the warped image to 0..255 before thresholding (the thesis does).
    """

    source: tuple[tuple[float, float], ...] = THESIS_SOURCE
    destination: tuple[tuple[float, float], ...] = THESIS_DESTINATION
    points_size: tuple[int, int] = THESIS_SIZE
    s_threshold: tuple[int, int] | None = THESIS_S_THRESHOLD
    color_mask: str | None = None
    white_min_lightness: int = 200
    yellow_hue: tuple[int, int] = (15, 35)
    yellow_min_saturation: int = 80
    normalize: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "source", _points(self.source, "lane source points (LANE_SOURCE_POINTS)"))
        object.__setattr__(self, "destination",
                           _points(self.destination, "lane destination points (LANE_DESTINATION_POINTS)"))
        try:
            w, h = (int(v) for v in self.points_size)
        except (TypeError, ValueError):
            raise LaneSettingsError(f"LANE_POINTS_SIZE must be (width, height), got {self.points_size!r}") from None
        if w < 8 or h < 8:
            raise LaneSettingsError(f"LANE_POINTS_SIZE must be at least 8x8 pixels, got {w}x{h}")
        object.__setattr__(self, "points_size", (w, h))
        if self.s_threshold is not None:
            object.__setattr__(self, "s_threshold", _range(self.s_threshold, "LANE_S_THRESHOLD"))
        if self.color_mask is not None and self.color_mask not in COLOR_MASKS:
            raise LaneSettingsError(f"LANE_COLOR_MASK must be None or one of {COLOR_MASKS}, got {self.color_mask!r}")
        if self.s_threshold is None and self.color_mask is None:
            raise LaneSettingsError("lane extraction needs LANE_S_THRESHOLD or LANE_COLOR_MASK (both are off)")
        if not 0 <= int(self.white_min_lightness) <= 255:
            raise LaneSettingsError(f"LANE_WHITE_MIN_LIGHTNESS must be 0..255, got {self.white_min_lightness}")
        object.__setattr__(self, "yellow_hue", _range(self.yellow_hue, "LANE_YELLOW_HUE", 0, 180))
        if not 0 <= int(self.yellow_min_saturation) <= 255:
            raise LaneSettingsError(f"LANE_YELLOW_MIN_SATURATION must be 0..255, got {self.yellow_min_saturation}")

    @classmethod
    def from_config(cls, cfg: Any) -> LaneSettings:
        """Settings from the car's LANE_* values."""
        return cls(source=cfg.LANE_SOURCE_POINTS, destination=cfg.LANE_DESTINATION_POINTS,
                   points_size=cfg.LANE_POINTS_SIZE, s_threshold=cfg.LANE_S_THRESHOLD,
                   color_mask=cfg.LANE_COLOR_MASK, white_min_lightness=cfg.LANE_WHITE_MIN_LIGHTNESS,
                   yellow_hue=cfg.LANE_YELLOW_HUE, yellow_min_saturation=cfg.LANE_YELLOW_MIN_SATURATION,
                   normalize=cfg.LANE_NORMALIZE)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON values (stored in a lanes model's preprocessing)."""
        return {"source": [list(p) for p in self.source], "destination": [list(p) for p in self.destination],
                "points_size": list(self.points_size),
                "s_threshold": list(self.s_threshold) if self.s_threshold is not None else None,
                "color_mask": self.color_mask, "white_min_lightness": int(self.white_min_lightness),
                "yellow_hue": list(self.yellow_hue), "yellow_min_saturation": int(self.yellow_min_saturation),
                "normalize": bool(self.normalize)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LaneSettings:
        """Inverse of :meth:`to_dict`; unknown keys are refused."""
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise LaneSettingsError(f"unknown lane setting(s) {sorted(unknown)}")
        return cls(**d)

    def scaled(self, points: tuple[tuple[float, float], ...], width: int, height: int) -> np.ndarray:
        """``points`` (of ``points_size``) scaled to a ``width`` x ``height`` image, float32 (4, 2)."""
        sx, sy = width / self.points_size[0], height / self.points_size[1]
        return np.asarray(points, np.float32) * np.float32([sx, sy])


class LaneExtractor:
    """Computes binary lane images; the perspective matrix is computed once per size.

    ``extract(frame)`` returns a uint8 HxW image, 255 on lane pixels, 0 elsewhere, of the frame's
    size or of ``out_size`` = (width, height) (the warp goes straight to that size: no extra
    resize).
    """

    def __init__(self, settings: LaneSettings | None = None) -> None:
        self.settings = settings or LaneSettings()
        self._matrices: dict[tuple[int, int, int, int], np.ndarray] = {}
        self._sizes_told: set[tuple[int, int]] = set()

    def matrix(self, in_size: tuple[int, int], out_size: tuple[int, int]) -> np.ndarray:
        """3x3 matrix taking frame pixels (``in_size`` = (w, h)) to bird's-eye pixels (``out_size``)."""
        key = (*in_size, *out_size)
        m = self._matrices.get(key)
        if m is None:
            s = self.settings
            self._check_aspect(in_size)
            m = cv2.getPerspectiveTransform(s.scaled(s.source, *in_size), s.scaled(s.destination, *out_size))
            self._matrices[key] = m
        return m

    def _check_aspect(self, in_size: tuple[int, int]) -> None:
        """Warn once per frame size whose aspect ratio is not the points' (they are stretched to it)."""
        (pw, ph), (w, h) = self.settings.points_size, in_size
        if in_size in self._sizes_told or abs(w / h - pw / ph) <= 0.01 * pw / ph:
            return
        self._sizes_told.add(in_size)
        logger.warning("lane extraction: the points are given for %dx%d frames (LANE_POINTS_SIZE), these are %dx%d, "
                       "another aspect ratio: the region of interest is stretched to fit; set the LANE_* points "
                       "for this camera (vehicle lanes preview, vehicle lanes points --sim)", pw, ph, w, h)

    def warp(self, image: np.ndarray, out_size: tuple[int, int] | None = None) -> np.ndarray:
        """The bird's-eye view of ``image`` (RGB uint8), ``out_size`` or the frame's size."""
        h, w = image.shape[:2]
        size = out_size or (w, h)
        return cv2.warpPerspective(image, self.matrix((w, h), size), size, flags=cv2.INTER_LINEAR)

    def threshold(self, warped: np.ndarray) -> np.ndarray:
        """Lane pixels of a warped RGB image: uint8 HxW, 255 = lane."""
        s = self.settings
        if s.normalize:
            warped = cv2.normalize(warped, None, 0, 255, cv2.NORM_MINMAX, cv2.CV_8U)
        hls = cv2.cvtColor(warped, cv2.COLOR_RGB2HLS)
        mask = np.zeros(hls.shape[:2], np.uint8)
        if s.s_threshold is not None:
            lo, hi = s.s_threshold
            # inRange is inclusive: S in [lo + 1, hi] == the thesis's S > lo for hi = 255
            mask |= cv2.inRange(hls[:, :, 2], lo + 1, hi)
        if s.color_mask in ("white", "white_yellow"):
            mask |= cv2.inRange(hls[:, :, 1], int(s.white_min_lightness), 255)
        if s.color_mask in ("yellow", "white_yellow"):
            lo_h, hi_h = s.yellow_hue
            mask |= cv2.inRange(hls, (lo_h, 0, int(s.yellow_min_saturation)), (hi_h, 255, 255))
        return mask

    def extract(self, image: np.ndarray, out_size: tuple[int, int] | None = None) -> np.ndarray:
        """Warp then threshold: the binary lane image of one RGB frame."""
        if not isinstance(image, np.ndarray) or image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"lane extraction needs a uint8 HxWx3 RGB frame, got "
                             f"{getattr(image, 'dtype', type(image).__name__)} {getattr(image, 'shape', '')}")
        return self.threshold(self.warp(image, out_size))

    __call__ = extract

    def draw_region(self, image: np.ndarray, color: tuple[int, int, int] = (255, 40, 40)) -> np.ndarray:
        """A copy of ``image`` with the region of interest (source points) outlined."""
        out = image.copy()
        h, w = image.shape[:2]
        pts = self.settings.scaled(self.settings.source, w, h)
        cv2.polylines(out, [np.round(pts * 4).astype(np.int32).reshape(-1, 1, 2)], True, color, 1,
                      cv2.LINE_AA, 2)
        return out


class LaneExtraction:
    """Part: ``cam/image_array`` -> ``vision/lane_image`` (uint8 HxW, 255 = lane pixel).

    For the web view, a tub or your own parts; the ``lanes`` pilot computes the same image itself
    from the raw frame (with the settings stored in its model file).

    Args:
        settings: lane settings (default: the thesis's).
        out_size: (width, height) of the lane image; None = the frame's size.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("vision/lane_image",)

    def __init__(self, settings: LaneSettings | None = None, out_size: tuple[int, int] | None = None) -> None:
        self.extractor = LaneExtractor(settings)
        self.out_size = tuple(out_size) if out_size is not None else None

    @classmethod
    def from_config(cls, cfg: Any) -> LaneExtraction:
        """A part with the car's LANE_* settings."""
        return cls(LaneSettings.from_config(cfg))

    def run(self, image: np.ndarray | None) -> np.ndarray | None:
        """Part entry point; None (no frame yet) gives None."""
        if image is None:
            return None
        return self.extractor.extract(image, self.out_size)  # type: ignore[arg-type]


def preview_strip(frames: list[np.ndarray], extractor: LaneExtractor, scale: int = 2) -> np.ndarray:
    """An RGB image, one row per frame: raw frame with the region of interest outlined, the
    bird's-eye view, and the thresholded lane image (what ``vehicle lanes preview`` writes)."""
    if not frames:
        raise ValueError("preview_strip needs at least one frame")
    h, w = frames[0].shape[:2]
    rows = []
    for frame in frames:
        if frame.shape[:2] != (h, w):
            frame = cv2.resize(frame, (w, h), interpolation=cv2.INTER_AREA)
        warped = extractor.warp(frame)
        mask = extractor.threshold(warped)
        cells = [extractor.draw_region(frame), warped, cv2.cvtColor(mask, cv2.COLOR_GRAY2RGB)]
        row = np.hstack([cv2.resize(c, (w * scale, h * scale), interpolation=cv2.INTER_NEAREST) for c in cells])
        for i, label in enumerate(("raw + region", "bird's-eye", "lanes")):
            (tw, th), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
            x0 = i * w * scale
            cv2.rectangle(row, (x0, 0), (x0 + tw + 8, th + 8), (0, 0, 0), -1)  # a band keeps it legible
            cv2.putText(row, label, (x0 + 4, th + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 0), 1, cv2.LINE_AA)
        rows.append(row)
    return np.vstack(rows)
