"""Assembly of the pilot: drive with a trained model (``add_pilot``)."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


# -- driving (pilots room, 5b) ---------------------------------------------------------------------
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
    from parts.pilots.pilot import SPEED_LIMIT_KEY, ModelSwitch

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
        speed_key = cfg.PILOT_SPEED_KEY or _measured_speed_key(V)
    try:
        pilot = load_pilot(path, backend=cfg.PILOT_BACKEND, speed_control=speed_control, speed_key=speed_key,
                           onnx_threads=cfg.PILOT_ONNX_THREADS, models_dir=cfg.path("MODELS_PATH"))
    except (ValueError, ImportError, OSError) as exc:
        raise UserError(f"cannot drive with {path}: {exc}") from exc
    V.add(PilotCondition(), inputs=["user/mode"], outputs=["run_pilot"])
    if "pilot/model_request" not in V.mem:
        V.mem["pilot/model_request"] = None  # seeded: the web page's model picker may be absent
    V.add(ModelSwitch(pilot), inputs=["pilot/model_request"], outputs=["pilot/model"])
    if speed_control is not None and SPEED_LIMIT_KEY not in V.mem:
        V.mem[SPEED_LIMIT_KEY] = None  # seeded for cars without a web page; PILOT_SPEED_LIMIT applies
    pilot.lock_inputs = True  # the vehicle's wiring is fixed from here on
    V.add(pilot, inputs=pilot.inputs, outputs=list(pilot.outputs), run_condition="run_pilot")
    return pilot


def _measured_speed_key(V: Any) -> str:
    """sim/speed when a part of ``V`` produces it (the simulator), else enc/speed (an encoder)."""
    produced = {key for entry in getattr(V, "parts", ()) for key in getattr(entry, "outputs", ())}
    return "sim/speed" if "sim/speed" in produced else "enc/speed"
