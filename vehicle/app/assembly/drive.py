"""Assembly of the drive logic: drive mode, behaviour state, camera watchdog, throttle filter, recording rules."""

from __future__ import annotations

import logging
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def _has_part(V: Any, cls: type) -> bool:
    return any(isinstance(getattr(entry, "part", None), cls) for entry in getattr(V, "parts", ()))


def add_drive_mode(V: Any, cfg: Config) -> Any:
    """Add DriveMode: ``user/*`` and ``pilot/*`` commands -> ``angle``, ``throttle``.

    Seeds ``user/mode`` with DEFAULT_MODE so a car without a mode selector still has one.
    """
    from parts.drive.modes import DriveMode

    if "user/mode" not in V.mem:
        V.mem["user/mode"] = cfg.DEFAULT_MODE
    for key in ("pilot/angle", "pilot/throttle", "estop"):
        if key not in V.mem:
            V.mem[key] = None  # seeded: a car may have no pilot or no emergency stop button
    part = DriveMode(ai_throttle_mult=cfg.AI_THROTTLE_MULT)
    V.add(part, inputs=["user/mode", "user/angle", "user/throttle", "pilot/angle", "pilot/throttle",
                        "estop"],
          outputs=["angle", "throttle"])
    return part


def add_camera_watchdog(V: Any, cfg: Config) -> Any:
    """Add the CameraWatchdog after the controller: ``cam/ok`` False in a pilot mode -> ``user/mode``
    'user' and ``user/throttle`` 0. Returns None (and adds nothing) when the car has no camera
    (``cam/ok`` not in memory, e.g. the simulator) or the watchdog is already there.
    """
    from parts.drive.safety import CameraWatchdog

    if "cam/ok" not in V.mem or _has_part(V, CameraWatchdog):
        return None
    part = CameraWatchdog()
    V.add(part, inputs=["cam/ok", "user/mode", "user/throttle"], outputs=["user/mode", "user/throttle"])
    return part


def add_behavior(V: Any, cfg: Config) -> Any:
    """Add the behaviour state (with TRAIN_BEHAVIORS): ``behavior/step`` -> ``behavior/state,
    behavior/label, behavior/one_hot_state_array``. Returns the BehaviorState part, or None when
    TRAIN_BEHAVIORS is off.
    """
    from parts.drive.behavior import BehaviorState

    if not cfg.TRAIN_BEHAVIORS:
        return None
    try:
        part = BehaviorState(cfg.BEHAVIOR_LIST, cfg.BEHAVIOR_INITIAL)
    except (TypeError, ValueError) as exc:
        raise UserError(f"{exc} (check BEHAVIOR_LIST and BEHAVIOR_INITIAL in myconfig.py)") from exc
    if "behavior/step" not in V.mem:
        V.mem["behavior/step"] = 0  # seeded: a car without a gamepad has no behaviour buttons
    V.add(part, inputs=["behavior/step"],
          outputs=["behavior/state", "behavior/label", "behavior/one_hot_state_array"])
    return part


def add_throttle_filter(V: Any, cfg: Config) -> Any:
    """Add DonkeyCar's ThrottleFilter on ``throttle`` (USE_THROTTLE_FILTER). Returns None when it is
    off or when the drivetrain does the double tap itself (ESC_REVERSE_MODE = "double_tap").
    """
    from parts.drive.throttle_filter import ThrottleFilter

    if not cfg.USE_THROTTLE_FILTER:
        return None
    if getattr(cfg, "ESC_REVERSE_MODE", "direct") == "double_tap":
        logger.info("throttle filter skipped: ESC_REVERSE_MODE = 'double_tap' does the reverse sequence")
        return None
    part = ThrottleFilter()
    V.add(part, inputs=["throttle"], outputs=["throttle"])
    return part


def add_recording_rules(V: Any, cfg: Config) -> Any:
    """Add the recording rules: ``user/mode, recording, throttle, estop`` -> ``recording``
    (AUTO_RECORD_ON_THROTTLE, RECORD_DURING_AI, e-stop stops recording)."""
    from parts.drive.recording import RecordingRules

    for key, value in (("recording", False), ("estop", None), ("user/mode", cfg.DEFAULT_MODE)):
        if key not in V.mem:
            V.mem[key] = value  # seeded: a car may have no record button or e-stop
    part = RecordingRules(cfg.AUTO_RECORD_ON_THROTTLE, cfg.RECORD_DURING_AI, cfg.JOYSTICK_DEADZONE)
    V.add(part, inputs=["user/mode", "recording", "throttle", "estop"], outputs=["recording"])
    return part
