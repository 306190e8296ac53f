"""NVIDIA DAVE-2 (PilotNet) as the Udacity projects use it, and the thesis's NVIDIA variant for Donkey."""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from parts.pilots.models.base import (
    DAVE2_CONVS,
    FastDropout,
    PilotModel,
    check_option,
    conv_stack,
    dense_head,
    flat_size,
)
from parts.pilots.models.cnn import InferredModel


class PilotNetModel(InferredModel):
    """Conv 24/36/48 5x5 stride 2, conv 64/64 3x3, dropout, dense 100/50/10/1 (252,219 parameters
    on a 3x66x200 input). Its preprocessing defaults follow the paper: resize to 66x200, YUV,
    normalise to [-1, 1]. One output (steering); throttle as for ``inferred``.

    Options: ``activation`` "relu" (the Udacity project, seed 001) or "elu" (Track Driver AI,
    seed 000); ``dropout`` after the last convolution (0.5 as seed 001; 0 = none, as seed 000);
    ``batch_norm`` after each convolution (the thesis's §8.6 practice; changes the count).
    """

    type_name = "pilotnet"
    defaults = {"dropout": 0.5, "activation": "relu", "batch_norm": False, "throttle_max": 0.5,
                "throttle_min": 0.2, "throttle_decay": 3.0}
    #: preprocessing this type defaults to where the car's config leaves a choice open (None)
    preprocess_defaults: dict[str, Any] = {"resize": [66, 200], "color": "yuv", "normalize": "symmetric"}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        # Skip LinearModel's layers: build DAVE-2's own.
        self.throttle_max = check_option(options, "throttle_max", float)
        self.throttle_min = check_option(options, "throttle_min", float)
        self.throttle_decay = check_option(options, "throttle_decay", float, 0.0)
        PilotModel.__init__(self, input_shape, options)
        dropout = check_option(self.options, "dropout", float, 0.0)
        act = check_option(self.options, "activation", str)
        batch_norm = check_option(self.options, "batch_norm", bool)
        self.features = nn.Sequential(
            *conv_stack(input_shape[0], DAVE2_CONVS, act=act, batch_norm=batch_norm),
            FastDropout(dropout), nn.Flatten())
        self.head = dense_head(flat_size(self.features, input_shape), (100, 50, 10), 1, 0.0, act)

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        return self.head(self.features(images))


class NvidiaModel(PilotModel):
    """The thesis's first custom Donkey model (seed 002, §8.5.1: ``customArchitecture``).

    DAVE-2's convolutions on DonkeyCar's 120x160 frames, each followed by dropout 0.1 (the thesis's
    ``keep_prob = 0.9``), the first one without an activation exactly as the thesis's code has it,
    the other four ReLU; dense 100/50/25/10/5 ReLU; two linear outputs (steering, throttle), MSE.
    803,700 parameters on a 3x120x160 input. The thesis's code declares the outputs as Dense(1)
    and Dense(2) under one name, a slip its text contradicts ("two outputs"): here they are one
    Dense(2), as DonkeyCar's linear model has them.

    Options: ``dropout`` (0.1), ``batch_norm`` (False).
    """

    type_name = "nvidia"
    defaults: dict[str, Any] = {"dropout": 0.1, "batch_norm": False}
    #: DonkeyCar's preprocessing, which the thesis used: the frame as it is, scaled to [0, 1]
    preprocess_defaults: dict[str, Any] = {"resize": None, "color": "rgb", "normalize": "unit"}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__(input_shape, options)
        dropout = check_option(self.options, "dropout", float, 0.0)
        batch_norm = check_option(self.options, "batch_norm", bool)
        self.features = nn.Sequential(
            *conv_stack(input_shape[0], DAVE2_CONVS, dropout=dropout, batch_norm=batch_norm,
                        first_activation=False), nn.Flatten())
        self.head = dense_head(flat_size(self.features, input_shape), (100, 50, 25, 10, 5), 2, 0.0)

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        return self.head(self.features(images))
