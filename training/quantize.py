"""int8 ONNX exports for Raspberry Pi-class CPUs: ONNX Runtime's static or dynamic quantisation.

- **static** (default): weights int8 per output channel, activations uint8 with ranges measured on
  calibration frames from tubs (MinMax over ``frames`` samples spread over the records, run
  through the model's own preprocessing), QDQ format. Convolutions and matrix products run as
  integer kernels.
- **dynamic**: weights int8, activation ranges computed at run time for every input; needs no
  data, but its integer convolutions (ConvInteger) are often slower than float on x86.

The exported file (``NAME.int8.onnx`` by default) carries the source model's metadata and hash like
every export (:mod:`training.export`), plus ``quantization`` (method, calibration frames and
tubs), and runs with ``PILOT_BACKEND = "onnx-int8"``. Accuracy and speed against the float export
are measured by ``bench/int8.py`` (docs/benchmarks.md): check them for your model before driving.
"""

from __future__ import annotations

import logging
import os
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np

logger = logging.getLogger(__name__)

Method = Literal["static", "dynamic"]
METHODS: tuple[str, ...] = ("static", "dynamic")
DEFAULT_CALIBRATION_FRAMES = 300


def calibration_inputs(meta: dict[str, Any], tubs: Sequence[str | os.PathLike[str]],
                       frames: int = DEFAULT_CALIBRATION_FRAMES) -> list[dict[str, np.ndarray]]:
    """Up to ``frames`` model inputs (``{"images": ..., ["extra": ...]}``, batch 1) from ``tubs``,
    spread evenly over their records, preprocessed as the model was trained (centre camera, no
    augmentation; history and extra inputs from the records, as in training)."""
    import torch

    from parts.pilots.preprocess import Preprocess
    from training.dataset import IMAGE_KEY, PilotDataset, build_samples, read_drive_data
    from training.framecache import FrameCache

    desc = meta["model"]
    pre = Preprocess.from_dict(meta["preprocess"])
    n_frames, history = int(desc.get("frames", 1)), int(desc.get("command_history", 0))
    extra_inputs = list(desc.get("extra_inputs", ()))
    data = read_drive_data(tubs, modes=None)
    samples = build_samples(data, np.arange(len(data)), depth=max(n_frames - 1, history))
    if len(samples) == 0:
        raise ValueError(f"no usable records for calibration in {', '.join(map(str, tubs))}")
    pick = np.unique(np.linspace(0, len(samples) - 1, min(frames, len(samples))).round().astype(np.int64))
    samples = samples.subset(np.isin(np.arange(len(samples)), pick))
    keys = list(desc.get("image_inputs") or [IMAGE_KEY])
    ds = PilotDataset(data, samples, FrameCache(data.records, keys, enabled=False), pre,
                      frames=n_frames, command_history=history, views=len(keys),
                      extra_key=extra_inputs[0] if extra_inputs else None, extra_size=int(desc.get("extra_size", 0)))
    out = []
    for i in range(len(ds)):
        x, extra, _ = ds[i]
        feed = {"images": pre.normalize_batch(x)[None].numpy()}
        if extra.numel():
            feed["extra"] = extra[None].to(torch.float32).numpy()
        out.append(feed)
    return out


class _Reader:
    """ONNX Runtime's CalibrationDataReader protocol over prepared inputs."""

    def __init__(self, inputs: list[dict[str, np.ndarray]]) -> None:
        self._inputs = inputs
        self._it: Iterator[dict[str, np.ndarray]] = iter(inputs)

    def get_next(self) -> dict[str, np.ndarray] | None:
        return next(self._it, None)

    def rewind(self) -> None:
        self._it = iter(self._inputs)


def default_calibration_tubs(meta: dict[str, Any]) -> list[str]:
    """The tubs the model was trained on that still exist (``meta["datasets"]``)."""
    return [t for t in meta.get("datasets") or [] if Path(t).is_dir()]


def quantize_onnx(float_onnx: str | os.PathLike[str], out: str | os.PathLike[str], meta: dict[str, Any],
                  method: Method | str = "static", tubs: Sequence[str | os.PathLike[str]] | None = None,
                  frames: int = DEFAULT_CALIBRATION_FRAMES) -> dict[str, Any]:
    """Quantise the float export ``float_onnx`` into ``out``; returns the ``quantization`` record.

    Raises:
        ValueError: unknown method, or static quantisation without calibration tubs.
        ImportError: onnxruntime (with its quantization tools) is not installed.
    """
    if method not in METHODS:
        raise ValueError(f"unknown int8 method {method!r}: use one of {', '.join(METHODS)}")
    try:
        from onnxruntime.quantization import (
            CalibrationMethod,
            QuantFormat,
            QuantType,
            quant_pre_process,
            quantize_dynamic,
            quantize_static,
        )
    except ImportError as exc:
        raise ImportError("int8 export needs onnxruntime: pip install 'vehicle-rc[export]'") from exc
    record: dict[str, Any] = {"method": method, "calibration_frames": 0, "calibration_tubs": []}
    with tempfile.TemporaryDirectory(prefix="vehicle-int8-") as tmp:
        prepared = Path(tmp) / "prepared.onnx"
        # shape inference + graph optimisation first (ONNX Runtime's recommended pre-processing)
        quant_pre_process(str(float_onnx), str(prepared), skip_symbolic_shape=True)
        if method == "dynamic":
            quantize_dynamic(str(prepared), str(out), weight_type=QuantType.QInt8, per_channel=True)
            return record
        tubs = list(tubs) if tubs else default_calibration_tubs(meta)
        if not tubs:
            raise ValueError("static int8 quantisation needs calibration frames and the model's training tubs "
                             f"({meta.get('datasets') or 'none recorded'}) are gone: pass tubs with "
                             "--calibration TUB (or use --int8 dynamic)")
        inputs = calibration_inputs(meta, tubs, frames)
        quantize_static(str(prepared), str(out), _Reader(inputs), quant_format=QuantFormat.QDQ,
                        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8, per_channel=True,
                        calibrate_method=CalibrationMethod.MinMax)
        record.update(calibration_frames=len(inputs), calibration_tubs=[str(t) for t in tubs])
    logger.info("int8 (%s) quantisation of %s: %d calibration frames", method, float_onnx,
                record["calibration_frames"])
    return record

