"""Where a pilot looks: saliency maps of a PyTorch pilot model, per output and per input stream.

Three methods, all on the model's own preprocessed input (:mod:`parts.pilots.preprocess`):

- ``integrated``: integrated gradients (Sundararajan et al. 2017) from a baseline of the frame's
  mean colour, ``samples`` steps of a midpoint Riemann sum in one batch; attribution
  ``(x - baseline) * mean gradient``, its magnitude summed over the channels. What the pilot's
  output owes to each pixel, relative to a frame with nothing in it.
- ``smoothgrad``: SmoothGrad (Smilkov et al. 2017) of gradient x input: ``(x' - baseline) *
  gradient`` averaged over ``samples`` copies ``x'`` of the input with Gaussian noise (15 % of the
  input range), its magnitude summed over the channels.
- ``occlusion``: the output's change when a square patch (1/8 of the shorter side, patches side
  by side) is painted the frame's mean colour; forwards only, no gradient. Coarse, model-agnostic.

Steering and throttle are explained separately (``output``): the differentiable value each model
type drives with (the expectation over the bins of a categorical model, the throttle a ``inferred``
model derives from its steering). A model whose input has several streams gets one map per
stream: the lanes models' camera and lane image (:attr:`PilotModel.input_streams`), the
three-camera model's views; a sequence model's map is that of its newest frame.

    explainer = Explainer.from_file("models/mypilot.pt")
    sal = explainer.explain([frame], output="steering", method="integrated")
    pictures = explainer.overlays([frame], sal)  # stream -> RGB frame with the heat map
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import torch

    from parts.pilots.models import PilotModel
    from parts.pilots.preprocess import Preprocess

logger = logging.getLogger(__name__)

METHODS = ("integrated", "smoothgrad", "occlusion")
OUTPUTS = ("steering", "throttle")
#: SmoothGrad's noise, as a share of the input's value range (the paper finds 10-20 % best)
NOISE_SHARE = 0.15
#: frames per forward pass of the occlusion method (bounds memory: 64 x 3 x 120 x 160 floats = 15 MB)
OCCLUSION_BATCH = 64


@dataclass(frozen=True)
class Saliency:
    """One explanation: ``maps`` = stream name -> float32 (H, W) map of the model input, in [0, 1]
    (1 = the most salient pixel, robustly: the 99.5th percentile); ``prediction`` = the model's
    (steering, throttle) on the unperturbed input."""

    output: str
    method: str
    maps: dict[str, np.ndarray]
    prediction: tuple[float, float]


class Explainer:
    """Saliency of one pilot model with its preprocessing (see the module docstring)."""

    def __init__(self, model: PilotModel, preprocess: Preprocess) -> None:
        self.model = model.eval()
        self.preprocess = preprocess

    @classmethod
    def from_file(cls, path: str | Path) -> Explainer:
        """The explainer of a model file (loaded safely, :func:`parts.pilots.modelfile.load_model`).

        Raises:
            parts.pilots.errors.ModelFileError: the file is not a readable model file.
        """
        from parts.pilots.modelfile import load_model
        from parts.pilots.preprocess import Preprocess

        model, meta = load_model(path)
        return cls(model, Preprocess.from_dict(meta.get("preprocess") or {}))

    # -- inputs ------------------------------------------------------------------------------------
    @property
    def frames_needed(self) -> int:
        """Camera frames per explanation: the views (three_camera) or the sequence (rnn, 3d)."""
        return self.model.views * self.model.frames

    def streams(self) -> list[str]:
        """Names of the maps :meth:`explain` returns."""
        if self.model.views > 1:
            return list(self.model.image_inputs)
        return list(self.model.input_streams)

    def check_frames(self, frames: Sequence[np.ndarray]) -> None:
        """ValueError (one line) when ``frames`` are not what the model takes: the count, or a frame
        size other than the one it was trained on (ModelMismatch)."""
        if len(frames) != self.frames_needed:
            raise ValueError(f"model type {self.model.type_name!r} takes {self.frames_needed} frame(s) per "
                             f"explanation, got {len(frames)}")
        for f in frames:
            self.preprocess.check_frame_shape(np.shape(f))

    def inputs(self, frames: Sequence[np.ndarray], extra: Sequence[float] | None = None
               ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """The model's (images, extra) batch of one sample: ``frames`` are uint8 HxWx3 RGB camera
        frames (views left to right, or a sequence oldest first); ``extra`` the behaviour one-hot or
        command history (default: the first behaviour, or no previous command)."""
        import torch

        self.check_frames(frames)
        x = torch.from_numpy(np.stack([self.preprocess.array(f) for f in frames]))
        x = x[None] if len(frames) > 1 else x  # (1, T|V, C, H, W) or (1, C, H, W)
        size = self.model.extra_size
        if not size:
            return x, None
        if extra is None:
            extra = [0.0] * size
            if self.model.extra_inputs:  # a one-hot: the first behaviour
                extra[0] = 1.0
        e = torch.tensor([list(map(float, extra))], dtype=torch.float32)
        if e.shape[1] != size:
            raise ValueError(f"model type {self.model.type_name!r} takes {size} extra values, got {e.shape[1]}")
        return x, e

    # -- outputs -----------------------------------------------------------------------------------
    def _drive_values(self, raw: torch.Tensor) -> torch.Tensor:
        """(N, 2) differentiable (steering, throttle) from the model's raw output."""
        import torch

        from parts.pilots.models.cnn import CategoricalModel, InferredModel

        m = self.model
        if isinstance(m, CategoricalModel):  # argmax has no gradient: the expected bin instead
            a = torch.softmax(raw[:, :m.angle_bins], 1) @ torch.linspace(-1, 1, m.angle_bins)
            t = torch.softmax(raw[:, m.angle_bins:], 1) @ torch.linspace(0, m.throttle_range, m.throttle_bins)
            return torch.stack([a, t], 1)
        if isinstance(m, InferredModel):
            return m.controls(raw)
        return raw[:, :2]

    def predict(self, frames: Sequence[np.ndarray], extra: Sequence[float] | None = None) -> tuple[float, float]:
        """The model's (steering, throttle) for these frames, as it drives (``controls``)."""
        import torch

        x, e = self.inputs(frames, extra)
        with torch.no_grad():
            c = self.model.controls(self.model(x, e))[0]
        return float(c[0]), float(c[1])

    # -- explanation ------------------------------------------------------------------------------
    def explain(self, frames: Sequence[np.ndarray], extra: Sequence[float] | None = None, *,
                output: str = "steering", method: str = "integrated", samples: int = 16,
                seed: int = 0) -> Saliency:
        """The saliency of ``output`` (steering or throttle) by ``method`` (see the module docstring).

        Raises:
            ValueError: an unknown output or method, ``samples`` < 1, or frames the model does not
                take (count, or size: :class:`parts.pilots.compat.ModelMismatch`).
        """
        import torch

        if output not in OUTPUTS:
            raise ValueError(f"output must be one of {OUTPUTS}, got {output!r}")
        if method not in METHODS:
            raise ValueError(f"saliency method must be one of {METHODS}, got {method!r}")
        if not isinstance(samples, int) or isinstance(samples, bool) or samples < 1:
            raise ValueError(f"samples must be a whole number >= 1, got {samples!r}")
        x, e = self.inputs(frames, extra)
        which = OUTPUTS.index(output)
        with torch.no_grad():
            prediction = tuple(float(v) for v in self.model.controls(self.model(x, e))[0])
        if method == "occlusion":
            raw = self._occlusion(x, e, which)
        else:
            raw = self._gradient(x, e, which, method, samples, seed)
        return Saliency(output, method, self._split(raw), prediction)  # type: ignore[arg-type]

    def _baseline(self, x: torch.Tensor) -> torch.Tensor:
        """The frame's mean colour, per channel (a frame with nothing in it)."""
        return x.mean(dim=(-2, -1), keepdim=True).expand_as(x)

    def _gradient(self, x: torch.Tensor, e: torch.Tensor | None, which: int, method: str, samples: int,
                  seed: int) -> torch.Tensor:
        """|attribution| (integrated) or |mean gradient| (smoothgrad), same shape as ``x``'s sample."""
        import torch

        if method == "integrated":
            base = self._baseline(x)
            alphas = (torch.arange(samples, dtype=torch.float32) + 0.5) / samples  # midpoint rule
            shape = (samples,) + (1,) * (x.dim() - 1)
            batch = base + alphas.view(shape) * (x - base)
        else:
            gen = torch.Generator().manual_seed(seed)
            sigma = NOISE_SHARE * float(x.max() - x.min()) or NOISE_SHARE
            batch = x + sigma * torch.randn((samples, *x.shape[1:]), generator=gen)
        batch.requires_grad_(True)
        extra = e.expand(samples, -1) if e is not None else None
        with torch.enable_grad():
            value = self._drive_values(self.model(batch, extra))[:, which].sum()
            (grad,) = torch.autograd.grad(value, batch)
        # gradient x input (from the baseline): a pixel matters by how much it is there and how much
        # the output cares; pure gradients light up where nothing is (tested: they missed the line)
        if method == "integrated":
            mean = grad.mean(0) * (x[0] - self._baseline(x)[0])
        else:
            mean = (grad * (batch.detach() - self._baseline(x))).mean(0)
        return mean.abs()

    def _occlusion(self, x: torch.Tensor, e: torch.Tensor | None, which: int) -> torch.Tensor:
        """|change of the output| when each patch is painted the mean colour, spread over the patch."""
        import torch

        h, w = x.shape[-2:]
        patch = max(2, min(h, w) // 8)
        stride = patch  # side by side: 8 x 16 forwards on 80x160 (half a patch: 4x as many, measured 1 s)
        base = self._baseline(x)[0]
        spots = [(r, c) for r in range(0, max(1, h - patch + stride), stride)
                 for c in range(0, max(1, w - patch + stride), stride)]
        with torch.no_grad():
            ref = self._drive_values(self.model(x, e))[0, which]
            changes = []
            for i in range(0, len(spots), OCCLUSION_BATCH):
                chunk = spots[i:i + OCCLUSION_BATCH]
                batch = x.expand(len(chunk), *x.shape[1:]).clone()
                for k, (r, c) in enumerate(chunk):
                    batch[k, ..., r:r + patch, c:c + patch] = base[..., r:r + patch, c:c + patch]
                extra = e.expand(len(chunk), -1) if e is not None else None
                changes.append((self._drive_values(self.model(batch, extra))[:, which] - ref).abs())
        change = torch.cat(changes)
        total = torch.zeros(x.shape[1:])
        count = torch.zeros(x.shape[1:])
        for (r, c), d in zip(spots, change, strict=True):
            total[..., r:r + patch, c:c + patch] += d
            count[..., r:r + patch, c:c + patch] += 1
        return total / count.clamp(min=1)

    def _split(self, attribution: torch.Tensor) -> dict[str, np.ndarray]:
        """Per stream: summed over its channels, normalised to [0, 1]."""
        a = attribution.detach().float().numpy()
        m = self.model
        if m.views > 1:  # (V, C, H, W): one map per view
            return {key: _normalise(a[i].sum(0)) for i, key in enumerate(m.image_inputs)}
        if m.frames > 1:  # (T, C, H, W): the newest frame
            a = a[-1]
        return {name: _normalise(a[slice(*span)].sum(0)) for name, span in m.input_streams.items()}

    # -- pictures ----------------------------------------------------------------------------------
    def overlays(self, frames: Sequence[np.ndarray], saliency: Saliency, alpha: float = 0.6) -> dict[str, np.ndarray]:
        """Per stream, an RGB uint8 picture with the map as a heat overlay: a camera stream on the
        camera frame (the map placed back where the crop took it from), the lane stream on the lane
        image the model saw. The newest frame of a sequence; each view of a three-camera model."""
        out = {}
        views = list(frames) if self.model.views > 1 else [frames[-1]]
        for name, sal in saliency.maps.items():
            if self.model.views > 1:
                frame = views[list(self.model.image_inputs).index(name)]
                out[name] = heat_overlay(frame, self._frame_map(sal, frame.shape), alpha)
            elif name == "lanes":
                lane = self.preprocess.frame(views[0])[:, :, -1]
                out[name] = heat_overlay(np.repeat(lane[:, :, None], 3, axis=2), sal, alpha)
            else:
                out[name] = heat_overlay(views[0], self._frame_map(sal, views[0].shape), alpha)
        return out

    def _frame_map(self, sal: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
        """A model-input map placed on the camera frame: resized to the cropped area (0 outside)."""
        import cv2

        top, bottom, left, right = self.preprocess.crop
        h, w = shape[0], shape[1]
        full = np.zeros((h, w), np.float32)
        full[top:h - bottom, left:w - right] = cv2.resize(sal, (w - left - right, h - top - bottom),
                                                          interpolation=cv2.INTER_LINEAR)
        return full


def _normalise(a: np.ndarray) -> np.ndarray:
    """``a`` scaled to [0, 1] by its 99.5th percentile (one hot pixel does not dim the rest)."""
    a = np.nan_to_num(a.astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    top = float(np.percentile(a, 99.5))
    if top <= 0:
        top = float(a.max())
    return np.clip(a / top, 0.0, 1.0) if top > 0 else np.zeros_like(a)


def heat_overlay(frame: np.ndarray, sal: np.ndarray, alpha: float = 0.6) -> np.ndarray:
    """RGB ``frame`` with ``sal`` (same H, W, values in [0, 1]) as a heat map (OpenCV's inferno),
    opaque where salient and clear where not, so the frame stays readable."""
    import cv2

    if sal.shape != frame.shape[:2]:
        sal = cv2.resize(sal, (frame.shape[1], frame.shape[0]), interpolation=cv2.INTER_LINEAR)
    heat = cv2.applyColorMap((np.clip(sal, 0, 1) * 255).astype(np.uint8), cv2.COLORMAP_INFERNO)
    heat = cv2.cvtColor(heat, cv2.COLOR_BGR2RGB).astype(np.float32)
    weight = (alpha * np.clip(sal, 0, 1))[:, :, None]
    return (frame.astype(np.float32) * (1 - weight) + heat * weight).round().astype(np.uint8)
