"""Assembly of the drive-mode part: the final steering and throttle commands."""

from __future__ import annotations

from typing import Any

from vehicle.config import Config


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
