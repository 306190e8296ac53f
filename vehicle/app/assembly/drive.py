"""Assembly of the drive logic: drive mode, behaviour state, camera watchdog, throttle filter, recording rules."""

from __future__ import annotations

import logging
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError
from vehicle.keys import rename

logger = logging.getLogger(__name__)


def add_drive_mode(V: Any, cfg: Config) -> Any:
    """Add DriveMode: ``user/*`` and ``pilot/*`` commands -> ``angle``, ``throttle``; with
    CORRECTION_MODE the person's stick overrides the pilot while moved (:mod:`parts.drive.correction`).

    Add it after the controller (and the pilot, when there is one): it reads their commands of
    this loop. A car without a pilot or an e-stop button reads None there (no pilot command, no
    stop), as DriveMode's declaration says. The speed limit and the obstacle stop, which act on its
    ``throttle``, are added right after it by name (:func:`add_speed_limit`, :func:`add_obstacle_stop`).
    """
    from parts.drive.modes import DriveMode

    part = DriveMode(ai_throttle_mult=cfg.AI_THROTTLE_MULT)
    V.add(part)
    if getattr(cfg, "CORRECTION_MODE", False):
        from parts.drive.correction import Correction

        # before the speed limit and the obstacle stop: they act on the person's override too
        V.add(Correction(cfg.CORRECTION_DEADZONE))
    return part


def add_speed_limit(V: Any, cfg: Config) -> Any:
    """Add SpeedLimit after the drive mode: ``throttle`` capped so that the measured speed stays
    under ``user/speed_limit`` (the web page's limit), in every mode. Returns None (and adds
    nothing) when no part sets a limit or none measures the speed: the page then says that the
    limit is not available."""
    from parts.drive.speed import SpeedLimit
    from vehicle.app.assembly.pilot import speed_key_of

    speed_key = speed_key_of(V, cfg)
    if not V.produces("user/speed_limit") or not V.produces(speed_key) or V.find(SpeedLimit):
        return None
    part = SpeedLimit(dt=1.0 / cfg.DRIVE_LOOP_HZ, kp=cfg.PILOT_SPEED_KP, ki=cfg.PILOT_SPEED_KI)
    V.add(part, inputs=rename(SpeedLimit.INPUTS, {"sim/speed": speed_key}))
    return part


def add_obstacle_stop(V: Any, cfg: Config) -> Any:
    """Add ObstacleStop after the drive mode and speed limit (OBSTACLE_STOP): the final
    ``throttle`` is cut to a brake while the LiDAR sees something too close ahead, in every mode.
    Returns None (adds nothing) when OBSTACLE_STOP is off or the car has one already.

    Raises:
        UserError: OBSTACLE_STOP is on but no part writes ``lidar/dist_array`` (no USE_LIDAR).
    """
    from parts.drive.obstacle import ObstacleStop

    if not cfg.OBSTACLE_STOP or V.find(ObstacleStop):
        return None
    if not V.produces("lidar/dist_array"):
        raise UserError(f"{cfg.where('OBSTACLE_STOP')}OBSTACLE_STOP needs a LiDAR: set USE_LIDAR = True "
                        "(in a simulator car the simulated LiDAR is used), or OBSTACLE_STOP = False")
    part = ObstacleStop.from_config(cfg)
    V.add(part)
    return part


def add_camera_watchdog(V: Any, cfg: Config) -> Any:
    """Add the CameraWatchdog after the controller: ``cam/ok`` False in a pilot mode -> ``user/mode``
    'user' and ``user/throttle`` 0. Returns None (and adds nothing) when no part produces
    ``cam/ok`` (no camera part, e.g. the simulator) or the vehicle has a watchdog already.
    """
    from parts.drive.safety import CameraWatchdog

    if not V.produces("cam/ok") or V.find(CameraWatchdog):
        return None
    part = CameraWatchdog()
    V.add(part)
    return part


def add_behavior(V: Any, cfg: Config) -> Any:
    """Add the behaviour state (with TRAIN_BEHAVIORS): ``behavior/step`` (gamepad) and, when the web
    page was added before, ``web/behavior_step`` -> ``behavior/state, behavior/label,
    behavior/one_hot_state_array``. Returns the BehaviorState part, or None when TRAIN_BEHAVIORS
    is off.
    """
    from parts.drive.behavior import BehaviorState

    if not cfg.TRAIN_BEHAVIORS:
        return None
    try:
        part = BehaviorState(cfg.BEHAVIOR_LIST, cfg.BEHAVIOR_INITIAL)
    except (TypeError, ValueError) as exc:
        raise UserError(f"{exc} (check BEHAVIOR_LIST and BEHAVIOR_INITIAL in myconfig.py)") from exc
    V.add(part)  # the gamepad's behavior/step and the web page's web/behavior_step, when present
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
    V.add(part)
    return part


def add_recording_rules(V: Any, cfg: Config) -> Any:
    """Add the recording rules: ``user/mode, recording, throttle, estop`` -> ``recording``
    (AUTO_RECORD_ON_THROTTLE, RECORD_DURING_AI, e-stop stops recording)."""
    from parts.drive.recording import RecordingRules

    part = RecordingRules(cfg.AUTO_RECORD_ON_THROTTLE, cfg.RECORD_DURING_AI, cfg.JOYSTICK_DEADZONE)
    V.add(part)
    return part
