"""Single-frame model types on DonkeyCar's core CNN: linear, categorical, inferred, memory, behavior."""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from parts.pilots.models.base import PilotModel, check_option, dense_head, donkey_convs, flat_size, he_init

#: the options every type on the core CNN has: dropout, a normalisation after each convolution
#: (``batch_norm`` or ``group_norm``), He initialisation (``he_init``)
CORE_DEFAULTS: dict[str, Any] = {"dropout": 0.2, "batch_norm": False, "group_norm": False, "he_init": False}


class LinearModel(PilotModel):
    """DonkeyCar's default: core CNN, dense 100, 50, two continuous outputs (angle, throttle); MSE.

    Options ``batch_norm`` or ``group_norm`` (4 groups): a normalisation after each convolution.
    Option ``throttle_limits``: None, or ``[low, high]`` within [-1, 1]: the throttle it drives with
    is clamped to that range (an RL policy's throttle range, ``vehicle rl train --throttle-range``,
    or a cap on a trained pilot's throttle through MODEL_OPTIONS).
    """

    type_name = "linear"
    defaults: dict[str, Any] = {**CORE_DEFAULTS, "throttle_limits": None}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        super().__init__(input_shape, options)
        dropout = check_option(self.options, "dropout", float, 0.0)
        batch_norm = check_option(self.options, "batch_norm", bool)
        self.throttle_limits = _limits(self.options.get("throttle_limits"))
        group_norm = check_option(self.options, "group_norm", bool)
        self.features = donkey_convs(input_shape[0], dropout, batch_norm, group_norm)
        self.head = dense_head(flat_size(self.features, input_shape) + self.extra_size, (100, 50),
                               self.n_outputs(), dropout)
        if check_option(self.options, "he_init", bool):
            he_init(self.features, self.head)

    def n_outputs(self) -> int:
        return 2

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        x = self.features(images)
        if self.extra_size:
            if extra is None:
                raise ValueError(f"model type {self.type_name!r} needs the extra input "
                                 f"({self.extra_size} values per sample)")
            x = torch.cat([x, extra], dim=1)
        return self.head(x)

    def controls(self, output: torch.Tensor) -> torch.Tensor:
        if self.throttle_limits is None:
            return output
        low, high = self.throttle_limits
        return torch.stack([output[:, 0], output[:, 1].clamp(low, high)], dim=1)


def _limits(value: Any) -> tuple[float, float] | None:
    """``throttle_limits`` checked: None or two numbers ``-1 <= low <= high <= 1``."""
    if value is None:
        return None
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"model option throttle_limits={value!r} must be None or [low, high]") from None
    if not -1.0 <= low <= high <= 1.0:
        raise ValueError(f"model option throttle_limits={value!r} needs -1 <= low <= high <= 1")
    return low, high


class LinearTanhModel(LinearModel):
    """The linear model with its outputs bounded by tanh: what SAC's deterministic actor computes
    (``vehicle rl train --algo sac`` exports to it); trains by MSE like ``linear``."""

    type_name = "linear_tanh"
    defaults: dict[str, Any] = dict(CORE_DEFAULTS)

    def forward(self, images: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        return torch.tanh(super().forward(images, extra))


class CategoricalModel(LinearModel):
    """Steering and throttle as classes: ``angle_bins`` over [-1, 1] and ``throttle_bins`` over
    [0, ``throttle_range``]; cross-entropy with weights 0.5/0.5; drives with the most likely bin."""

    type_name = "categorical"
    defaults = {**CORE_DEFAULTS, "angle_bins": 15, "throttle_bins": 20, "throttle_range": 0.8}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        self.angle_bins = check_option(options, "angle_bins", int, 2)
        self.throttle_bins = check_option(options, "throttle_bins", int, 2)
        self.throttle_range = check_option(options, "throttle_range", float, 1e-3)
        super().__init__(input_shape, options)

    def n_outputs(self) -> int:
        return self.angle_bins + self.throttle_bins

    def _bins(self, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        angle = ((target[:, 0].clamp(-1, 1) + 1) / 2 * (self.angle_bins - 1)).round().long()
        thr = (target[:, 1].clamp(0, self.throttle_range) / self.throttle_range
               * (self.throttle_bins - 1)).round().long()
        return angle, thr

    def loss(self, output: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        angle, thr = self._bins(target)
        ce = nn.functional.cross_entropy
        return 0.5 * ce(output[:, :self.angle_bins], angle) + 0.5 * ce(output[:, self.angle_bins:], thr)

    def controls(self, output: torch.Tensor) -> torch.Tensor:
        angle = output[:, :self.angle_bins].argmax(dim=1).float() / (self.angle_bins - 1) * 2 - 1
        thr = output[:, self.angle_bins:].argmax(dim=1).float() / (self.throttle_bins - 1)
        thr = thr * self.throttle_range
        return torch.stack([angle, thr], dim=1)


class InferredModel(LinearModel):
    """Steering only; throttle is derived from it: ``min + (max - min) * exp(-decay * |angle|)``
    (slow down in curves). MSE on the angle."""

    type_name = "inferred"
    defaults = {**CORE_DEFAULTS, "throttle_max": 0.5, "throttle_min": 0.2, "throttle_decay": 3.0}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        self.throttle_max = check_option(options, "throttle_max", float)
        self.throttle_min = check_option(options, "throttle_min", float)
        self.throttle_decay = check_option(options, "throttle_decay", float, 0.0)
        if not -1 <= self.throttle_min <= self.throttle_max <= 1:
            raise ValueError(f"inferred model needs -1 <= throttle_min <= throttle_max <= 1, got "
                             f"{self.throttle_min}, {self.throttle_max}")
        super().__init__(input_shape, options)

    def n_outputs(self) -> int:
        return 1

    def loss(self, output: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return nn.functional.mse_loss(output[:, 0], target[:, 0])

    def controls(self, output: torch.Tensor) -> torch.Tensor:
        angle = output[:, 0]
        span = self.throttle_max - self.throttle_min
        thr = self.throttle_min + span * torch.exp(-self.throttle_decay * angle.abs())
        return torch.stack([angle, thr], dim=1)


class MemoryModel(LinearModel):
    """Linear model that also sees its previous ``mem_length`` (angle, throttle) commands, oldest first
    (training: the recorded user commands; driving: the pilot's own previous outputs)."""

    type_name = "memory"
    defaults = {**CORE_DEFAULTS, "mem_length": 3}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        self.mem_length = check_option(options, "mem_length", int, 1)
        super().__init__(input_shape, options)

    @property
    def command_history(self) -> int:
        return self.mem_length

    @property
    def extra_size(self) -> int:
        return 2 * self.mem_length


class BehaviorModel(LinearModel):
    """Linear model that also sees the one-hot behaviour state (e.g. left lane / right lane)."""

    type_name = "behavior"
    extra_inputs = ("behavior/one_hot_state_array",)
    defaults = {**CORE_DEFAULTS, "num_behaviors": 2}

    def __init__(self, input_shape: tuple[int, int, int], options: dict[str, Any]) -> None:
        self.num_behaviors = check_option(options, "num_behaviors", int, 1)
        super().__init__(input_shape, options)

    @property
    def extra_size(self) -> int:
        return self.num_behaviors

