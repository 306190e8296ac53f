"""The one preprocessing path shared by training and driving: crop, resize, colour space, normalise.

Two stages so that training stays fast and both paths stay identical:

1. :meth:`Preprocess.frame`: uint8 HxWx3 RGB camera frame -> uint8 H'xW'xC (crop, resize, colour).
   Training runs it per sample on the CPU after the augmentations.
2. :meth:`Preprocess.normalize`: uint8 tensor ``(..., C, H', W')`` -> float32. Training runs it per
   batch on the training device; driving runs it on the one frame.

``Preprocess(...)(frame)`` does both for one frame (the pilot part's path). The settings are stored
in the model file (``meta["preprocess"]`` = :meth:`Preprocess.to_dict`), so a model always drives
with the preprocessing it was trained with.

With ``lanes`` settings (the ``lanes`` model type), stage 1 also computes the binary lane image
(:mod:`parts.vision.lanes`) from the whole raw frame, straight at the output size, and appends it
as the last channel (0 or 255, so stage 2 scales it like the image).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

if TYPE_CHECKING:
    import torch

    from parts.vision.lanes import LaneExtractor

COLORS = ("rgb", "yuv", "hsv", "gray")
#: "unit": x / 255; "symmetric": x / 127.5 - 1; "symmetric127": x / 127 - 1 (the Udacity
#: behavioural-cloning project's Keras Lambda, seed 001: 255 maps to 1.008, not 1)
NORMALIZATIONS = ("unit", "symmetric", "symmetric127")
INTERPOLATIONS = ("area", "linear")
_CV2_INTERPOLATION = {"area": cv2.INTER_AREA, "linear": cv2.INTER_LINEAR}
_CV2_COLOR = {"yuv": cv2.COLOR_RGB2YUV, "hsv": cv2.COLOR_RGB2HSV, "gray": cv2.COLOR_RGB2GRAY}


@dataclass(frozen=True)
class Preprocess:
    """Preprocessing settings; all sizes in pixels.

    Attributes:
        crop: pixels removed at (top, bottom, left, right) of the camera frame (sky, bonnet).
        resize: (height, width) after cropping, or None to keep the cropped size.
        color: colour space fed to the model: rgb, yuv (DAVE-2), hsv or gray (1 channel).
        normalize: "unit" maps 0..255 to [0, 1]; "symmetric" to [-1, 1] (x / 127.5 - 1);
            "symmetric127" is x / 127 - 1 (seed 001's Keras Lambda).
        image_shape: (height, width, channels) of the camera frames the model was trained on, or
            None to accept any size (checked so a camera of another size fails clearly).
        lanes: lane-extraction settings (:meth:`parts.vision.lanes.LaneSettings.to_dict`) to append
            the lane image as the last channel, or None.
        color_first: convert the colour space (and blur) before resizing, in Track Driver AI's
            order (crop, YUV, blur, resize); False: crop, resize, colour.
        blur: side in pixels of a fixed Gaussian blur kernel (OpenCV's sigma for that size), odd;
            0 = none. Applied after the colour conversion.
        interpolation: "area" (averages when shrinking) or "linear" (OpenCV's default, and
            ``tf.image.resize``'s: what both Udacity-simulator documents use).
    """

    crop: tuple[int, int, int, int] = (0, 0, 0, 0)
    resize: tuple[int, int] | None = None
    color: str = "rgb"
    normalize: str = "unit"
    image_shape: tuple[int, int, int] | None = field(default=None)
    lanes: dict[str, Any] | None = None
    color_first: bool = False
    blur: int = 0
    interpolation: str = "area"
    _lanes: LaneExtractor | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        crop = tuple(int(v) for v in self.crop)
        if len(crop) != 4 or min(crop) < 0:
            raise ValueError(f"crop must be 4 pixel counts >= 0 (top, bottom, left, right), "
                             f"got {self.crop!r}")
        object.__setattr__(self, "crop", crop)
        if self.resize is not None:
            resize = tuple(int(v) for v in self.resize)
            if len(resize) != 2 or min(resize) < 1:
                raise ValueError(f"resize must be (height, width) >= 1 or None, got {self.resize!r}")
            object.__setattr__(self, "resize", resize)
        if self.color not in COLORS:
            raise ValueError(f"color must be one of {COLORS}, got {self.color!r}")
        if self.normalize not in NORMALIZATIONS:
            raise ValueError(f"normalize must be one of {NORMALIZATIONS}, got {self.normalize!r}")
        if self.interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {INTERPOLATIONS}, got {self.interpolation!r}")
        blur = int(self.blur)
        if blur < 0 or (blur and blur % 2 == 0):
            raise ValueError(f"blur must be 0 (none) or an odd kernel size in pixels, got {self.blur!r}")
        object.__setattr__(self, "blur", blur)
        object.__setattr__(self, "color_first", bool(self.color_first))
        if self.image_shape is not None:
            shape = tuple(int(v) for v in self.image_shape)
            if len(shape) != 3:
                raise ValueError(f"image_shape must be (height, width, channels), got {self.image_shape!r}")
            object.__setattr__(self, "image_shape", shape)
            self.output_shape(shape)  # validates the crop against the frame size
        if self.lanes is not None:
            from parts.vision.lanes import LaneExtractor, LaneSettings

            if not isinstance(self.lanes, dict):
                raise ValueError(f"lanes must be a dict of lane settings or None, got {self.lanes!r}")
            settings = LaneSettings.from_dict(self.lanes)
            object.__setattr__(self, "lanes", settings.to_dict())
            object.__setattr__(self, "_lanes", LaneExtractor(settings))

    # -- shapes
    def output_shape(self, image_shape: tuple[int, ...]) -> tuple[int, int, int]:
        """(C, H, W) of the model input for camera frames of ``image_shape`` (H, W[, C])."""
        h, w = int(image_shape[0]), int(image_shape[1])
        top, bottom, left, right = self.crop
        ch, cw = h - top - bottom, w - left - right
        if ch < 1 or cw < 1:
            raise ValueError(f"crop {self.crop} (top, bottom, left, right) leaves nothing of a "
                             f"{h}x{w} frame; "
                             "lower ROI_CROP_* settings")
        if self.resize is not None:
            ch, cw = self.resize
        return ((1 if self.color == "gray" else 3) + (1 if self.lanes is not None else 0), ch, cw)

    def check_frame_shape(self, shape: tuple[int, ...]) -> None:
        """Raise ModelMismatch (a ValueError) when the model was trained on frames of another shape
        than ``shape``."""
        if self.image_shape is not None and tuple(shape) != self.image_shape:
            from parts.pilots.compat import ModelMismatch  # here: this check runs on every frame

            got = "x".join(map(str, shape))
            want = "x".join(map(str, self.image_shape))
            raise ModelMismatch(f"frame is {got} but the model was trained on {want} frames")

    # -- stage 1: per frame, uint8
    def frame(self, image: np.ndarray) -> np.ndarray:
        """Crop, resize and convert one uint8 HxWx3 RGB frame; returns uint8 H'xW'xC."""
        if not isinstance(image, np.ndarray) or image.ndim != 3 or image.shape[2] != 3 \
                or image.dtype != np.uint8:
            kind = getattr(image, "dtype", type(image).__name__)
            raise ValueError(f"expected a uint8 HxWx3 RGB frame, got {kind} of shape "
                             f"{getattr(image, 'shape', '?')}")
        self.check_frame_shape(image.shape)
        top, bottom, left, right = self.crop
        h, w = image.shape[:2]
        if top + bottom >= h or left + right >= w:
            raise ValueError(f"crop {self.crop} leaves nothing of a {h}x{w} frame; lower ROI_CROP_* settings")
        out = image[top:h - bottom, left:w - right]
        if self.color_first:
            out = self._resize(self._blur(self._color(out)))
        else:
            out = self._blur(self._color(self._resize(out)))
        if out.ndim == 2:
            out = out[:, :, None]
        if self._lanes is not None:
            # from the whole frame (the lane points are frame pixels), warped straight to this size
            lanes = self._lanes.extract(image, (out.shape[1], out.shape[0]))
            return np.concatenate([out, lanes[:, :, None]], axis=2)
        return np.ascontiguousarray(out)

    def _resize(self, image: np.ndarray) -> np.ndarray:
        if self.resize is None or image.shape[:2] == self.resize:
            return image
        # INTER_AREA averages when shrinking (no aliasing), like a camera at a lower resolution.
        return cv2.resize(image, (self.resize[1], self.resize[0]),
                          interpolation=_CV2_INTERPOLATION[self.interpolation])

    def _color(self, image: np.ndarray) -> np.ndarray:
        if self.color == "rgb":
            return image
        return cv2.cvtColor(np.ascontiguousarray(image), _CV2_COLOR[self.color])

    def _blur(self, image: np.ndarray) -> np.ndarray:
        if not self.blur:
            return image
        return cv2.GaussianBlur(image, (self.blur, self.blur), 0)

    @staticmethod
    def to_chw(frame: np.ndarray) -> torch.Tensor:
        """uint8 HxWxC array -> uint8 tensor CxHxW (no copy of the values' meaning)."""
        import torch

        return torch.from_numpy(np.ascontiguousarray(frame.transpose(2, 0, 1)))

    # -- stage 2: per batch, float
    def normalize_batch(self, x: torch.Tensor) -> torch.Tensor:
        """uint8 (or float 0..255) tensor ``(..., C, H, W)`` -> float32 model input."""
        import torch

        # One new tensor, scaled in place: a batch is tens of MB and fresh allocations cost page faults.
        x = x.to(torch.float32, copy=True)
        if self.normalize == "unit":
            return x.mul_(1.0 / 255.0)
        return x.mul_(1.0 / self._half_scale).sub_(1.0)

    @property
    def _half_scale(self) -> float:
        """The divisor of the symmetric normalisations (x / d - 1)."""
        return 127.0 if self.normalize == "symmetric127" else 127.5

    def array(self, image: np.ndarray) -> np.ndarray:
        """The inference path without torch: one RGB uint8 frame -> float32 array (C, H', W').

        Normalised in numpy with the same float32 multiply (and subtract) as :meth:`normalize_batch`,
        bit for bit (a test checks it). Also faster: in torch, one frame is above the size at which
        an operation fans out to the thread pool, and on a busy machine each call then waited for
        every thread (measured: 20 ms per frame instead of 0.1 ms during the demo's evaluation).
        """
        chw = np.ascontiguousarray(self.frame(image).transpose(2, 0, 1))
        if self.normalize == "unit":
            return np.multiply(chw, np.float32(1.0 / 255.0), dtype=np.float32)
        out = np.multiply(chw, np.float32(1.0 / self._half_scale), dtype=np.float32)
        return np.subtract(out, np.float32(1.0), out=out)

    def __call__(self, image: np.ndarray) -> torch.Tensor:
        """:meth:`array` as a float32 tensor (sharing its memory)."""
        import torch

        return torch.from_numpy(self.array(image))

    # -- storage
    def to_dict(self) -> dict[str, Any]:
        """Plain values for the model file (``lanes`` only when set, so older readers still load
        every other model)."""
        d: dict[str, Any] = {"crop": list(self.crop), "resize": list(self.resize) if self.resize else None,
                             "color": self.color, "normalize": self.normalize,
                             "image_shape": list(self.image_shape) if self.image_shape else None}
        if self.lanes is not None:
            d["lanes"] = dict(self.lanes)
        # only when set, so that older readers still load every model that does not need them
        if self.color_first:
            d["color_first"] = True
        if self.blur:
            d["blur"] = self.blur
        if self.interpolation != "area":
            d["interpolation"] = self.interpolation
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Preprocess:
        """Inverse of :meth:`to_dict`; unknown keys are refused."""
        unknown = set(d) - {"crop", "resize", "color", "normalize", "image_shape", "lanes", "color_first", "blur",
                            "interpolation"}
        if unknown:
            raise ValueError(f"unknown preprocessing setting(s) {sorted(unknown)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


def preprocess_from_config(cfg: Any, model_type: str,
                           image_shape: tuple[int, int, int] | None = None) -> Preprocess:
    """The car's preprocessing for ``model_type``: ROI_CROP_* and PREPROCESS_* settings; where a
    PREPROCESS_* setting is None the model type's default applies (pilotnet: 66x200, YUV; lanes:
    [0, 1] and the lane image from the LANE_* settings; every other type: [-1, 1])."""
    from parts.pilots.models import model_type as lookup

    # [-1, 1] for every type: with [0, 1] inputs (DonkeyCar's) the linear model often sat on the
    # "predict the mean" plateau for several epochs of the demo; centred, it learns from the first
    defaults: dict[str, Any] = {"resize": None, "color": "rgb", "normalize": "symmetric"}
    defaults.update(getattr(lookup(model_type), "preprocess_defaults", {}))
    resize = cfg.PREPROCESS_RESIZE if cfg.PREPROCESS_RESIZE is not None else defaults["resize"]
    return Preprocess(
        crop=(cfg.ROI_CROP_TOP, cfg.ROI_CROP_BOTTOM, cfg.ROI_CROP_LEFT, cfg.ROI_CROP_RIGHT),
        resize=tuple(resize) if resize is not None else None,
        color=cfg.PREPROCESS_COLOR or defaults["color"],
        normalize=cfg.PREPROCESS_NORMALIZE or defaults["normalize"],
        image_shape=image_shape,
        lanes=_lane_settings(cfg) if defaults.get("lanes") else None,
        color_first=cfg.PREPROCESS_COLOR_FIRST,
        blur=cfg.PREPROCESS_BLUR,
        interpolation=cfg.PREPROCESS_INTERPOLATION,
    )


def _lane_settings(cfg: Any) -> dict[str, Any]:
    from parts.vision.lanes import LaneSettings

    return LaneSettings.from_config(cfg).to_dict()
