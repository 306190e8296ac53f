"""Inference backends behind the Pilot part: eager PyTorch, TorchScript and ONNX Runtime (float or int8).

A :class:`Runner` turns one *preprocessed* input (batch 1) into ``(angle, throttle)``; every
backend is fed by the same preprocessing code as training (:mod:`parts.pilots.preprocess`), built
from the metadata stored in the model file (and copied into each export).

:func:`open_runner` picks the backend for a path:

- ``.onnx`` → ONNX Runtime; ``.ts`` → TorchScript; ``.pt`` → eager PyTorch, except that with
  ``backend="auto"`` a sibling ``NAME.onnx`` is preferred when onnxruntime is installed and the
  export was made from the .pt as it is now (same SHA-256, recorded in the export by
  :mod:`training.export`). A stale or foreign .onnx is ignored with a log line, never used.
- ``backend="torch" | "onnx" | "torchscript"`` forces one (for .pt: the sibling export).
- ``backend="onnx-int8"`` runs the int8 export ``NAME.int8.onnx`` (:mod:`training.quantize`);
  only when asked, never by "auto": whether int8 pays depends on the CPU and the model
  (``bench/int8.py`` measures both speed and steering difference).
"""

from __future__ import annotations

import abc
import json
import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

if TYPE_CHECKING:
    import torch

    from parts.pilots.preprocess import Preprocess

logger = logging.getLogger(__name__)

Backend = Literal["auto", "torch", "onnx", "onnx-int8", "torchscript"]
BACKENDS: tuple[str, ...] = ("auto", "torch", "onnx", "onnx-int8", "torchscript")


def preprocessing_from_meta(meta: dict[str, Any]) -> Preprocess:
    """The training preprocessing stored in ``meta["preprocess"]``."""
    from parts.pilots.preprocess import Preprocess

    try:
        return Preprocess.from_dict(meta.get("preprocess") or {})
    except (TypeError, ValueError) as exc:
        raise ValueError(f"the model's preprocessing settings are invalid: {exc}") from exc


class Runner(abc.ABC):
    """One loaded model: its metadata, its preprocessing and a batch-1 ``predict``.

    Attributes:
        path: the file loaded; ``backend``: "torch", "torchscript" or "onnx"; ``meta``: the model
        file's metadata; ``preprocess``: frame (HxWx3 uint8 RGB) -> float32 array (C, H, W).
    """

    backend = ""

    def __init__(self, path: Path, meta: dict[str, Any] | str) -> None:
        from parts.pilots.errors import ModelFileError

        self.path = path
        try:
            self.meta = meta = json.loads(meta) if isinstance(meta, str) else meta
            desc = meta["model"]
            self.model_type: str = str(desc["type"])
            self.frames = int(desc.get("frames", 1))
            #: camera frames per prediction, in the model's view order (older files: the centre one)
            self.image_inputs: tuple[str, ...] = tuple(str(k) for k in desc.get("image_inputs") or ("cam/image_array",))
            self.command_history = int(desc.get("command_history", 0))
            self.extra_inputs: tuple[str, ...] = tuple(str(k) for k in desc.get("extra_inputs", ()))
            self.extra_size = int(desc.get("extra_size", 0))
            self.input_shape = tuple(int(v) for v in desc["input_shape"])
            self.preprocessing = preprocessing_from_meta(meta)
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            self.close()
            raise ModelFileError(f"{path}: the model description stored in the file is invalid or "
                                 f"incomplete ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
                                 "export the model again with `vehicle models export`") from exc

    def preprocess(self, image: np.ndarray) -> np.ndarray:
        """A camera frame (HxWx3 uint8 RGB) -> the model's float32 input (C, H, W)."""
        return self.preprocessing.array(image)  # numpy only: an ONNX pilot runs without torch

    def check_frames(self, frame_shape: tuple[int, ...]) -> None:
        """Raise ValueError unless camera frames of ``frame_shape`` (H, W, C) fit this model: the
        size it was trained on, and, after its preprocessing, its input shape."""
        pre = self.preprocessing
        pre.check_frame_shape(frame_shape)
        got = pre.output_shape(frame_shape)
        if got != self.input_shape:
            raise ValueError(f"{'x'.join(map(str, frame_shape))} frames give model inputs of shape {got} "
                             f"after the model's preprocessing, but it takes {self.input_shape}")


    @property
    def name(self) -> str:
        """The model's file name (what ``pilot/model`` shows)."""
        return self.path.name

    @abc.abstractmethod
    def predict(self, images: np.ndarray, extra: np.ndarray | None) -> tuple[float, float]:
        """``(angle, throttle)`` for one preprocessed input (batch dimension included)."""

    def close(self) -> None:  # noqa: B027 - optional
        """Release the backend's resources."""


class TorchRunner(Runner):
    """Eager PyTorch: eval mode, ``torch.inference_mode``, batch 1."""

    backend = "torch"

    def __init__(self, path: Path, model: torch.nn.Module | None = None,
                 meta: dict[str, Any] | None = None) -> None:
        if model is None or meta is None:
            from parts.pilots.modelfile import load_model

            model, meta = load_model(path, map_location="cpu")
        super().__init__(path, meta)
        self.model = model.eval()

    def predict(self, images: np.ndarray, extra: np.ndarray | None) -> tuple[float, float]:
        import torch

        with torch.inference_mode():
            x = torch.from_numpy(images)
            e = None if extra is None else torch.from_numpy(extra)
            out = self.model.controls(self.model(x, e))
            angle, throttle = out[0].tolist()
        return angle, throttle


class TorchScriptRunner(Runner):
    """A TorchScript export (``.ts``), run under ``torch.inference_mode``."""

    backend = "torchscript"

    def __init__(self, path: Path) -> None:
        from parts.pilots.export_files import META_KEY, SOURCE_KEY

        self.module, props = read_torchscript(path)
        self.source_sha256 = props.get(SOURCE_KEY)
        super().__init__(path, props[META_KEY])

    def predict(self, images: np.ndarray, extra: np.ndarray | None) -> tuple[float, float]:
        import torch

        with torch.inference_mode():
            args = (torch.from_numpy(images),) if extra is None else (torch.from_numpy(images),
                                                                      torch.from_numpy(extra))
            angle, throttle = self.module(*args)[0].tolist()
        return angle, throttle


def read_torchscript(path: str | os.PathLike[str]) -> tuple[Any, dict[str, str]]:
    """Load a TorchScript export; returns ``(scripted module, {META_KEY: ..., SOURCE_KEY: ...})``."""
    import warnings

    import torch

    from parts.pilots.errors import ModelFileError
    from parts.pilots.export_files import META_KEY, SOURCE_KEY

    extra = {f"{k}.txt": "" for k in (META_KEY, SOURCE_KEY)}
    if not Path(path).is_file():
        raise ModelFileError(f"{path}: no such TorchScript file; export one with "
                             "`vehicle models export MODEL --format torchscript`")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            module = torch.jit.load(str(path), map_location="cpu", _extra_files=extra)
        props = {k[:-4]: (v.decode() if isinstance(v, bytes) else v) for k, v in extra.items()}
    except Exception as exc:  # torch raises RuntimeError (and others) for damaged or foreign files
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelFileError(f"{path}: not a readable TorchScript file (corrupt, truncated or another "
                             f"format: {first[:160]}); export the model again with `vehicle models export "
                             "MODEL --format torchscript`") from exc
    if not props.get(META_KEY):
        raise ModelFileError(f"{path}: not a TorchScript export of a pilot model (no {META_KEY}); "
                             "export one with `vehicle models export MODEL --format torchscript`")
    return module.eval(), props


def onnxruntime_available() -> bool:
    """Whether onnxruntime can be imported."""
    try:
        import onnxruntime  # noqa: F401
    except ImportError:
        return False
    return True


class OnnxRunner(Runner):
    """An ONNX export run by ONNX Runtime on the CPU with ``threads`` intra-op threads."""

    backend = "onnx"

    def __init__(self, path: Path, threads: int = 1) -> None:
        from parts.pilots.export_files import META_KEY, SOURCE_KEY

        try:
            import onnxruntime as ort
        except ImportError as exc:
            raise ImportError(f"{path}: running an ONNX model needs onnxruntime: "
                              "pip install 'vehicle-rc[export]' (or drive the .pt model)") from exc
        if not isinstance(threads, int) or threads < 0:
            raise ValueError(f"ONNX threads must be an int >= 0 (0 = onnxruntime's default), got {threads!r}")
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        try:
            self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types
            raise ValueError(f"{path}: not a loadable ONNX model: {exc}") from exc
        props = self.session.get_modelmeta().custom_metadata_map
        if META_KEY not in props:
            raise ValueError(f"{path}: not an ONNX export of a pilot model (no {META_KEY} metadata); "
                             "export one with `vehicle models export MODEL --format onnx`")
        self.source_sha256 = props.get(SOURCE_KEY)
        from parts.pilots.export_files import quant_record

        self.quantization = quant_record(props)
        if self.quantization is not None:
            self.backend = "onnx-int8"
        self.input_names = [i.name for i in self.session.get_inputs()]
        super().__init__(path, props[META_KEY])

    def predict(self, images: np.ndarray, extra: np.ndarray | None) -> tuple[float, float]:
        feed = {self.input_names[0]: images}
        if extra is not None:
            feed[self.input_names[1]] = extra
        out = self.session.run(None, feed)[0]
        return float(out[0, 0]), float(out[0, 1])


def sibling_onnx(path: Path, threads: int = 1) -> OnnxRunner | None:
    """The ONNX export next to the .pt ``path`` if it exists, onnxruntime is installed and the
    export matches the .pt as it is now; None (with a log line saying why) otherwise."""
    from parts.pilots.export_files import export_matches

    onnx_path = path.with_suffix(".onnx")
    if not onnx_path.is_file():
        return None
    if not onnxruntime_available():
        logger.info("%s exists but onnxruntime is not installed: using PyTorch", onnx_path.name)
        return None
    try:
        runner = OnnxRunner(onnx_path, threads)
    except (ValueError, ImportError) as exc:
        logger.warning("ignoring %s: %s", onnx_path, exc)
        return None
    if not export_matches(path, runner.source_sha256):
        logger.warning("ignoring %s: it was exported from another version of %s; re-export with "
                       "`vehicle models export %s --format onnx`", onnx_path.name, path.name, path)
        runner.close()
        return None
    return runner


def open_runner(path: str | os.PathLike[str], backend: Backend | str = "auto",
                onnx_threads: int = 1) -> Runner:
    """Load ``path`` with the backend chosen as described in the module docstring.

    Raises:
        ValueError: unknown backend, or the forced export does not exist / does not match.
        parts.pilots.modelfile.ModelFileError: the model file is missing, corrupt or unsafe.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown pilot backend {backend!r}: use one of {', '.join(BACKENDS)}")
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".onnx":
        if backend not in ("auto", "onnx", "onnx-int8"):
            raise ValueError(f"{path} is an ONNX file: it runs with backend 'onnx' or 'onnx-int8', not {backend!r}")
        runner = OnnxRunner(path, onnx_threads)
        if backend == "onnx-int8" and runner.backend != "onnx-int8":
            raise ValueError(f"{path} is a float ONNX export, not an int8 one; create one with "
                             "`vehicle models export MODEL --format onnx-int8`")
        return runner
    if suffix == ".ts":
        if backend not in ("auto", "torchscript"):
            raise ValueError(f"{path} is a TorchScript file: it runs with backend 'torchscript', "
                             f"not {backend!r}")
        return TorchScriptRunner(path)
    if backend == "torch":
        return TorchRunner(path)
    if backend in ("onnx", "onnx-int8", "torchscript"):
        from parts.pilots.export_files import SUFFIXES, export_matches

        export = path.with_suffix(SUFFIXES[backend])
        if not export.is_file():
            raise ValueError(f"{export}: no {backend} export of {path.name}; create it with "
                             f"`vehicle models export {path} --format {backend}`")
        forced: Runner = TorchScriptRunner(export) if backend == "torchscript" else OnnxRunner(export, onnx_threads)
        if path.is_file() and not export_matches(path, getattr(forced, "source_sha256", None)):
            raise ValueError(f"{export} was exported from another version of {path.name}; re-export it "
                             f"with `vehicle models export {path} --format {backend}`")
        if forced.backend != backend:
            raise ValueError(f"{export} is not an {backend} export (it runs as {forced.backend}); re-export "
                             f"it with `vehicle models export {path} --format {backend}`")
        return forced
    if not path.is_file():
        from parts.pilots.errors import ModelFileError

        raise ModelFileError(f"{path}: no such model file. Train one with `manage.py train` "
                             "or check the path.")
    return sibling_onnx(path, onnx_threads) or TorchRunner(path)
