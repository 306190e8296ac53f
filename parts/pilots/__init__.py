"""Pilots: what drives the car with a trained model: the Pilot part, the model types (``models/``),
the preprocessing shared with training, the runtimes (PyTorch, ONNX Runtime, TorchScript) and the
model file format. Training them is the separate :mod:`training` package, which no part imports.

Importing this package is light: torch is imported only when a model is loaded.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from parts.pilots.pilot import Pilot


def load_pilot(path: str | Path, *, backend: str = "auto", **options: Any) -> Pilot:
    """The :class:`parts.pilots.pilot.Pilot` part for a model file (.pt, .onnx or .ts).

    ``backend="auto"`` runs a sibling ``.onnx`` export when onnxruntime is installed and the export
    matches the .pt (see :mod:`parts.pilots.backends`); other options go to ``Pilot``
    (``speed_control``, ``speed_key``, ``onnx_threads``, ``models_dir``).
    """
    from parts.pilots.pilot import Pilot

    return Pilot(path, backend=backend, **options)


__all__ = ["load_pilot"]
