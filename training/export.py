"""Export a model file to TorchScript (``.ts``), ONNX (``.onnx``) or int8 ONNX (``.int8.onnx``).

Both exports compute the *controls* (angle, throttle) — the model's forward followed by its
``controls()`` decoding — from the preprocessed input, so every runtime needs only the shared
preprocessing (:mod:`parts.pilots.preprocess`) in front. Inputs: ``images`` ``(1, C, H, W)``
(``(1, T, C, H, W)`` for sequence models, ``(1, V, C, H, W)`` for the views of ``three_camera``)
and, for models with an extra input, ``extra`` ``(1, E)``. Output: ``controls`` ``(1, 2)``.

Each export carries the source model file's metadata (JSON) and the SHA-256 of the source file,
so an export is self-contained (``load_pilot("x.onnx")`` works without the .pt) and a stale export
(the .pt was retrained since) is detected: :func:`parts.pilots.export_files.export_matches`.
"""

from __future__ import annotations

import json
import logging
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch
from torch import nn

# the export file format's facts live in the torch-free export_files; imported here for callers
from parts.pilots.export_files import (  # noqa: F401
    META_KEY,
    SOURCE_KEY,
    SUFFIXES,
    ExportFormat,
    export_matches,
    file_sha256,
)
from parts.pilots.modelfile import load_model

logger = logging.getLogger(__name__)

ONNX_OPSET = 17


class ControlsModule(nn.Module):
    """``images -> controls``: the model's forward then its output decoding, for export."""

    def __init__(self, model: nn.Module) -> None:
        super().__init__()
        self.model = model

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.model.controls(self.model(images))


class ControlsWithExtraModule(ControlsModule):
    """``(images, extra) -> controls`` for models with an extra input (memory, behaviour)."""

    def forward(self, images: torch.Tensor, extra: torch.Tensor) -> torch.Tensor:  # type: ignore[override]
        return self.model.controls(self.model(images, extra))


def example_inputs(desc: dict[str, Any]) -> tuple[torch.Tensor, ...]:
    """Zero inputs of batch 1 shaped as the model described by ``meta["model"]`` expects."""
    shape = [int(v) for v in desc["input_shape"]]
    frames = int(desc.get("frames", 1))
    views = len(desc.get("image_inputs") or ("cam/image_array",))  # three_camera: (1, 3, C, H, W)
    lead = frames if frames > 1 else views
    images = torch.zeros(1, lead, *shape) if lead > 1 else torch.zeros(1, *shape)
    extra_size = int(desc.get("extra_size", 0))
    return (images, torch.zeros(1, extra_size)) if extra_size else (images,)


def controls_module(model: nn.Module, desc: dict[str, Any]) -> ControlsModule:
    """The export wrapper that fits the model's inputs."""
    wrapper = ControlsWithExtraModule(model) if int(desc.get("extra_size", 0)) else ControlsModule(model)
    return wrapper.eval()


def default_output(source: Path, fmt: str) -> Path:
    """Where an export goes by default: next to the model file, suffix .onnx or .ts."""
    return source.with_suffix(SUFFIXES[fmt])


def export_model(source: str | os.PathLike[str], fmt: ExportFormat | str = "onnx",
                 out: str | os.PathLike[str] | None = None, *, int8: str = "static",
                 calibration: Sequence[str | os.PathLike[str]] | None = None,
                 calibration_frames: int | None = None) -> Path:
    """Export the model file ``source`` to ``fmt`` ("onnx", "onnx-int8" or "torchscript"); returns
    the file.

    For "onnx-int8": ``int8`` is the method ("static" or "dynamic", :mod:`training.quantize`),
    ``calibration`` the tubs whose frames set the activation ranges (default: the tubs the model
    was trained on), ``calibration_frames`` how many (default 300).

    Raises:
        ValueError: unknown format or method, no calibration data for static int8.
        ImportError: ONNX export without the ``onnx`` package (``pip install vehicle-rc[export]``).
        parts.pilots.modelfile.ModelFileError: the source is not a valid model file.
    """
    if fmt not in SUFFIXES:
        raise ValueError(f"unknown export format {fmt!r}: use one of {', '.join(SUFFIXES)}")
    source = Path(source)
    model, meta = load_model(source, map_location="cpu")
    out_path = Path(out) if out is not None else default_output(source, fmt)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    desc = meta["model"]
    wrapper = controls_module(model, desc)
    inputs = example_inputs(desc)
    props = {META_KEY: json.dumps(meta, sort_keys=True), SOURCE_KEY: file_sha256(source)}
    tmp = out_path.with_name(f".{out_path.name}.tmp{os.getpid()}")
    try:
        if fmt == "onnx":
            _export_onnx(wrapper, inputs, tmp, props)
        elif fmt == "onnx-int8":
            from parts.pilots.export_files import QUANT_KEY
            from training.quantize import DEFAULT_CALIBRATION_FRAMES, quantize_onnx

            float_tmp = out_path.with_name(f".{out_path.name}.float{os.getpid()}")
            try:
                _export_onnx(wrapper, inputs, float_tmp, {})
                record = quantize_onnx(float_tmp, tmp, meta, int8, calibration,
                                       calibration_frames or DEFAULT_CALIBRATION_FRAMES)
            finally:
                float_tmp.unlink(missing_ok=True)
            _add_onnx_props(tmp, {**props, QUANT_KEY: json.dumps(record, sort_keys=True)})
        else:
            _export_torchscript(wrapper, inputs, tmp, props)
        os.replace(tmp, out_path)
    finally:
        tmp.unlink(missing_ok=True)
    logger.info("exported %s to %s", source, out_path)
    return out_path


def _export_onnx(wrapper: nn.Module, inputs: tuple[torch.Tensor, ...], out: Path,
                 props: dict[str, str]) -> None:
    try:
        import onnx  # noqa: F401 - checked here, used by _add_onnx_props
    except ImportError as exc:
        raise ImportError("ONNX export needs the onnx package: pip install 'vehicle-rc[export]'") from exc
    names = ["images", "extra"][:len(inputs)]
    with torch.no_grad(), warnings.catch_warnings():
        # The TorchScript-based exporter: the torch.export-based one needs onnxscript, which is not
        # a dependency, and these small CNNs export identically with either.
        warnings.simplefilter("ignore")
        torch.onnx.export(wrapper, inputs, str(out), dynamo=False, input_names=names,
                          output_names=["controls"], opset_version=ONNX_OPSET)
    _add_onnx_props(out, props)


def _add_onnx_props(path: Path, props: dict[str, str]) -> None:
    import onnx

    proto = onnx.load(str(path))
    for key, value in props.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(proto, str(path))


def _export_torchscript(wrapper: nn.Module, inputs: tuple[torch.Tensor, ...], out: Path,
                        props: dict[str, str]) -> None:
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # torch.jit is deprecated in favour of torch.export; still works
        traced = torch.jit.trace(wrapper, inputs, check_trace=False)
        torch.jit.save(traced, str(out), _extra_files={f"{k}.txt": v for k, v in props.items()})
