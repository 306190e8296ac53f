"""How training uses the device it runs on: precision, memory layout, host-to-device copies, compile.

Decided once at start-up from what the device offers (:func:`probe_device` -> :class:`DeviceCaps`)
and the car's settings (TRAIN_PRECISION, TRAIN_COMPILE) by :func:`choose_plan`, a pure function
(tested for every kind of device, GPUs included, without one):

- **CPU** with native bf16 (AVX512-BF16 or AMX): bf16 autocast. Without: fp32 (bf16 would be
  emulated, slower than fp32). Always channels_last (oneDNN's convolutions are faster in NHWC).
- **CUDA** compute capability >= 8.0 (Ampere and later): bf16 autocast. 7.x (Volta, Turing): fp16
  autocast with a gradient scaler (fp16 overflows without one). Older: fp32. channels_last from
  7.0 on (tensor cores want NHWC); batches are pinned in host memory and copied asynchronously.
- ``torch.compile`` only when TRAIN_COMPILE asks and the device can compile (a C++ compiler for
  CPUs, Triton for GPUs); its compile time is logged.

The master weights stay float32 in every plan: autocast runs the convolutions and matrix products in
the low precision and keeps the loss, the reductions and the optimiser in float32, so a model file
is the same whichever plan trained it.
"""

from __future__ import annotations

import contextlib
import logging
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Literal

import torch

logger = logging.getLogger(__name__)

Precision = Literal["fp32", "bf16", "fp16"]
PRECISIONS: tuple[str, ...] = ("auto", "fp32", "bf16", "fp16")
_DTYPES = {"bf16": torch.bfloat16, "fp16": torch.float16}


@dataclass(frozen=True)
class DeviceCaps:
    """What a training device offers, as far as the plan is concerned.

    Attributes:
        type: "cpu", "cuda" or another torch device type (mps, xpu: trained in fp32).
        name: for the log line (CPU model or GPU name).
        native_bf16: bf16 arithmetic in hardware (CPU: AVX512-BF16 or AMX-BF16; CUDA: sm_80+).
        compute_capability: CUDA (major, minor); None elsewhere.
        can_compile: torch.compile's default backend can build code here.
    """

    type: str
    name: str = ""
    native_bf16: bool = False
    compute_capability: tuple[int, int] | None = None
    can_compile: bool = False


@dataclass(frozen=True)
class TrainPlan:
    """The choices :func:`choose_plan` made, and why (``reasons``, one short phrase each)."""

    device_type: str
    precision: Precision = "fp32"
    channels_last: bool = False
    grad_scaler: bool = False
    pin_memory: bool = False
    non_blocking: bool = False
    compile: bool = False
    reasons: tuple[str, ...] = field(default=())

    @property
    def autocast_dtype(self) -> torch.dtype | None:
        """dtype autocast runs in, None for fp32 (no autocast)."""
        return _DTYPES.get(self.precision)

    def describe(self) -> str:
        """One line for the log: ``bf16 autocast, channels_last, eager (CPU has AVX512-BF16)``."""
        parts = [f"{self.precision} autocast" if self.precision != "fp32" else "fp32"]
        if self.grad_scaler:
            parts.append("gradient scaler")
        parts.append("channels_last" if self.channels_last else "contiguous")
        if self.pin_memory:
            parts.append("pinned non-blocking copies")
        parts.append("torch.compile" if self.compile else "eager")
        text = ", ".join(parts)
        return f"{text} ({'; '.join(self.reasons)})" if self.reasons else text

    def to_dict(self) -> dict[str, Any]:
        """Plain values for the model file's training metadata."""
        return {"precision": self.precision, "channels_last": self.channels_last,
                "grad_scaler": self.grad_scaler, "pin_memory": self.pin_memory, "compile": self.compile}


def cpu_caps() -> DeviceCaps:
    """This machine's CPU: native bf16 from torch's CPU feature checks, C++ compiler on PATH."""
    bf16 = False
    for check in ("_is_avx512_bf16_supported", "_is_amx_tile_supported"):
        probe = getattr(torch.cpu, check, None)
        with contextlib.suppress(Exception):  # private helpers: absent or failing means no
            bf16 = bf16 or bool(probe and probe())
    bf16 = bf16 and torch.backends.mkldnn.is_available()
    compiler = any(shutil.which(c) for c in ("g++", "c++", "clang++"))
    return DeviceCaps("cpu", _cpu_name(), native_bf16=bf16, can_compile=compiler)


def _cpu_name() -> str:
    import platform

    with contextlib.suppress(OSError), open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or "CPU"


def cuda_caps(device: torch.device) -> DeviceCaps:
    """A CUDA device's name and compute capability; Triton decides whether it can compile."""
    index = device.index if device.index is not None else torch.cuda.current_device()
    major, minor = torch.cuda.get_device_capability(index)
    try:
        import triton  # noqa: F401

        triton_ok = True
    except ImportError:
        triton_ok = False
    return DeviceCaps("cuda", torch.cuda.get_device_name(index), native_bf16=major >= 8,
                      compute_capability=(major, minor), can_compile=triton_ok and major >= 7)


def probe_device(device: torch.device) -> DeviceCaps:
    """The capabilities of ``device`` (CPU and CUDA probed; other types get fp32 defaults)."""
    if device.type == "cpu":
        return cpu_caps()
    if device.type == "cuda":
        return cuda_caps(device)
    return DeviceCaps(device.type, device.type)


def choose_plan(caps: DeviceCaps, precision: str = "auto", compile: bool = False,
                spatial_model: bool = True) -> TrainPlan:
    """The training plan for a device (module docstring); ``precision`` is TRAIN_PRECISION.

    ``spatial_model``: the model takes 4-D image batches (channels_last applies); sequence models
    (5-D batches) keep the default layout.

    Raises:
        ValueError: an unknown precision, or fp16/bf16 forced where autocast cannot run them.
    """
    if precision not in PRECISIONS:
        raise ValueError(f"TRAIN_PRECISION = {precision!r}: use one of {', '.join(PRECISIONS)}")
    reasons: list[str] = []
    cc = caps.compute_capability
    if caps.type == "cpu":
        auto: Precision = "bf16" if caps.native_bf16 else "fp32"
        reasons.append("CPU with native bf16 (AVX512-BF16/AMX)" if caps.native_bf16
                       else "CPU without native bf16: bf16 would be emulated, slower than fp32")
        layout = spatial_model
    elif caps.type == "cuda" and cc is not None:
        auto = "bf16" if cc >= (8, 0) else "fp16" if cc >= (7, 0) else "fp32"
        reasons.append(f"GPU compute capability {cc[0]}.{cc[1]}"
                       + {"bf16": ": native bf16", "fp16": ": tensor cores without bf16",
                          "fp32": ": no tensor cores"}[auto])
        layout = spatial_model and cc >= (7, 0)
    else:
        auto = "fp32"
        reasons.append(f"{caps.type} device: fp32")
        layout = False
    chosen: Precision
    if precision == "auto":
        chosen = auto
    else:
        chosen = precision  # type: ignore[assignment]
        reasons.append(f"TRAIN_PRECISION = {precision!r}")
        if chosen != "fp32" and caps.type not in ("cpu", "cuda"):
            raise ValueError(f"TRAIN_PRECISION = {precision!r} is not supported on a {caps.type} device; "
                             "use 'auto' or 'fp32'")
        if chosen != auto and chosen != "fp32":
            logger.warning("TRAIN_PRECISION = %r on %s (%s): it runs, but slower than %s", precision,
                           caps.name or caps.type, "; ".join(reasons[:1]), auto)
    use_compile = False
    if compile:
        if caps.can_compile:
            use_compile = True
        else:
            need = "a C++ compiler (g++) on PATH" if caps.type == "cpu" else "Triton and compute capability 7.0+"
            logger.warning("TRAIN_COMPILE = True but torch.compile needs %s here: training eagerly", need)
            reasons.append("torch.compile unavailable")
    cuda = caps.type == "cuda"
    return TrainPlan(device_type=caps.type, precision=chosen, channels_last=layout,
                     grad_scaler=chosen == "fp16", pin_memory=cuda, non_blocking=cuda, compile=use_compile,
                     reasons=tuple(reasons))


def plan_for(device: torch.device, precision: str = "auto", compile: bool = False,
             spatial_model: bool = True) -> TrainPlan:
    """:func:`choose_plan` for ``device`` as probed now."""
    return choose_plan(probe_device(device), precision, compile, spatial_model)


@contextlib.contextmanager
def autocast(plan: TrainPlan) -> Iterator[None]:
    """Autocast in the plan's precision (nothing for fp32)."""
    dtype = plan.autocast_dtype
    if dtype is None:
        yield
        return
    with torch.autocast(plan.device_type, dtype=dtype):
        yield


def grad_scaler(plan: TrainPlan) -> Any:
    """A ``torch.amp.GradScaler`` for fp16 plans, None otherwise."""
    return torch.amp.GradScaler(plan.device_type) if plan.grad_scaler else None


def apply_layout(model: torch.nn.Module, plan: TrainPlan) -> torch.nn.Module:
    """Put ``model``'s weights in the plan's memory layout, in place (before any DDP wrapping:
    DistributedDataParallel must see the parameters it will train); returns the model."""
    if plan.channels_last:
        model.to(memory_format=torch.channels_last)
    return model


def to_layout(x: torch.Tensor, plan: TrainPlan) -> torch.Tensor:
    """An image batch in the plan's memory layout (no copy when it already is)."""
    if plan.channels_last and x.dim() == 4:
        return x.contiguous(memory_format=torch.channels_last)
    return x
