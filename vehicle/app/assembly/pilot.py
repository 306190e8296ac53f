"""Assembly of the pilot: drive with a trained model (``add_pilot``)."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def add_pilot(V: Any, cfg: Config, model_path: str | Path) -> Any:
    """Add PilotCondition (``user/mode`` -> ``run_pilot``), the model switcher and the Pilot.

    The pilot runs only while ``run_pilot`` is True and reads the inputs its model file declares
    (``cam/image_array`` first); it outputs ``pilot/angle`` and ``pilot/throttle``. A
    :class:`parts.pilots.pilot.ModelSwitch` (every loop) loads the model named in
    ``pilot/model_request`` in the background and outputs ``pilot/model``. With
    PILOT_SPEED_CONTROL set, a speed controller replaces the model's throttle while
    ``user/speed_limit`` (the web page's limit; PILOT_SPEED_LIMIT while it is None) is set.
    Returns the Pilot.

    Raises:
        UserError: the model file is missing, unreadable, or the backend setting cannot be met.
    """
    from parts.drive.modes import PilotCondition
    from parts.pilots import load_pilot
    from parts.pilots.pilot import ModelSwitch

    path = Path(model_path)
    if not path.is_absolute() and not path.exists():
        path = Path(cfg.CAR_PATH) / path  # manage.py may run from another folder
    speed_control = None
    speed_key = "enc/speed"
    if cfg.PILOT_SPEED_CONTROL != "off":
        from parts.drive.speed import SpeedControl

        speed_control = SpeedControl(cfg.PILOT_SPEED_CONTROL, dt=1.0 / cfg.DRIVE_LOOP_HZ,
                                     kp=cfg.PILOT_SPEED_KP, ki=cfg.PILOT_SPEED_KI,
                                     max_throttle=cfg.PILOT_SPEED_MAX_THROTTLE,
                                     default_limit=cfg.PILOT_SPEED_LIMIT)
        # the simulator measures its speed; a real car needs an encoder part writing enc/speed
        speed_key = cfg.PILOT_SPEED_KEY or ("sim/speed" if V.produces("sim/speed") else "enc/speed")
    try:
        pilot = load_pilot(path, backend=cfg.PILOT_BACKEND, speed_control=speed_control, speed_key=speed_key,
                           onnx_threads=cfg.PILOT_ONNX_THREADS, models_dir=cfg.path("MODELS_PATH"))
    except (ValueError, ImportError, OSError) as exc:
        raise UserError(f"cannot drive with {path}: {exc}") from exc
    V.add(PilotCondition())
    V.add(ModelSwitch(pilot))
    pilot.lock_inputs = True  # the vehicle's wiring is fixed from here on
    V.add(pilot, run_condition="run_pilot")
    return pilot
