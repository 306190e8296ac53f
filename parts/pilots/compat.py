"""Does a model file fit the car it is about to drive? Behaviour order and camera undistortion.

A behaviour model's one-hot input means what BEHAVIOR_LIST meant when it was trained: index 0 is
the first behaviour of the training order (stored as ``meta["training"]["behaviors"]``). A car
with the list in another order would swap the lanes without a word, so it is refused. A model
trained on undistorted frames (``meta["camera"]``, CAMERA_UNDISTORT when it was trained) sees
other images on a car that does not undistort, and the other way round: refused too.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

BEHAVIOR_KEY = "behavior/one_hot_state_array"


class ModelMismatch(VehicleError, ValueError):
    """A model file does not fit the car's settings (the message names the setting to change)."""


@dataclass(frozen=True)
class CarInputs:
    """What the car feeds a pilot, as far as a model file can be checked against it.

    Attributes:
        behaviors: BEHAVIOR_LIST (None: not checked).
        train_behaviors: TRAIN_BEHAVIORS (whether the car makes the behaviour input).
        undistort: CAMERA_UNDISTORT (None: not checked).
        calibration_size: (width, height) the car's camera calibration was made at, when it undistorts.
    """

    behaviors: tuple[str, ...] | None = None
    train_behaviors: bool = True
    undistort: bool | None = None
    calibration_size: tuple[int, int] | None = None

    @classmethod
    def from_config(cls, cfg: Any) -> CarInputs:
        """The car's BEHAVIOR_LIST, TRAIN_BEHAVIORS, CAMERA_UNDISTORT and its calibration's size."""
        return cls(tuple(cfg.BEHAVIOR_LIST), bool(cfg.TRAIN_BEHAVIORS), bool(cfg.CAMERA_UNDISTORT),
                   calibration_size(cfg) if cfg.CAMERA_UNDISTORT else None)


def calibration_size(cfg: Any) -> tuple[int, int] | None:
    """(width, height) of the car's camera calibration (CAMERA_CALIBRATION_PATH), None without one."""
    from parts.vision.calibration import CalibrationError, CameraCalibration

    try:
        return CameraCalibration.load(cfg.path("CAMERA_CALIBRATION_PATH")).image_size
    except CalibrationError:
        return None


def camera_meta(cfg: Any) -> dict[str, Any]:
    """What a model file records about its frames (``meta["camera"]``): whether they were undistorted
    (CAMERA_UNDISTORT) and the size the calibration was made at."""
    size = calibration_size(cfg) if cfg.CAMERA_UNDISTORT else None
    return {"undistort": bool(cfg.CAMERA_UNDISTORT), "calibration_size": list(size) if size else None}


def check_model(name: str, meta: dict[str, Any], extra_inputs: Sequence[str], extra_size: int,
                car: CarInputs) -> None:
    """Raise :class:`ModelMismatch` when model ``name`` (its metadata ``meta``, its extra inputs)
    does not fit ``car``; log a warning where it may not."""
    if BEHAVIOR_KEY in extra_inputs and car.behaviors is not None:
        _check_behaviors(name, meta, extra_size, car)
    camera = meta.get("camera")
    if car.undistort is not None and isinstance(camera, dict) and "undistort" in camera:
        _check_camera(name, camera, car)


def _check_behaviors(name: str, meta: dict[str, Any], extra_size: int, car: CarInputs) -> None:
    car_list = list(car.behaviors or ())
    trained = (meta.get("training") or {}).get("behaviors") or None
    also = "" if car.train_behaviors else "; set TRAIN_BEHAVIORS = True"
    if trained is not None and list(trained) != car_list:
        raise ModelMismatch(f"{name} was trained with {list(trained)}, BEHAVIOR_LIST is {car_list}: the behaviours "
                            f"would be swapped; set BEHAVIOR_LIST = {list(trained)!r} in myconfig.py (same names, "
                            f"same order){also}")
    if trained is None:
        if extra_size != len(car_list):
            raise ModelMismatch(f"{name} takes {extra_size} behaviours, BEHAVIOR_LIST {car_list} has "
                                f"{len(car_list)}: set BEHAVIOR_LIST to the list its tubs were recorded with{also}")
        logger.warning("%s does not record its behaviour names: check BEHAVIOR_LIST %s is in the order its tubs "
                       "were recorded with (else the behaviours are swapped)", name, car_list)


def _check_camera(name: str, camera: dict[str, Any], car: CarInputs) -> None:
    trained = bool(camera["undistort"])
    if trained != car.undistort:
        frames = "undistorted" if trained else "raw (not undistorted)"
        raise ModelMismatch(f"{name} was trained on {frames} frames but CAMERA_UNDISTORT is {car.undistort}: set "
                            f"CAMERA_UNDISTORT = {trained} in myconfig.py, or train on frames recorded the way the "
                            "car drives")
    size = camera.get("calibration_size")
    if trained and size and car.calibration_size and tuple(size) != tuple(car.calibration_size):
        logger.warning("%s was trained on frames undistorted with a calibration made at %dx%d, the car's is "
                       "made at %dx%d: the undistorted view may differ; retrain if it drives worse", name, *size,
                       *car.calibration_size)
