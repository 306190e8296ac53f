"""Photometric augmentations of a whole training batch at once: colour, light, noise, cutout.

They run on the uint8 batch tensor after preprocessing (cropped and resized, so on fewer pixels
than the camera frame), on the training device, just before the batch becomes floats
(:func:`training.fit.fit`), as a handful of tensor operations for the whole batch instead of one
OpenCV call per frame. Every sample gets its own random draw (each operation with its probability);
the frames of one sample (a sequence model's clip, a three-camera model's views) share it. They
run in a fixed order whatever the order of AUGMENTATIONS: light, colour, noise, cutout.
Geometric augmentations that change the steering label (flip, shift) stay per sample
(:class:`training.augment.Augmenter`). Validation and driving never augment.

The draws are reproducible: :meth:`BatchAugmenter.set_epoch` reseeds from (seed, epoch), and the
batches of an epoch then draw in order.
"""

from __future__ import annotations

import logging
import math

import cv2
import numpy as np
import torch

from training.augment import BATCH_AUGMENTATIONS, AugmentSettings

logger = logging.getLogger(__name__)

_LUMA = (0.299, 0.587, 0.114)
#: noise frames drawn once per run and shared out among the samples (see ``_noise``)
NOISE_BANK = 16


class BatchAugmenter:
    """The batch augmentations of ``settings.names`` (those in :data:`BATCH_AUGMENTATIONS`).

    Call with a uint8 batch (N, C, H, W) or (N, T, C, H, W) in RGB (C = 3); returns a new uint8
    tensor of the same shape on the same device.
    """

    def __init__(self, settings: AugmentSettings, seed: int = 0) -> None:
        self.settings = settings
        self.names = tuple(n for n in settings.names if n in BATCH_AUGMENTATIONS)
        self.seed = int(seed)
        self._gen: torch.Generator | None = None
        self._noise_bank: torch.Tensor | None = None
        self._epoch = 0

    def __bool__(self) -> bool:
        return bool(self.names)

    def set_epoch(self, epoch: int) -> None:
        """Start the draws of ``epoch`` (the same seed and epoch give the same draws)."""
        self._epoch = int(epoch)
        self._gen = None

    def _generator(self) -> torch.Generator:
        if self._gen is None:
            self._gen = torch.Generator()  # parameters are drawn on the CPU: the same on every device
            self._gen.manual_seed((self.seed * 1_000_003 + self._epoch) % 2**63)
        return self._gen

    def _u(self, n: int, lo: float, hi: float) -> torch.Tensor:
        return lo + (hi - lo) * torch.rand(n, generator=self._generator())

    def _on(self, n: int, p: float) -> torch.Tensor:
        return torch.rand(n, generator=self._generator()) < p

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        if not self.names:
            return x
        if x.dtype != torch.uint8:
            raise TypeError(f"batch augmentations take uint8 batches, got {x.dtype}")
        shape = x.shape
        if x.dim() == 4:
            x = x.unsqueeze(1)
        if x.dim() != 5 or x.shape[2] != 3:
            raise ValueError(f"batch augmentations need RGB batches (N, 3, H, W) or (N, T, 3, H, W), got "
                             f"{tuple(shape)}")
        n, dev = x.shape[0], x.device
        # light is a pointwise map: a 256-entry table per sample on the uint8 values; colour and
        # noise need floats (one conversion for both); cutout writes into the uint8 result
        if "light" in self.names:
            x = self._light(x, n)
        floats = [name for name in ("colour", "noise") if name in self.names]
        if floats:
            y = x.float().div_(255.0)
            for name in floats:
                y = getattr(self, f"_{name}")(y, n, dev)
            x = y.mul_(255.0).round_().clamp_(0.0, 255.0).to(torch.uint8)
        if "cutout" in self.names:
            x = self._cutout(x, n, dev)
        return x.reshape(shape)

    def _light(self, x: torch.Tensor, n: int) -> torch.Tensor:
        """A tone curve, then contrast around mid-grey, then brightness: a camera's exposure and
        response. The curve ``v + a * v * (1 - v)`` (values in [0, 1]) keeps black and white and
        lifts (a > 0) or lowers (a < 0) the mid-tones like a gamma of about 1 / (1 + a) would.
        Applied as one 256-entry table per sample (exact, and no float copy of the batch)."""
        s = self.settings
        on = self._on(n, s.light_p)
        a = torch.where(on, self._u(n, -s.light_curve, s.light_curve), 0.0).view(n, 1)
        c = torch.where(on, 1.0 + self._u(n, -s.light_contrast, s.light_contrast), 1.0).view(n, 1)
        b = torch.where(on, self._u(n, -s.light_brightness, s.light_brightness), 0.0).view(n, 1)
        v = torch.arange(256, dtype=torch.float32).view(1, 256) / 255.0
        lut = ((v + a * v * (1.0 - v) - 0.5) * c + 0.5 + b).mul_(255.0).round_().clamp_(0.0, 255.0)
        lut = lut.to(torch.uint8)
        if x.device.type == "cpu":
            out = np.empty(tuple(x.shape), np.uint8)
            xs = x.numpy()
            for i in range(n):
                frame = np.ascontiguousarray(xs[i]).reshape(-1, xs.shape[-1])
                out[i] = cv2.LUT(frame, lut[i].numpy()).reshape(xs.shape[1:])
            return torch.from_numpy(out)
        lut = lut.to(x.device)
        return torch.stack([lut[i][x[i].long()] for i in range(n)])

    def _colour(self, y: torch.Tensor, n: int, dev: torch.device) -> torch.Tensor:
        """Hue turned round the grey axis and saturation scaled: one 3x3 matrix per sample."""
        s = self.settings
        on = self._on(n, s.colour_p)
        theta = torch.where(on, self._u(n, -s.colour_hue, s.colour_hue), 0.0) * (math.pi / 180.0)
        sat = torch.where(on, 1.0 + self._u(n, -s.colour_saturation, s.colour_saturation), 1.0)
        k = torch.full((3,), 1.0 / math.sqrt(3.0))
        cross = torch.tensor([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        cos, sin = torch.cos(theta).view(n, 1, 1), torch.sin(theta).view(n, 1, 1)
        hue = cos * torch.eye(3) + sin * cross + (1 - cos) * torch.outer(k, k)  # Rodrigues' rotation
        luma = torch.tensor(_LUMA).expand(3, 3)  # every row: the luma weights
        sat_m = sat.view(n, 1, 1) * torch.eye(3) + (1 - sat.view(n, 1, 1)) * luma
        m = (sat_m @ hue).to(dev, y.dtype)
        return torch.einsum("nij,ntjhw->ntihw", m, y)

    def _noise(self, y: torch.Tensor, n: int, dev: torch.device) -> torch.Tensor:
        """Gaussian sensor noise of a random strength up to AUG_NOISE_SIGMA (0-255 units).

        The noise comes from a bank of ``NOISE_BANK`` noise frames drawn once, each sample taking
        one of them: drawing fresh Gaussian noise for every pixel of every batch cost more than
        the rest of the augmentations together."""
        s = self.settings
        sigma = torch.where(self._on(n, s.noise_p), self._u(n, 0.0, s.noise_sigma / 255.0), 0.0)
        shape = tuple(y.shape[1:])
        if self._noise_bank is None or self._noise_bank.shape[1:] != shape or self._noise_bank.device != y.device:
            bank_gen = torch.Generator().manual_seed(self.seed)
            self._noise_bank = torch.randn((NOISE_BANK, *shape), generator=bank_gen).to(dev, y.dtype)
        pick = torch.randint(0, NOISE_BANK, (n,), generator=self._generator()).to(dev)
        noise = self._noise_bank.index_select(0, pick)
        return y.addcmul_(noise, sigma.to(dev, y.dtype).view(n, 1, 1, 1, 1))

    def _cutout(self, x: torch.Tensor, n: int, dev: torch.device) -> torch.Tensor:
        """One rectangle per sample (up to AUG_CUTOUT_SIZE of each side) filled with a flat grey:
        something in front of the camera, or a patch of the view that tells nothing."""
        s = self.settings
        h, w = x.shape[-2:]
        on = self._on(n, s.cutout_p)
        fh, fw = self._u(n, 0.1, 1.0) * s.cutout_size, self._u(n, 0.1, 1.0) * s.cutout_size
        cy, cx = self._u(n, 0.0, 1.0), self._u(n, 0.0, 1.0)
        grey = torch.randint(0, 256, (n,), generator=self._generator()).to(dev, torch.uint8).view(n, 1, 1, 1, 1)
        ys = torch.arange(h).float().view(1, h, 1) / h
        xs = torch.arange(w).float().view(1, 1, w) / w
        inside = ((ys - cy.view(n, 1, 1)).abs() < fh.view(n, 1, 1) / 2) & \
            ((xs - cx.view(n, 1, 1)).abs() < fw.view(n, 1, 1) / 2) & on.view(n, 1, 1)
        return torch.where(inside.to(dev).view(n, 1, 1, h, w), grey, x)
