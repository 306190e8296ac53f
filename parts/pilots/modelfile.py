"""Model files: weights plus metadata in one file that never runs code.

The file is a ``torch.save`` of a plain dict::

    {"format": "vehicle-pilot", "format_version": 1,
     "state_dict": {name: tensor}, "meta": {...plain dicts/lists/str/numbers...}}

and is read with ``torch.load(..., weights_only=True)``, which refuses pickled Python objects.
``meta["model"]`` (written by :func:`save_model`) holds the type, input shape and options that
rebuild the architecture; the rest of ``meta`` is the caller's (preprocessing, training config,
dataset names, metrics) plus ``meta["versions"]``.
"""

from __future__ import annotations

import os
import pickle
import platform
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch
from torch import nn

from parts.pilots.errors import ModelFileError
from parts.pilots.models import PilotModel, create_model

FORMAT = "vehicle-pilot"
FORMAT_VERSION = 1


def _plain(value: Any, where: str) -> Any:
    """``value`` as plain dicts/lists/str/numbers/None (tuples become lists); TypeError otherwise."""
    if value is None or isinstance(value, bool | str | int):
        return value
    if isinstance(value, float):
        return float(value)
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise TypeError(f"model metadata key {k!r} at {where} must be a str")
            out[k] = _plain(v, f"{where}.{k}")
        return out
    if isinstance(value, list | tuple):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:  # numpy / torch scalars
        return _plain(value.item(), where)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"model metadata at {where} is a {type(value).__name__}; only dicts, lists, str, "
                    "numbers, bool and None can be stored (a model file never holds Python objects)")


def versions() -> dict[str, str]:
    """Versions of the software that wrote a model file."""
    try:
        from importlib.metadata import version
        package = version("vehicle-rc")
    except Exception:  # not installed as a distribution (running from a checkout)
        package = "unknown"
    return {"vehicle": package, "torch": torch.__version__.split("+")[0], "python": platform.python_version()}


def unwrap(model: nn.Module) -> nn.Module:
    """The bare model inside a DistributedDataParallel / DataParallel wrapper."""
    while isinstance(model, nn.parallel.DistributedDataParallel | nn.DataParallel):
        model = model.module
    return model


def save_model(path: str | os.PathLike[str], model: nn.Module, meta: dict[str, Any]) -> Path:
    """Write ``model`` (a :class:`PilotModel`, possibly DDP-wrapped) and ``meta`` to ``path``.

    The write is atomic (temporary file then rename), so a crash never leaves half a model.
    Returns the path written. Raises TypeError when ``meta`` holds anything but plain values.
    """
    model = unwrap(model)
    if not isinstance(model, PilotModel):
        raise TypeError(f"save_model needs a PilotModel from parts.pilots.models, got {type(model).__name__}")
    plain_meta = _plain(dict(meta), "meta")
    plain_meta["model"] = _plain(model.describe(), "meta.model")
    plain_meta.setdefault("versions", versions())
    state = {k: v.detach().to("cpu").clone() for k, v in model.state_dict().items()}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        torch.save({"format": FORMAT, "format_version": FORMAT_VERSION, "state_dict": state,
                    "meta": plain_meta}, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _read(path: str | os.PathLike[str], map_location: Any) -> dict[str, Any]:
    path = Path(path)
    if path.is_dir():
        raise ModelFileError(f"{path} is a folder; pass the model file (e.g. models/mypilot.pt)")
    if not path.is_file():
        raise ModelFileError(f"{path}: no such model file. Train one with `manage.py train` "
                             "or check the path.")
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5", ".keras", ".tflite"):  # what DonkeyCar and drive.py scripts trained
        raise ModelFileError(f"{path}: a Keras/TensorFlow model cannot be loaded; import its data "
                             "(`vehicle tub import-udacity`, or DonkeyCar tubs as they are) and train here "
                             "with `manage.py train`")
    if suffix in (".onnx", ".ts"):
        raise ModelFileError(f"{path}: an export for driving only; use the model it was exported from "
                             f"({path.with_suffix('.pt')})")
    if not zipfile.is_zipfile(path):  # torch.save has written zip archives since torch 1.6
        raise ModelFileError(f"{path}: not a model file (not a torch zip archive; corrupt, truncated or "
                             "another format). Train a model with `manage.py train` or `vehicle train`.")
    _check_archive(path)
    try:
        data = torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as exc:
        found = [line.strip().split(" was not")[0] for line in str(exc).splitlines()
                 if "Unsupported global" in line]
        raise ModelFileError(
            f"{path}: refused: the file contains pickled Python objects, which could run code when "
            f"loaded. Only model files written by this framework (weights + plain metadata) are "
            f"accepted; re-train or re-save the model. ({found[0] if found else 'weights_only load failed'})"
        ) from exc
    except Exception as exc:  # torch raises many types for damaged archives (RuntimeError, struct.error..)
        raise ModelFileError(f"{path}: not a readable model file (corrupt or truncated?): "
                             f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}") from exc
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ModelFileError(f"{path}: not a {FORMAT} model file (it was not written by save_model); "
                             "train a model with `manage.py train` or `vehicle train`.")
    version = data.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise ModelFileError(f"{path}: model file format version {version!r} is newer than this software "
                             f"reads ({FORMAT_VERSION}); upgrade the vehicle package.")
    if not isinstance(data.get("state_dict"), dict) or not isinstance(data.get("meta"), dict) \
            or not isinstance(data["meta"].get("model"), dict):
        raise ModelFileError(f"{path}: model file is incomplete (no weights or no model description)")
    return data


def _check_archive(path: Path) -> None:
    """Refuse an archive whose members fail their CRC-32 (torch.load does not check them: bytes
    flipped inside the weights load silently as other weights)."""
    try:
        with zipfile.ZipFile(path) as zf:
            bad = zf.testzip()
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:
        raise ModelFileError(f"{path}: not a readable model file (damaged zip archive: {exc}); copy it again "
                             "or retrain") from exc
    if bad is not None:
        raise ModelFileError(f"{path}: damaged: {bad} fails its CRC-32 check (a bad copy or a failing "
                             "disk); copy the model again or retrain it")


def read_meta(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The metadata of a model file without building the model (for listings and registries)."""
    return _read(path, "cpu")["meta"]


def load_model(path: str | os.PathLike[str], map_location: Any = "cpu") -> tuple[PilotModel, dict[str, Any]]:
    """Rebuild the model stored in ``path``; returns ``(model in eval mode, meta)``.

    Raises:
        ModelFileError: missing, corrupt, pickled objects inside, unknown model type, or weights
            that do not fit the described architecture.
    """
    data = _read(path, map_location)
    meta = data["meta"]
    desc = meta["model"]
    try:
        model = create_model(desc["type"], desc["input_shape"], **desc.get("options", {}))
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelFileError(f"{path}: cannot rebuild the model it describes ({exc}); it may come from "
                             "a newer version of the software.") from exc
    try:
        model.load_state_dict(data["state_dict"], strict=True)
    except RuntimeError as exc:
        raise ModelFileError(f"{path}: the weights do not fit a {desc['type']!r} model of input shape "
                             f"{desc['input_shape']} ({str(exc).splitlines()[0]})") from exc
    for name, tensor in data["state_dict"].items():
        if tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
            raise ModelFileError(f"{path}: weight {name!r} holds NaN or infinite values (training diverged); "
                                 "re-train with a lower learning rate.")
    if isinstance(map_location, str | torch.device):
        model.to(map_location)
    model.eval()
    return model, meta
