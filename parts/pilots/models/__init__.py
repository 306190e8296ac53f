"""Registry of pilot model types by name, all PyTorch.

``create_model("linear", (3, 120, 160))`` builds a model; ``model_type("pilotnet")`` gives its
class (declared inputs, outputs, loss, defaults). See :mod:`parts.pilots.models.base` for the
contract every model type follows.
"""

from __future__ import annotations

import difflib
from typing import Any

from parts.pilots.models.base import PilotModel
from parts.pilots.models.cnn import (
    BehaviorModel,
    CategoricalModel,
    InferredModel,
    LinearModel,
    LinearTanhModel,
    MemoryModel,
)
from parts.pilots.models.lanes import LanesBasicModel, LanesModel
from parts.pilots.models.multicam import ThreeCameraModel
from parts.pilots.models.pilotnet import NvidiaModel, PilotNetModel
from parts.pilots.models.sequence import Conv3DModel, RNNModel

__all__ = ["PilotModel", "create_model", "model_type", "model_type_names", "register_model_type"]

_REGISTRY: dict[str, type[PilotModel]] = {}


def register_model_type(cls: type[PilotModel]) -> type[PilotModel]:
    """Add a model class to the registry under ``cls.type_name`` (usable as a decorator)."""
    if not cls.type_name:
        raise ValueError(f"{cls.__name__} has no type_name")
    if cls.type_name in _REGISTRY and _REGISTRY[cls.type_name] is not cls:
        raise ValueError(f"model type {cls.type_name!r} is already registered by {_REGISTRY[cls.type_name]}")
    _REGISTRY[cls.type_name] = cls
    return cls


for _cls in (LinearModel, LinearTanhModel, CategoricalModel, InferredModel, PilotNetModel, MemoryModel,
             BehaviorModel, RNNModel, Conv3DModel, LanesModel, LanesBasicModel, NvidiaModel, ThreeCameraModel):
    register_model_type(_cls)


def model_type_names() -> list[str]:
    """Names of every registered model type."""
    return sorted(_REGISTRY)


def model_type(name: str) -> type[PilotModel]:
    """The class registered as ``name``; ValueError naming the known types otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        close = difflib.get_close_matches(str(name), _REGISTRY, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ValueError(f"unknown model type {name!r}.{hint} Known types: {', '.join(model_type_names())}") \
            from None


def create_model(name: str, input_shape: tuple[int, int, int] | list[int], **options: Any) -> PilotModel:
    """Build a fresh model of type ``name`` for preprocessed frames of ``input_shape`` (C, H, W).

    Options not given take the type's defaults (``model_type(name).defaults``); unknown options
    are refused.
    """
    cls = model_type(name)
    unknown = set(options) - set(cls.defaults)
    if unknown:
        raise ValueError(f"unknown option(s) {sorted(unknown)} for model type {name!r}; "
                         f"it takes {sorted(cls.defaults)}")
    return cls(tuple(int(v) for v in input_shape), {**cls.defaults, **options})
