"""The base class every pilot model derives from, and layers shared by several model types.

A model's contract (what training, the pilot part and export rely on):

- ``forward(images, extra=None)``: ``images`` is a float batch ``(N, C, H, W)`` already
  preprocessed (see :mod:`parts.pilots.preprocess`), or ``(N, T, C, H, W)`` when
  ``frames > 1`` (sequence models, oldest frame first). ``extra`` is a float batch ``(N, E)``
  when ``extra_size > 0``: the previous commands (``memory``) or the one-hot behaviour state
  (``behavior``). A model of several camera views (``image_inputs``, e.g. the left, centre and
  right cameras) takes ``(N, V, C, H, W)``, the views in the order of ``image_inputs``.
  Returns one tensor ``(N, K)`` of raw outputs.
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
    #: camera frames the model takes per sample, in the order of its views (memory keys)
    image_inputs: ClassVar[tuple[str, ...]] = ("cam/image_array",)
    #: memory keys the model needs beyond its camera frames (e.g. the behaviour one-hot)
    extra_inputs: ClassVar[tuple[str, ...]] = ()
    #: the input's streams for saliency maps: name -> channel span (start, stop) of a frame
    input_streams: ClassVar[dict[str, tuple[int | None, int | None]]] = {"camera": (None, None)}

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

    #: camera views per sample (>1: ``images`` is (N, V, C, H, W), one view per ``image_inputs`` key)
    @property
    def views(self) -> int:
        return len(self.image_inputs)

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
                "frames": self.frames, "image_inputs": list(self.image_inputs),
                "command_history": self.command_history,
                "extra_inputs": list(self.extra_inputs), "extra_size": self.extra_size}


class _KeepMask(torch.autograd.Function):
    """``x * keep * scale`` with the boolean mask saved (1 byte per element) for the backward."""

    @staticmethod
    def forward(ctx: Any, x: torch.Tensor, keep: torch.Tensor, scale: float) -> torch.Tensor:
        ctx.save_for_backward(keep)
        ctx.scale = scale
        return x.mul(keep).mul_(scale)

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[torch.Tensor, None, None]:
        (keep,) = ctx.saved_tensors
        return grad.mul(keep).mul_(ctx.scale), None, None


def _dense(x: torch.Tensor) -> bool:
    """Whether ``x`` covers its memory without gaps or overlaps in some dimension order (contiguous,
    channels_last, ...): a mask of the same strides can then be laid over one flat buffer."""
    expected = 1
    for size, stride in sorted(zip(x.shape, x.stride(), strict=True), key=lambda p: p[1]):
        if size == 1:
            continue
        if stride != expected:
            return False
        expected *= size
    return True


class FastDropout(nn.Dropout):
    """:class:`torch.nn.Dropout` with a cheap random mask on the CPU; identical everywhere else.

    PyTorch's CPU dropout draws one Bernoulli number per element from a serial generator (MKL's
    vectorised path only runs on Intel CPUs): in the linear model's training step it took 43 % of
    the time on an AMD CPU (torch.profiler; docs/benchmarks.md, "training"). Here the mask comes from
    64-bit random words of the same seeded torch generator, cut into four 16-bit numbers each, and
    one comparison (``keep = r < round((1 - p) * 2**16)``, so p is exact to 1/65536 and the scale
    uses that exact keep rate: the expectation is unchanged). One comparison, not several
    operations: on a busy machine every parallel operation waits for all its threads. Evaluation
    mode, p = 0 or 1, in-place use and other devices (CUDA has a fused kernel) run torch's own
    dropout, so exports and inference are unchanged.
    """

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.inplace or x.device.type != "cpu" or not 0.0 < self.p < 1.0:
            return super().forward(x)
        keep_count = round((1.0 - self.p) * 65536)
        if keep_count in (0, 65536):
            return super().forward(x)
        if not _dense(x):
            x = x.contiguous()
        n = x.numel()
        words = torch.empty((n + 3) // 4, dtype=torch.int64).random_(-(2**63), None)  # all 64 bits random
        r = torch.as_strided(words.view(torch.int16)[:n], x.shape, x.stride())  # uniform in [-2**15, 2**15)
        return _KeepMask.apply(x, r < keep_count - 32768, 65536.0 / keep_count)


#: DonkeyCar's core CNN: (filters, kernel, stride) of its five convolutions
DONKEY_CONVS: tuple[tuple[int, int, int], ...] = ((24, 5, 2), (32, 5, 2), (64, 5, 2), (64, 3, 1), (64, 3, 1))
#: NVIDIA's DAVE-2 (PilotNet) convolutions
DAVE2_CONVS: tuple[tuple[int, int, int], ...] = ((24, 5, 2), (36, 5, 2), (48, 5, 2), (64, 3, 1), (64, 3, 1))
ACTIVATIONS = ("relu", "elu")


def activation(name: str) -> nn.Module:
    """The activation layer called ``name`` (relu, or elu as Track Driver AI's DAVE-2 uses)."""
    if name == "relu":
        return nn.ReLU(inplace=True)
    if name == "elu":
        return nn.ELU(inplace=True)
    raise ValueError(f"model option activation={name!r} must be one of {ACTIVATIONS}")


#: groups of ``group_norm``: divides the channel counts of the convolution stacks (24, 32, 36, 48, 64)
GROUP_NORM_GROUPS = 4


def conv_stack(in_channels: int, convs: tuple[tuple[int, int, int], ...], *, act: str = "relu",
               dropout: float | None = None, batch_norm: bool = False, group_norm: bool = False,
               first_activation: bool = True) -> nn.Sequential:
    """Convolutions ('valid' padding) each followed by [batch or group norm,] the activation [and dropout].

    ``dropout=None`` adds no dropout layer; a rate (0 included) adds one after each convolution,
    so that the layer indices, and with them the model files, do not depend on the rate.
    ``first_activation=False`` leaves the first convolution linear, as the thesis's NVIDIA model
    (seed 002, §8.5.1) has it. Not flattened.
    """
    layers: list[nn.Module] = []
    for i, (out_ch, k, s) in enumerate(convs):
        layers.append(nn.Conv2d(in_channels, out_ch, k, stride=s, bias=not (batch_norm or group_norm)))
        if batch_norm:
            layers.append(nn.BatchNorm2d(out_ch))
        elif group_norm:  # per frame: no statistics of the training frames carried to the road
            layers.append(nn.GroupNorm(GROUP_NORM_GROUPS, out_ch))
        if i or first_activation:
            layers.append(activation(act))
        if dropout is not None:
            layers.append(FastDropout(dropout))
        in_channels = out_ch
    return nn.Sequential(*layers)


def donkey_convs(in_channels: int, dropout: float, batch_norm: bool = False,
                 group_norm: bool = False) -> nn.Sequential:
    """DonkeyCar's core CNN: conv 24-5x5/2, 32-5x5/2, 64-5x5/2, 64-3x3/1, 64-3x3/1, ReLU and dropout
    (optionally batch or group normalisation after each convolution), flattened."""
    if batch_norm and group_norm:
        raise ValueError("model options batch_norm and group_norm: choose one normalisation")
    return nn.Sequential(*conv_stack(in_channels, DONKEY_CONVS, dropout=dropout, batch_norm=batch_norm,
                                     group_norm=group_norm), nn.Flatten())


def flat_size(features: nn.Module, input_shape: tuple[int, ...]) -> int:
    """Number of features ``features`` produces for one input of ``input_shape`` (dry run)."""
    with torch.no_grad():
        try:
            out = features(torch.zeros(1, *input_shape))
        except RuntimeError as exc:
            raise ValueError(f"input shape {tuple(input_shape)} is too small for this model "
                             f"({exc}); use a larger image or a smaller crop") from exc
    return int(out.shape[1])


class Float32Head(nn.Sequential):
    """Dense layers that run in float32 even inside a mixed-precision (autocast) training step.

    The convolutions are where the time goes (the dense layers are ~1 % of a step's FLOPs); in
    bf16 the dense layers cost quality: on a 2-core AMD EPYC with AVX512-BF16, 10 training seeds of
    the bar task (tests/training/test_train_precision.py) gave bf16 a validation loss 1.24x fp32's
    with a bf16 head and 1.06x with this float32 one. Outside autocast (inference, export) it is a
    plain Sequential; its parameter names are Sequential's, so model files are unchanged.
    """

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if torch.is_autocast_enabled(x.device.type):
            with torch.autocast(x.device.type, enabled=False):
                return super().forward(x.float())
        return super().forward(x)


def dense_head(in_features: int, sizes: tuple[int, ...], outputs: int, dropout: float,
               act: str = "relu") -> nn.Sequential:
    """Dense layers of ``sizes`` with the activation (and dropout) then a linear layer of ``outputs``,
    in float32 under autocast (:class:`Float32Head`)."""
    layers: list[nn.Module] = []
    for size in sizes:
        layers += [nn.Linear(in_features, size), activation(act), FastDropout(dropout)]
        in_features = size
    layers.append(nn.Linear(in_features, outputs))
    return Float32Head(*layers)


def he_init(*stacks: nn.Sequential) -> None:
    """He (Kaiming) normal initialisation of every convolution and dense layer of ``stacks`` that a
    ReLU follows, biases zero; the last layer (the outputs) keeps torch's default. Torch's default
    (uniform, a = sqrt(5)) shrinks the signal about 2.4x per ReLU layer: through DonkeyCar's five
    convolutions and two dense layers a seed can start on the "predict the mean" plateau."""
    layers = [m for stack in stacks for m in stack.modules() if isinstance(m, nn.Conv2d | nn.Linear)]
    for layer in layers[:-1]:
        nn.init.kaiming_normal_(layer.weight, nonlinearity="relu")
        if layer.bias is not None:
            nn.init.zeros_(layer.bias)


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
