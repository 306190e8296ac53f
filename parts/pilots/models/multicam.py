"""The three-camera network of Track Driver AI's extensions (seed 000, "3 Cameras"): model type
``three_camera``.

The document trains DAVE-2 on the left, centre and right frames as separate samples (side frames
with a steering offset) and drives on the centre frame alone; its extension proposes to "modify the
input layer ... to take three images simultaneously and both train and infer with this". Here one
DAVE-2 trunk (shared weights) looks at each of the three preprocessed views, the three feature
vectors are concatenated (left, centre, right: the head knows which view is which) and a dense head
gives steering and throttle. It drives only where the car makes all three frames
(``cam/image_array_left``, ``cam/image_array``, ``cam/image_array_right``, the keys `vehicle tub
import-udacity` records): the built-in simulator with SIM_SIDE_CAMERAS_OFFSET, or a car with three
cameras. The Udacity simulator sends only the centre frame while driving, so there it is refused.
"""

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

#: the three cameras, left to right (a horizontal flip reverses this order)
CAMERA_KEYS: tuple[str, str, str] = ("cam/image_array_left", "cam/image_array", "cam/image_array_right")


class ThreeCameraModel(PilotModel):
    """A shared DAVE-2 trunk per view, features concatenated, dense 100/50/10, (steering, throttle).

    Input ``images`` (N, 3, C, H, W): the left, centre and right frames, each preprocessed as one
    frame (default: DAVE-2's 66x200 YUV in [-1, 1]). Trunk: conv 24/36/48 5x5 stride 2, conv
    64/64 3x3 ('valid'), the activation after each, dropout, flatten (1,152 features per view on
    66x200). Head: concat (3 x 1,152) -> dense 100, 50, 10 with the activation -> dense 2, MSE on
    both outputs. 482,630 parameters on 3x66x200 views (131,348 in the shared trunk).

    Options: ``activation`` "elu" (Track Driver AI's DAVE-2) or "relu"; ``dropout`` after the
    trunk (0 = none, as the document's DAVE-2); ``batch_norm`` after each convolution.
    """

    type_name = "three_camera"
    image_inputs = CAMERA_KEYS
    defaults: dict[str, Any] = {"activation": "elu", "dropout": 0.0, "batch_norm": False}
    #: DAVE-2's preprocessing, as ``pilotnet`` (the car's PREPROCESS_* settings win where set)
    preprocess_defaults: dict[str, Any] = {"resize": [66, 200], "color": "yuv", "normalize": "symmetric"}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__(input_shape, options)
        act = check_option(self.options, "activation", str)
        dropout = check_option(self.options, "dropout", float, 0.0)
        batch_norm = check_option(self.options, "batch_norm", bool)
        self.trunk = nn.Sequential(*conv_stack(input_shape[0], DAVE2_CONVS, act=act, batch_norm=batch_norm),
                                   FastDropout(dropout), nn.Flatten())
        per_view = flat_size(self.trunk, input_shape)
        self.head = dense_head(self.views * per_view, (100, 50, 10), 2, 0.0, act)

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        if images.dim() != 5 or images.shape[1] != self.views:
            raise ValueError(f"model type {self.type_name!r} takes (N, {self.views}, C, H, W) batches of the "
                             f"views {list(self.image_inputs)}, got shape {tuple(images.shape)}")
        n = images.shape[0]
        features = self.trunk(images.flatten(0, 1))  # every view of every sample through one trunk
        return self.head(features.reshape(n, -1))  # (N, views x features), left to right
