"""Assembly of the human controllers: the web page, a gamepad, or both with arbitration."""

from __future__ import annotations

import functools
import logging
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError
from vehicle.keys import rename

logger = logging.getLogger(__name__)

#: with a gamepad too, each controller writes its own keys and the arbiter merges them into user/*
TO_WEB_KEYS = {"user/angle": "web/angle", "user/throttle": "web/throttle", "user/mode": "web/mode",
               "recording": "web/recording", "estop": "web/estop"}
TO_GAMEPAD_KEYS = {"user/angle": "js/angle", "user/throttle": "js/throttle", "user/mode": "js/mode",
                   "recording": "js/recording", "estop": "js/estop"}


def add_controller(V: Any, cfg: Config) -> Any:
    """Add the human controller(s) and return the main one.

    - ``USE_WEB_CONTROLLER`` (default True): the web page (:class:`parts.web.controller.WebController`,
      threaded) on ``WEB_HOST:WEB_CONTROL_PORT``; outputs ``user/angle, user/throttle, user/mode,
      recording, estop, user/speed_limit, pilot/model_request``.
    - ``USE_JOYSTICK_AS_DEFAULT``: the gamepad (``vehicle.app.assembly.gamepad.add_gamepad``).
    - both: the page writes ``web/*`` keys, the gamepad ``js/*`` keys, and a
      :class:`parts.web.arbiter.ControllerArbiter` merges them into the ``user/*`` keys, as
      ``CONTROLLER_PRIORITY`` says.

    Returns the web controller when there is one (its ``url`` is the page), else the gamepad.

    Raises:
        UserError: both controllers are switched off.
    """
    use_web = bool(cfg.USE_WEB_CONTROLLER)
    use_pad = bool(cfg.get("USE_JOYSTICK_AS_DEFAULT", False))
    if not use_web and not use_pad:
        raise UserError("no controller: set USE_WEB_CONTROLLER = True (web page) or "
                        "USE_JOYSTICK_AS_DEFAULT = True (gamepad) in myconfig.py")
    web = None
    if use_web:
        from parts.web.controller import WebController

        web = WebController.from_config(cfg)
        if web.link is not None:  # a model pushed from the laptop is checked as `drive --model` checks it
            from vehicle.app.assembly.pilot import check_model_file

            web.link.check_model = functools.partial(check_model_file, V, cfg)
        # the page shows the effective mode/recording of the previous loop (declared FEEDBACK), so
        # it runs before the gamepad and the arbiter
        V.add(web, outputs=rename(WebController.OUTPUTS, TO_WEB_KEYS) if use_pad else None, threaded=True)
    if not use_pad:
        return web

    from parts.controllers.gamepad import Gamepad
    from vehicle.app.assembly.gamepad import add_gamepad

    pad = add_gamepad(V, cfg, outputs=rename(Gamepad.OUTPUTS, TO_GAMEPAD_KEYS) if web is not None else None)
    if web is None:
        return pad
    from parts.web.arbiter import ControllerArbiter

    V.add(ControllerArbiter(cfg.CONTROLLER_PRIORITY, initial_mode=cfg.DEFAULT_MODE))
    return web
