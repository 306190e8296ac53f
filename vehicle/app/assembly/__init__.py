"""Helpers that a car's manage.py calls to assemble its vehicle, one per concern.

Each helper takes the vehicle and the car's config, adds its part(s) with the standard memory
keys, and returns the main part it added, so a user can insert a part between two calls. Helpers
live in one module per concern and are imported on first use, so ``import vehicle.app.assembly``
loads no hardware library and no torch.
"""

from __future__ import annotations

import importlib
from typing import Any

# helper name -> module under vehicle.app.assembly that defines it
HELPERS: dict[str, str] = {
    "add_drive_mode": "drive",
    "add_speed_limit": "drive",
    "add_simulator": "sim",
    "sim_clock": "sim",
    "add_simulator_commands": "sim",
    "add_expert": "sim",
    "add_expert_noise": "sim",
    "add_camera": "camera",
    "add_undistort": "camera",
    "add_gamepad": "gamepad",
    "add_behavior": "drive",
    "add_camera_watchdog": "drive",
    "add_recording_rules": "drive",
    "add_throttle_filter": "drive",
    "add_controller": "controller",
    "add_drivetrain": "drivetrain",
    "add_sensors": "sensors",
    "add_odometry": "sensors",
    "add_obstacle_stop": "drive",
    "add_sim_sensors": "sim",
    "add_path_follow": "path",
    "add_pilot": "pilot",
    "add_tub_writer": "tub",
    "add_telemetry": "telemetry",
}

__all__ = sorted(HELPERS)


def __getattr__(name: str) -> Any:
    module = HELPERS.get(name)
    if module is None:
        raise AttributeError(f"vehicle.app.assembly has no helper {name!r}; helpers: {', '.join(__all__)}")
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)


def __dir__() -> list[str]:
    return __all__
