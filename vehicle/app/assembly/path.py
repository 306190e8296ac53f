"""Assembly of path follow: commands, localiser, path recorder and follower."""

from __future__ import annotations

import logging
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError

logger = logging.getLogger(__name__)

#: what each localiser needs a part to write
NEEDS = {"odometry": ("pos/x", "an encoder: HAVE_ODOM = True"),
         "gps": ("gps/x", "a GPS: HAVE_GPS = True"),
         "fused": ("gps/x", "a GPS and an encoder: HAVE_GPS = True and HAVE_ODOM = True")}


def add_path_follow(V: Any, cfg: Config, localizer: str | None = None) -> Any:
    """Add the path-follow parts after the controller and before drive mode, in this order:

    - :class:`parts.path.buttons.PathCommands`: the gamepad's path buttons (TOGGLE_RECORDING_BTN ...)
      and the page's ``web/path_command`` -> ``path/command``;
    - :class:`parts.path.localizer.Localizer` (PATH_LOCALIZER, or ``localizer``) -> ``loc/*``;
    - :class:`parts.path.recorder.PathRecorder` (PATH_FILENAME, PATH_MIN_DIST) -> ``path/xy`` ...;
    - :class:`parts.path.follower.PathFollower` -> ``pilot/angle, pilot/throttle``, ``path/state`` ...

    Returns the follower.

    Raises:
        UserError: the localiser's sensor is missing (the message names the setting).
    """
    from parts.controllers.gamepad import Gamepad
    from parts.path.buttons import PathCommands
    from parts.path.follower import PathFollower
    from parts.path.localizer import Localizer
    from parts.path.recorder import PathRecorder
    from vehicle.app.assembly.pilot import speed_key_of

    source = localizer or cfg.PATH_LOCALIZER
    for key, what in [NEEDS[source]] + ([NEEDS["odometry"]] if source == "fused" else []):
        if not V.produces(key):
            raise UserError(f"{cfg.where('PATH_LOCALIZER')}PATH_LOCALIZER = {source!r} needs {what} "
                            "(in the simulator its simulated sensors are used)")
    pads = V.find(Gamepad)
    V.add(PathCommands.from_config(cfg, pads[0] if pads else None))
    V.add(Localizer.from_config(cfg, source))
    speed_key = speed_key_of(V, cfg)
    V.add(PathRecorder.from_config(cfg), **speed_wiring(PathRecorder, speed_key))
    follower = PathFollower.from_config(cfg)
    V.add(follower, **speed_wiring(PathFollower, speed_key))
    logger.info("path follow: %s localiser, path file %s", source, cfg.path("PATH_FILENAME"))
    return follower


def speed_wiring(part: type, speed_key: str) -> dict[str, tuple[str, ...]]:
    """``V.add`` arguments reading the measured speed from ``speed_key`` instead of ``enc/speed``."""
    from vehicle.keys import rename

    mapping = {"enc/speed": speed_key} if speed_key != "enc/speed" else {}
    return {"inputs": rename(part.INPUTS, mapping), "optional_inputs": rename(part.OPTIONAL_INPUTS, mapping)}
