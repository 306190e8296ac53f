"""Training-only image augmentations, each applied with its own probability.

An :class:`Augmenter` draws the operations for one sample (:meth:`Augmenter.draw`), in the order
the settings list them, then applies the same draw to every frame of that sample (sequence models
see one consistent clip) and corrects the steering label (flip negates it, a horizontal shift adds
a correction). Images are uint8 HxWx3 RGB camera frames, before preprocessing. Validation and
driving never augment.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from vehicle.config import check_settings

#: augmentations of one frame at a time (OpenCV), in the order listed
SAMPLE_AUGMENTATIONS = ("flip", "brightness", "multiply", "shadow", "shift", "zoom", "blur", "hue")
#: augmentations of the whole batch tensor at once (:mod:`training.batch_augment`), after the
#: per-frame ones and the preprocessing, in the order listed
BATCH_AUGMENTATIONS = ("light", "colour", "noise", "cutout")
AUGMENTATION_NAMES = SAMPLE_AUGMENTATIONS + BATCH_AUGMENTATIONS
BORDERS = ("replicate", "constant")
_CV2_BORDER = {"replicate": cv2.BORDER_REPLICATE, "constant": cv2.BORDER_CONSTANT}


@dataclass(frozen=True)
class AugmentSettings:
    """Which augmentations run (in the order of ``names``), their probabilities and ranges (see
    AUG_* in the config)."""

    names: tuple[str, ...] = ("flip", "shift", "brightness", "shadow")
    flip_p: float = 0.5
    brightness_p: float = 0.5
    brightness_range: float = 0.2
    contrast_range: float = 0.2
    multiply_p: float = 0.5
    multiply_range: tuple[float, float] = (0.2, 1.2)
    shadow_p: float = 0.3
    shadow_darkness: float = 0.5
    shift_p: float = 0.5
    shift_x: float = 0.1
    shift_y: float = 0.05
    shift_steering: float = 1.0
    zoom_p: float = 0.3
    zoom_range: float = 0.3
    blur_p: float = 0.2
    blur_range: tuple[float, float] = (0.5, 1.5)
    hue_p: float = 0.3
    hue_range: float = 180.0
    border: str = "replicate"
    light_p: float = 0.5
    light_brightness: float = 0.25
    light_contrast: float = 0.3
    light_curve: float = 0.5
    colour_p: float = 0.5
    colour_hue: float = 30.0
    colour_saturation: float = 0.5
    noise_p: float = 0.3
    noise_sigma: float = 12.0
    cutout_p: float = 0.3
    cutout_size: float = 0.3

    def __post_init__(self) -> None:
        names = tuple(str(n).lower() for n in self.names)
        unknown = [n for n in names if n not in AUGMENTATION_NAMES]
        if unknown:
            raise ValueError(f"unknown augmentation(s) {unknown}; choose from {AUGMENTATION_NAMES}")
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"augmentation(s) {twice} listed twice in AUGMENTATIONS; list each once")
        object.__setattr__(self, "names", names)
        # the settings' own bounds (training/settings.py), then what a range cannot say: low <= high
        check_settings(AUG_BORDER=self.border, AUG_MULTIPLY_RANGE=tuple(self.multiply_range),
                       AUG_BLUR_RANGE=tuple(self.blur_range), AUG_SHADOW_DARKNESS=self.shadow_darkness,
                       AUG_HUE_RANGE=self.hue_range, AUG_LIGHT_CURVE=self.light_curve,
                       AUG_LIGHT_BRIGHTNESS=self.light_brightness, AUG_LIGHT_CONTRAST=self.light_contrast,
                       AUG_COLOUR_HUE=self.colour_hue, AUG_COLOUR_SATURATION=self.colour_saturation,
                       AUG_NOISE_SIGMA=self.noise_sigma, AUG_CUTOUT_SIZE=self.cutout_size,
                       **{f"AUG_{name.upper()}_P": getattr(self, f"{name}_p") for name in AUGMENTATION_NAMES})
        for setting, (lo, hi) in (("AUG_MULTIPLY_RANGE", self.multiply_range), ("AUG_BLUR_RANGE", self.blur_range)):
            if lo > hi:
                raise ValueError(f"{setting} = {(lo, hi)}: give (low, high) with low <= high")

    @classmethod
    def from_config(cls, cfg: Any, names: list[str] | tuple[str, ...] | None = None) -> AugmentSettings:
        """Settings from the car's AUGMENTATIONS and AUG_* values (``names`` overrides the list)."""
        return cls(names=tuple(cfg.AUGMENTATIONS if names is None else names),
                   flip_p=cfg.AUG_FLIP_P, brightness_p=cfg.AUG_BRIGHTNESS_P,
                   brightness_range=cfg.AUG_BRIGHTNESS_RANGE, contrast_range=cfg.AUG_CONTRAST_RANGE,
                   multiply_p=cfg.AUG_MULTIPLY_P, multiply_range=tuple(cfg.AUG_MULTIPLY_RANGE),
                   shadow_p=cfg.AUG_SHADOW_P, shadow_darkness=cfg.AUG_SHADOW_DARKNESS,
                   shift_p=cfg.AUG_SHIFT_P, shift_x=cfg.AUG_SHIFT_X, shift_y=cfg.AUG_SHIFT_Y,
                   shift_steering=cfg.AUG_SHIFT_STEERING, zoom_p=cfg.AUG_ZOOM_P,
                   zoom_range=cfg.AUG_ZOOM_RANGE, blur_p=cfg.AUG_BLUR_P,
                   blur_range=tuple(cfg.AUG_BLUR_RANGE), hue_p=cfg.AUG_HUE_P, hue_range=cfg.AUG_HUE_RANGE,
                   border=cfg.AUG_BORDER, light_p=cfg.AUG_LIGHT_P, light_brightness=cfg.AUG_LIGHT_BRIGHTNESS,
                   light_contrast=cfg.AUG_LIGHT_CONTRAST, light_curve=cfg.AUG_LIGHT_CURVE,
                   colour_p=cfg.AUG_COLOUR_P, colour_hue=cfg.AUG_COLOUR_HUE,
                   colour_saturation=cfg.AUG_COLOUR_SATURATION, noise_p=cfg.AUG_NOISE_P,
                   noise_sigma=cfg.AUG_NOISE_SIGMA, cutout_p=cfg.AUG_CUTOUT_P, cutout_size=cfg.AUG_CUTOUT_SIZE)

    def to_dict(self) -> dict[str, Any]:
        """Plain values (stored in the model file's training config)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in self.__dict__.items()}


Draw = list[tuple[str, dict[str, float]]]
_SHORT = {"flip": "flip", "brightness": "bright", "multiply": "mult", "shadow": "shadow", "shift": "shift",
          "zoom": "zoom", "blur": "blur", "hue": "hue"}


class Augmenter:
    """Random augmentations of training frames with steering correction."""

    def __init__(self, settings: AugmentSettings) -> None:
        self.settings = settings

    def draw(self, rng: np.random.Generator) -> Draw:
        """Choose the operations and their parameters for one sample."""
        s = self.settings
        ops: Draw = []
        for name in s.names:
            if name in BATCH_AUGMENTATIONS:  # drawn per batch (training.batch_augment)
                continue
            if rng.random() >= getattr(s, f"{name}_p"):
                continue
            if name == "flip":
                ops.append((name, {}))
            elif name == "shift":
                ops.append((name, {"dx": rng.uniform(-s.shift_x, s.shift_x),
                                   "dy": rng.uniform(-s.shift_y, s.shift_y)}))
            elif name == "zoom":
                ops.append((name, {"scale": 1.0 + rng.uniform(0.0, s.zoom_range)}))
            elif name == "hue":
                ops.append((name, {"degrees": rng.uniform(-s.hue_range, s.hue_range)}))
            elif name == "brightness":
                ops.append((name, {"beta": rng.uniform(-s.brightness_range, s.brightness_range) * 255.0,
                                   "alpha": 1.0 + rng.uniform(-s.contrast_range, s.contrast_range)}))
            elif name == "multiply":
                ops.append((name, {"factor": rng.uniform(*s.multiply_range)}))
            elif name == "shadow":
                # A band from the top edge to the bottom edge, darkening one side of it.
                ops.append((name, {"top": rng.uniform(0, 1), "bottom": rng.uniform(0, 1),
                                   "side": float(rng.integers(0, 2)),
                                   "factor": rng.uniform(s.shadow_darkness, 1.0)}))
            else:
                ops.append((name, {"sigma": rng.uniform(*s.blur_range)}))
        return ops

    def steering(self, angle: float, ops: Draw) -> float:
        """The label for the augmented frame: negated when flipped, corrected for a shift, in [-1, 1]."""
        for name, p in ops:
            if name == "flip":
                angle = -angle
            elif name == "shift":
                angle += self.settings.shift_steering * p["dx"]
        return float(np.clip(angle, -1.0, 1.0))

    @staticmethod
    def flipped(ops: Draw) -> bool:
        """Whether the draw mirrors the frame (a memory model's previous angles flip too)."""
        return any(name == "flip" for name, _ in ops)

    def apply(self, image: np.ndarray, ops: Draw) -> np.ndarray:
        """Apply a draw to one uint8 HxWx3 frame; returns a new array (the input is never changed)."""
        h, w = image.shape[:2]
        border = _CV2_BORDER[self.settings.border]
        out = image
        for name, p in ops:
            if name == "flip":
                out = cv2.flip(out, 1)
            elif name == "shift":
                m = np.float32([[1, 0, p["dx"] * w], [0, 1, p["dy"] * h]])
                out = cv2.warpAffine(out, m, (w, h), borderMode=border)
            elif name == "zoom":
                m = cv2.getRotationMatrix2D((w / 2.0, h / 2.0), 0.0, p["scale"])
                out = cv2.warpAffine(out, m, (w, h), borderMode=border)
            elif name == "hue":
                # Turn every colour round the colour wheel (grey, white and black stay): yellow tape
                # becomes blue, green grass purple; OpenCV's 8-bit hue is 0-179 (2 degrees a step).
                hsv = cv2.cvtColor(out, cv2.COLOR_RGB2HSV)
                step = int(round(p["degrees"] / 2.0)) % 180
                lut = ((np.arange(256) + step) % 180).astype(np.uint8)
                hsv[..., 0] = cv2.LUT(hsv[..., 0], lut)
                out = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
            elif name == "brightness":
                # Contrast around mid-grey, then brightness; a lookup table is exact and fast on uint8.
                lut = (np.arange(256, dtype=np.float32) - 128.0) * p["alpha"] + 128.0 + p["beta"]
                out = cv2.LUT(out, np.clip(np.rint(lut), 0, 255).astype(np.uint8))
            elif name == "multiply":
                # every value times one factor, rounded and clipped (imgaug's Multiply on uint8)
                lut = np.arange(256, dtype=np.float32) * np.float32(p["factor"])
                out = cv2.LUT(out, np.clip(np.rint(lut), 0, 255).astype(np.uint8))
            elif name == "shadow":
                ys = np.arange(h, dtype=np.float32)[:, None] / max(h - 1, 1)
                edge = (p["top"] + (p["bottom"] - p["top"]) * ys) * w
                xs = np.arange(w, dtype=np.float32)[None, :]
                mask = (xs < edge) if p["side"] < 0.5 else (xs >= edge)
                # the darkened copy through a lookup table (exactly rint(v * factor) in float32),
                # copied in where the mask says: 3-4x cheaper than scaling the frame in floats
                lut = np.rint(np.arange(256, dtype=np.float32) * np.float32(p["factor"])).astype(np.uint8)
                shaded = out.copy() if out is image else out
                out = cv2.copyTo(cv2.LUT(out, lut), mask.view(np.uint8), shaded)
            elif name == "blur":
                out = cv2.GaussianBlur(out, (0, 0), p["sigma"])
        return out if out is not image else image.copy()

    def __call__(self, image: np.ndarray, angle: float, rng: np.random.Generator) -> tuple[np.ndarray, float]:
        """Augment one frame and its steering label."""
        ops = self.draw(rng)
        return self.apply(image, ops), self.steering(angle, ops)


def preview_grid(frames: list[np.ndarray], angles: list[float], augmenter: Augmenter,
                 variants: int = 5, seed: int = 0, scale: int = 2) -> np.ndarray:
    """A uint8 RGB image: one row per frame, the original then ``variants`` augmented copies, each
    labelled with its steering and the operations applied."""
    if not frames:
        raise ValueError("preview_grid needs at least one frame")
    rng = np.random.default_rng(seed)
    h, w = frames[0].shape[:2]
    cell_h, cell_w = h * scale, w * scale
    grid = np.zeros((len(frames) * cell_h, (variants + 1) * cell_w, 3), np.uint8)
    for r, (frame, angle) in enumerate(zip(frames, angles, strict=True)):
        if frame.shape[:2] != (h, w):
            frame = cv2.resize(frame, (w, h), interpolation=cv2.INTER_AREA)
        for c in range(variants + 1):
            ops = [] if c == 0 else augmenter.draw(rng)
            img = augmenter.apply(frame, ops) if ops else frame.copy()
            label = f"{augmenter.steering(angle, ops):+.2f}"
            names = ",".join(_SHORT[n] for n, _ in ops) if c else "orig"
            cell = cv2.resize(img, (cell_w, cell_h), interpolation=cv2.INTER_NEAREST)
            for text, y in ((label, 14), (names, cell_h - 6)):
                cv2.putText(cell, text, (4, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 3, cv2.LINE_AA)
                cv2.putText(cell, text, (4, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 0), 1, cv2.LINE_AA)
            grid[r * cell_h:(r + 1) * cell_h, c * cell_w:(c + 1) * cell_w] = cell
    return grid


def preview_frames(tubs: list[Any], rows: int) -> tuple[list[np.ndarray], list[float]]:
    """``rows`` frames spread evenly over the (not deleted) records of ``tubs``, with their steering.

    Reads the tubs directly (no torch): the trainer console's web server calls it.
    """
    from parts.tub.reader import load_records

    if rows < 1:
        raise ValueError(f"rows must be >= 1, got {rows}")
    records = [r for r in load_records(tubs) if r.angle is not None]
    if not records:
        raise ValueError(f"no records with a steering angle in {', '.join(map(str, tubs))}")
    picks = np.unique(np.linspace(0, len(records) - 1, min(rows, len(records))).round().astype(int))
    return [records[i].image() for i in picks], [float(records[i].angle) for i in picks]
