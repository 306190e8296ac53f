"""The thesis's two-stream behavioural model (seed 002, §9.3 and Appendix 5.2) as model type ``lanes``.

One CNN looks at the raw camera image, a second one at the binary lane image (bird's-eye warp +
HLS S-channel threshold, :mod:`parts.vision.lanes`), a small dense subnetwork at the one-hot
behaviour (e.g. Left_Lane / Right_Lane); a final dense subnetwork turns all three into steering
and throttle. The lane image is computed by the model's preprocessing from the raw frame
(:class:`parts.pilots.preprocess.Preprocess` with ``lanes`` settings, stored in the model file),
so a tub holds only camera frames and training and driving compute it the same way.
"""

from __future__ import annotations

from typing import Any, ClassVar

import torch
from torch import nn

from parts.pilots.models.base import PilotModel, check_option, flat_size

#: the thesis's convolutions, both streams: (filters, kernel, stride)
THESIS_CONVS: tuple[tuple[int, int, int], ...] = ((24, 5, 2), (32, 5, 2), (64, 5, 2), (64, 3, 1), (64, 3, 1))


def _stream(in_channels: int, slope: float, dropout: float, last_dropout: bool) -> nn.Sequential:
    """Five convolutions with LeakyReLU, dropout after each (but the last where the thesis has none),
    flattened."""
    layers: list[nn.Module] = []
    for i, (out_ch, k, s) in enumerate(THESIS_CONVS):
        layers += [nn.Conv2d(in_channels, out_ch, k, stride=s), nn.LeakyReLU(slope)]
        if i < len(THESIS_CONVS) - 1 or last_dropout:
            layers.append(nn.Dropout(dropout))
        in_channels = out_ch
    layers.append(nn.Flatten())
    return nn.Sequential(*layers)


class _TwoStreams(PilotModel):
    """The thesis's two CNN streams, shared by its first iteration and its behavioural model: the
    raw image's channels and the lane image (the last channel, repeated to 3 as ``GRAY2RGB``), each
    five convolutions with LeakyReLU and dropout, flattened, Dense 100 and dropout."""

    #: channels the thesis gives the lane stream (a binary image repeated: GRAY2RGB)
    LANE_CHANNELS = 3
    #: the raw frame's channels, then the lane image (the last channel)
    input_streams: ClassVar[dict[str, tuple[int | None, int | None]]] = {"camera": (None, -1), "lanes": (-1, None)}

    def _build_streams(self, input_shape: tuple[int, int, int]) -> None:
        dropout = check_option(self.options, "dropout", float, 0.0)
        if dropout >= 1.0:
            raise ValueError(f"model option dropout={dropout} must be < 1")
        slope = check_option(self.options, "leaky_slope", float, 0.0)
        channels, h, w = input_shape
        if channels < 2:
            raise ValueError(f"model type {self.type_name!r} needs the raw channels plus the lane channel, got "
                             f"{channels} channel(s): train it with the lanes preprocessing (the type's default)")
        raw_shape = (channels - 1, h, w)
        lane_shape = (self.LANE_CHANNELS, h, w)
        self.image_convs = _stream(raw_shape[0], slope, dropout, last_dropout=True)
        self.image_dense = nn.Sequential(nn.Linear(flat_size(self.image_convs, raw_shape), 100), nn.Dropout(dropout))
        self.lane_convs = _stream(self.LANE_CHANNELS, slope, dropout, last_dropout=False)
        self.lane_dense = nn.Sequential(nn.Linear(flat_size(self.lane_convs, lane_shape), 100), nn.Dropout(dropout))

    def _streams(self, images: torch.Tensor) -> torch.Tensor:
        """The two streams' Dense 100 outputs, concatenated (N, 200)."""
        lane = images[:, -1:].expand(-1, self.LANE_CHANNELS, -1, -1)
        x = self.image_dense(self.image_convs(images[:, :-1]))
        y = self.lane_dense(self.lane_convs(lane))
        return torch.cat([x, y], dim=1)


class LanesModel(_TwoStreams):
    """Two-stream CNN + behaviour subnetwork, exactly as the thesis's Appendix 5.2 (``oriModel``).

    Input: ``images`` (N, C + 1, H, W) = the raw frame's C channels (preprocessed as usual) and,
    last, the binary lane image in [0, 1]; ``extra`` (N, B) = ``behavior/one_hot_state_array``.

    Layers (thesis numbers, Appendix 5.2):

    - raw-image stream: Conv2D 24 5x5/2, 32 5x5/2, 64 5x5/2, 64 3x3/1, 64 3x3/1 ('valid' padding),
      each followed by LeakyReLU and Dropout; Flatten; Dense 100 (linear); Dropout.
    - lane-image stream: the same five convolutions with LeakyReLU and Dropout, except no Dropout
      after the fifth (as the thesis's code); Flatten; Dense 100 (linear); Dropout. The thesis
      feeds the binary image as 3 identical channels (``cv2.COLOR_GRAY2RGB``); so does this model
      (the one lane channel is repeated), which keeps the thesis's parameter count.
    - behaviour subnetwork: three Dense layers of 2 x number-of-behaviours units, ReLU.
    - decision subnetwork: concat(raw, lane) -> Dense 100 ReLU; concat(behaviour, that) -> Dense 100
      ReLU -> Dense 50 ReLU; two linear outputs (steering, throttle). MSE loss on both.
    - dropout rate 0.1 (the thesis's ``keep_prob = 0.9``); LeakyReLU slope 0.3 (Keras's default,
      which the thesis's ``LeakyReLU()`` used; PyTorch's default would be 0.01).

    At the thesis's input (3 x 180 x 320 frames, 2 behaviours) this is 6,664,356 parameters; the
    thesis quotes "about 6.5 million" for the first iteration without behaviours (6,653,804 by
    the same layer list).

    Where the thesis is ambiguous, this follows its complete code (Appendix 5.2):

    - §9.3.2's snippet concatenates the behaviour subnetwork with the output of the whole first
      iteration's head (Dense 100 -> Dense 50) and adds Dense 100 -> Dense 50 after it; Appendix
      5.2 (and the text: "just before the first 100-unit dense layer of the last subnetwork")
      joins it after a single Dense 100. The latter is used: three dense layers after the
      streams (100, then 100 and 50 after the behaviour joins).
    - §9.2.1 says the first CNN takes the lane image and the second the raw image, while its code
      feeds the raw image to the first; only the names differ, the architecture is symmetric.
    - the thesis's preprocessing of the raw stream is DonkeyCar 3's (frames scaled to [0, 1]);
      this type's default normalisation is therefore "unit" (0..1) for both streams.

    Options: ``num_behaviors`` (set from the data when training), ``dropout`` (0.1),
    ``leaky_slope`` (0.3).
    """

    type_name = "lanes"
    extra_inputs = ("behavior/one_hot_state_array",)
    defaults: dict[str, Any] = {"dropout": 0.1, "num_behaviors": 2, "leaky_slope": 0.3}
    #: preprocessing this type defaults to where the car's config leaves a choice open; ``lanes``
    #: makes the preprocessing append the lane image (LANE_* settings) as the last channel
    preprocess_defaults: dict[str, Any] = {"resize": None, "color": "rgb", "normalize": "unit", "lanes": True}
    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__(input_shape, options)
        self.num_behaviors = check_option(self.options, "num_behaviors", int, 1)
        self._build_streams(input_shape)
        b = 2 * self.num_behaviors
        self.behavior = nn.Sequential(nn.Linear(self.num_behaviors, b), nn.ReLU(),
                                      nn.Linear(b, b), nn.ReLU(), nn.Linear(b, b), nn.ReLU())
        self._draw_live_behavior()
        self.merge = nn.Sequential(nn.Linear(200, 100), nn.ReLU())
        self.decide = nn.Sequential(nn.Linear(b + 100, 100), nn.ReLU(), nn.Linear(100, 50), nn.ReLU())
        self.steering_out = nn.Linear(50, 1)
        self.throttle_out = nn.Linear(50, 1)

    @property
    def extra_size(self) -> int:
        return self.num_behaviors

    def behavior_path_alive(self) -> bool:
        """Whether every behaviour reaches some unit of each ReLU layer of the behaviour subnetwork
        and no two behaviours give a layer the same output (else the model cannot tell them apart)."""
        with torch.no_grad():
            h = torch.eye(self.num_behaviors, device=self.behavior[0].weight.device)
            for layer in self.behavior:
                h = layer(h)
                if isinstance(layer, nn.ReLU) and (not bool((h > 0).any(dim=1).all())
                                                   or len(torch.unique(h, dim=0)) < self.num_behaviors):
                    return False
        return True

    def _draw_live_behavior(self) -> None:
        """Draw the behaviour subnetwork again until its path is alive. Its layers are only
        2 x behaviours units wide: torch's default draw left a layer dead for some behaviour in 1
        seed of 4 at the demo's input (TRAIN_SEED 43 and 44 among them; in 1 of 10 both behaviours
        came out the same), and a dead ReLU passes no gradient, so such a model never learnt to
        change lanes on command. A live first draw is kept as it is."""
        for _ in range(1000):
            if self.behavior_path_alive():
                return
            for layer in self.behavior:
                if isinstance(layer, nn.Linear):
                    layer.reset_parameters()
        raise RuntimeError("could not draw a behaviour subnetwork that tells the behaviours apart")

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        if extra is None:
            raise ValueError(f"model type 'lanes' needs the behaviour one-hot ({self.num_behaviors} values per sample)")
        c = self.merge(self._streams(images))
        o = self.decide(torch.cat([self.behavior(extra), c], dim=1))
        return torch.cat([self.steering_out(o), self.throttle_out(o)], dim=1)


class LanesBasicModel(_TwoStreams):
    """The thesis's first iteration (seed 002, §9.1-9.2.1: ``oriModel``), without behaviours.

    The same two streams as :class:`LanesModel` (raw image; binary lane image repeated to 3
    channels), each ending in Dense 100 and Dropout; concatenated -> Dense 100 ReLU -> Dense 50 ReLU
    -> two linear outputs (steering, throttle), MSE. 6,653,804 parameters on 3x180x320 frames, the
    thesis's "about 6.5 million".

    Options: ``dropout`` (0.1), ``leaky_slope`` (0.3, Keras's LeakyReLU default).
    """

    type_name = "lanes_basic"
    defaults: dict[str, Any] = {"dropout": 0.1, "leaky_slope": 0.3}
    preprocess_defaults: dict[str, Any] = LanesModel.preprocess_defaults

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__(input_shape, options)
        self._build_streams(input_shape)
        self.decide = nn.Sequential(nn.Linear(200, 100), nn.ReLU(), nn.Linear(100, 50), nn.ReLU())
        self.steering_out = nn.Linear(50, 1)
        self.throttle_out = nn.Linear(50, 1)

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        o = self.decide(self._streams(images))
        return torch.cat([self.steering_out(o), self.throttle_out(o)], dim=1)
