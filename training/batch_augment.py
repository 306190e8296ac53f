"""Photometric augmentations of a whole training batch at once: colour, light, noise, cutout.

They run on the uint8 batch tensor after preprocessing (cropped and resized, so on fewer pixels
than the camera frame), on the training device, just before the batch becomes floats
(:func:`training.fit.fit`), as a handful of tensor operations for the whole batch instead of one
OpenCV call per frame. Every sample gets its own random draw (each operation with its probability);
the frames of one sample (a sequence model's clip, a three-camera model's views) share it.
Geometric augmentations that change the steering label (flip, shift) stay per sample
(:class:`training.augment.Augmenter`). Validation and driving never augment.

The draws are reproducible: :meth:`BatchAugmenter.set_epoch` reseeds from (seed, epoch), and the
batches of an epoch then draw in order.
"""

from __future__ import annotations

import logging
import math

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
        y = x.float().div_(255.0)
        for name in self.names:
            y = getattr(self, f"_{name}")(y, n, dev)
        return y.mul_(255.0).round_().clamp_(0.0, 255.0).to(torch.uint8).reshape(shape)

    # each operation: y float (N, T, 3, H, W) in [0, 1] (not clipped between operations)

    def _light(self, y: torch.Tensor, n: int, dev: torch.device) -> torch.Tensor:
        """A tone curve, then contrast around mid-grey, then brightness: a camera's exposure and
        response. The curve ``y + a * y * (1 - y)`` keeps black and white and lifts (a > 0) or
        lowers (a < 0) the mid-tones like a gamma of about 1 / (1 + a) would, at the cost of two
        multiplications instead of a power."""
        s = self.settings
        on = self._on(n, s.light_p)
        curve = torch.where(on, self._u(n, -s.light_curve, s.light_curve), 0.0)
        contrast = torch.where(on, 1.0 + self._u(n, -s.light_contrast, s.light_contrast), 1.0)
        bright = torch.where(on, self._u(n, -s.light_brightness, s.light_brightness), 0.0)
        view = (n, 1, 1, 1, 1)
        a, c, b = (v.to(dev, y.dtype).view(view) for v in (curve, contrast, bright))
        y = y.clamp_(0.0, 1.0)
        y = y.addcmul_(y * (1.0 - y), a)
        return y.sub_(0.5).mul_(c).add_(0.5 + b)

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

    def _cutout(self, y: torch.Tensor, n: int, dev: torch.device) -> torch.Tensor:
        """One rectangle per sample (up to AUG_CUTOUT_SIZE of each side) filled with a flat grey:
        something in front of the camera, or a patch of the view that tells nothing."""
        s = self.settings
        h, w = y.shape[-2:]
        on = self._on(n, s.cutout_p)
        fh, fw = self._u(n, 0.1, 1.0) * s.cutout_size, self._u(n, 0.1, 1.0) * s.cutout_size
        cy, cx = self._u(n, 0.0, 1.0), self._u(n, 0.0, 1.0)
        grey = self._u(n, 0.0, 1.0).to(dev, y.dtype).view(n, 1, 1, 1, 1)
        ys = torch.arange(h).float().view(1, h, 1) / h
        xs = torch.arange(w).float().view(1, 1, w) / w
        inside = ((ys - cy.view(n, 1, 1)).abs() < fh.view(n, 1, 1) / 2) & \
            ((xs - cx.view(n, 1, 1)).abs() < fw.view(n, 1, 1) / 2) & on.view(n, 1, 1)
        return torch.where(inside.to(dev).view(n, 1, 1, h, w), grey, y)
