"""Errors about model files, in a module without torch: an ONNX pilot on a Pi reports them too."""

from __future__ import annotations

from vehicle.errors import VehicleError


class ModelFileError(VehicleError, ValueError):
    """A model file is missing, corrupt, unsafe (pickled objects) or does not fit this version."""
