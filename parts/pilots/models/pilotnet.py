"""NVIDIA DAVE-2 (PilotNet) as in the Udacity behavioural-cloning projects: steering only, throttle derived."""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from parts.pilots.models.base import FastDropout, PilotModel, check_option, dense_head, flat_size
from parts.pilots.models.cnn import InferredModel


class PilotNetModel(InferredModel):
    """Conv 24/36/48 5x5 stride 2, conv 64/64 3x3, dropout, dense 100/50/10/1 (252,219 parameters
    on a 3x66x200 input). Its preprocessing defaults follow the paper: resize to 66x200, YUV,
    normalise to [-1, 1]. One output (steering); throttle as for ``inferred``."""

    type_name = "pilotnet"
    defaults = {"dropout": 0.5, "throttle_max": 0.5, "throttle_min": 0.2, "throttle_decay": 3.0}
    #: preprocessing this type defaults to where the car's config leaves a choice open (None)
    preprocess_defaults: dict[str, Any] = {"resize": [66, 200], "color": "yuv", "normalize": "symmetric"}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        # Skip LinearModel's layers: build DAVE-2's own.
        self.throttle_max = check_option(options, "throttle_max", float)
        self.throttle_min = check_option(options, "throttle_min", float)
        self.throttle_decay = check_option(options, "throttle_decay", float, 0.0)
        PilotModel.__init__(self, input_shape, options)
        dropout = check_option(self.options, "dropout", float, 0.0)
        layers: list[nn.Module] = []
        in_ch = input_shape[0]
        for out_ch, k, s in ((24, 5, 2), (36, 5, 2), (48, 5, 2), (64, 3, 1), (64, 3, 1)):
            layers += [nn.Conv2d(in_ch, out_ch, k, stride=s), nn.ReLU(inplace=True)]
            in_ch = out_ch
        layers += [FastDropout(dropout), nn.Flatten()]
        self.features = nn.Sequential(*layers)
        self.head = dense_head(flat_size(self.features, input_shape), (100, 50, 10), 1, 0.0)

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        return self.head(self.features(images))
