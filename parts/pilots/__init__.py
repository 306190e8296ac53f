"""Pilots: model types, preprocessing, training, and the part that drives with a trained model.

Importing this package is light: torch is imported only when a model is loaded or trained.
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
