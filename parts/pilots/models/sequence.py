"""Sequence model types over the last ``seq_length`` frames: ``rnn`` (CNN per frame + LSTM) and
``3d`` (3D convolutions over time and space)."""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from parts.pilots.models.base import FastDropout, PilotModel, check_option, dense_head, donkey_convs, flat_size


class _SequenceModel(PilotModel):
    defaults: dict[str, Any] = {"dropout": 0.2, "seq_length": 3}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__(input_shape, options)
        self.seq_length = check_option(self.options, "seq_length", int, 2)
        self.dropout = check_option(self.options, "dropout", float, 0.0)

    @property
    def frames(self) -> int:
        return self.seq_length

    def _check(self, images: torch.Tensor) -> None:
        if images.dim() != 5 or images.shape[1] != self.seq_length:
            raise ValueError(f"model type {self.type_name!r} takes (N, {self.seq_length}, C, H, W) "
                             f"image batches, got shape {tuple(images.shape)}")


class RNNModel(_SequenceModel):
    """DonkeyCar's core CNN on every frame (shared weights), dense 100, an LSTM of 64 over the
    frames, then dense 50 and (angle, throttle); MSE."""

    type_name = "rnn"

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__(input_shape, options)
        self.features = donkey_convs(input_shape[0], self.dropout)
        size = flat_size(self.features, input_shape)
        self.embed = nn.Sequential(nn.Linear(size, 100), nn.ReLU(inplace=True))
        self.lstm = nn.LSTM(100, 64, batch_first=True)
        self.head = dense_head(64, (50,), 2, self.dropout)

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        self._check(images)
        n, t = images.shape[:2]
        x = self.embed(self.features(images.flatten(0, 1))).view(n, t, -1)
        out, _ = self.lstm(x)
        return self.head(out[:, -1])


class Conv3DModel(_SequenceModel):
    """3D convolutions (time x height x width) 16/32 5x5 over 3 frames, 64 5x5, 64 3x3, dense 100,
    50 and (angle, throttle); MSE."""

    type_name = "3d"

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__(input_shape, options)
        c = input_shape[0]
        layers: list[nn.Module] = []
        # Temporal kernel 3 with padding 1 keeps the number of frames; spatial stride 2 as in the 2D CNN.
        plan = ((c, 16, 5, 2, 3), (16, 32, 5, 2, 3), (32, 64, 5, 2, 1), (64, 64, 3, 1, 1))
        for in_ch, out_ch, k, s, tk in plan:
            layers += [nn.Conv3d(in_ch, out_ch, (tk, k, k), stride=(1, s, s), padding=(tk // 2, 0, 0)),
                       nn.ReLU(inplace=True), FastDropout(self.dropout)]
        layers.append(nn.Flatten())
        self.features = nn.Sequential(*layers)
        size = flat_size(_Permuted(self.features), (self.seq_length, *input_shape))
        self.head = dense_head(size, (100, 50), 2, self.dropout)

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        self._check(images)
        return self.head(self.features(images.transpose(1, 2)))  # (N, C, T, H, W) for Conv3d


class _Permuted(nn.Module):
    """(N, T, C, H, W) -> module on (N, C, T, H, W); used to size the 3D features."""

    def __init__(self, inner: nn.Module) -> None:
        super().__init__()
        self.inner = inner

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.inner(x.transpose(1, 2))
