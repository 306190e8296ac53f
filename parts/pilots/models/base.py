"""The base class every pilot model derives from, and layers shared by several model types.

A model's contract (what training, the pilot part and export rely on):

- ``forward(images, extra=None)``: ``images`` is a float batch ``(N, C, H, W)`` already
  preprocessed (see :mod:`parts.pilots.preprocess`), or ``(N, T, C, H, W)`` when
  ``frames > 1`` (sequence models, oldest frame first). ``extra`` is a float batch ``(N, E)``
  when ``extra_size > 0``: the previous commands (``memory``) or the one-hot behaviour state
  (``behavior``). Returns one tensor ``(N, K)`` of raw outputs.
- ``loss(output, target)``: ``target`` is always ``(N, 2)`` = (angle, throttle) in [-1, 1].
- ``controls(output)``: ``(N, 2)`` = (angle, throttle) to drive with.
- ``options``: plain values that rebuild the same architecture (stored in the model file).
"""

from __future__ import annotations

from typing import Any, ClassVar

import torch
from torch import nn


class PilotModel(nn.Module):
    """Base of all model types: declares inputs and outputs, the loss and the output decoding."""

    #: registry name, set by each subclass
    type_name: ClassVar[str] = ""
    #: memory keys the model needs beyond ``cam/image_array`` (e.g. the behaviour one-hot)
    extra_inputs: ClassVar[tuple[str, ...]] = ()

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__()
        if len(input_shape) != 3 or not all(isinstance(v, int) and v > 0 for v in input_shape):
            raise ValueError(f"input_shape must be (channels, height, width) of positive ints, "
                             f"got {input_shape!r}")
        self.input_shape = tuple(input_shape)
        self.options = dict(options)

    #: images per sample (>1 for sequence models: the last N frames)
    @property
    def frames(self) -> int:
        return 1

    #: previous (angle, throttle) pairs fed as extra input (``memory`` model)
    @property
    def command_history(self) -> int:
        return 0

    #: width of the ``extra`` input vector (0 = none)
    @property
    def extra_size(self) -> int:
        return 0

    def loss(self, output: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """Mean squared error on (angle, throttle)."""
        return nn.functional.mse_loss(output, target)

    def controls(self, output: torch.Tensor) -> torch.Tensor:
        """(angle, throttle) per sample from the raw output."""
        return output

    def describe(self) -> dict[str, Any]:
        """What the model expects and produces, as plain values (stored in the model file)."""
        return {"type": self.type_name, "input_shape": list(self.input_shape), "options": dict(self.options),
                "frames": self.frames, "command_history": self.command_history,
                "extra_inputs": list(self.extra_inputs), "extra_size": self.extra_size}


def donkey_convs(in_channels: int, dropout: float) -> nn.Sequential:
    """DonkeyCar's core CNN: conv 24-5x5/2, 32-5x5/2, 64-5x5/2, 64-3x3/1, 64-3x3/1, ReLU and dropout."""
    layers: list[nn.Module] = []
    for out_ch, k, s in ((24, 5, 2), (32, 5, 2), (64, 5, 2), (64, 3, 1), (64, 3, 1)):
        layers += [nn.Conv2d(in_channels, out_ch, k, stride=s), nn.ReLU(inplace=True), nn.Dropout(dropout)]
        in_channels = out_ch
    layers.append(nn.Flatten())
    return nn.Sequential(*layers)


def flat_size(features: nn.Module, input_shape: tuple[int, ...]) -> int:
    """Number of features ``features`` produces for one input of ``input_shape`` (dry run)."""
    with torch.no_grad():
        try:
            out = features(torch.zeros(1, *input_shape))
        except RuntimeError as exc:
            raise ValueError(f"input shape {tuple(input_shape)} is too small for this model "
                             f"({exc}); use a larger image or a smaller crop") from exc
    return int(out.shape[1])


def dense_head(in_features: int, sizes: tuple[int, ...], outputs: int, dropout: float) -> nn.Sequential:
    """Dense ReLU layers of ``sizes`` (with dropout) then a linear layer of ``outputs``."""
    layers: list[nn.Module] = []
    for size in sizes:
        layers += [nn.Linear(in_features, size), nn.ReLU(inplace=True), nn.Dropout(dropout)]
        in_features = size
    layers.append(nn.Linear(in_features, outputs))
    return nn.Sequential(*layers)


def check_option(options: dict[str, Any], name: str, kind: type, low: float | None = None) -> Any:
    """Return ``options[name]`` after checking its type and lower bound (clear error otherwise)."""
    value = options[name]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise ValueError(f"model option {name}={value!r} must be of type {kind.__name__}")
    if low is not None and value < low:
        raise ValueError(f"model option {name}={value!r} must be >= {low}")
    return value
