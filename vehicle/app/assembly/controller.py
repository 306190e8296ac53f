"""Assembly of the human controllers: the web page, a gamepad, or both with arbitration."""

from __future__ import annotations

import logging
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError

logger = logging.getLogger(__name__)

#: where the web page's commands go when a gamepad drives too (the arbiter merges them)
WEB_ARBITRATED_OUTPUTS = ("web/angle", "web/throttle", "web/mode", "web/recording", "web/estop",
                          "user/speed_limit", "pilot/model_request")


def add_controller(V: Any, cfg: Config) -> Any:
    """Add the human controller(s) and return the main one.

    - ``USE_WEB_CONTROLLER`` (default True): the web page (:class:`parts.web.controller.WebController`,
      threaded) on ``WEB_HOST:WEB_CONTROL_PORT``; outputs ``user/angle, user/throttle, user/mode,
      recording, estop, user/speed_limit, pilot/model_request``.
    - ``USE_JOYSTICK_AS_DEFAULT``: the gamepad (``vehicle.app.assembly.gamepad.add_gamepad``).
    - both: the page writes ``web/*`` keys and a :class:`parts.web.arbiter.ControllerArbiter`
      merges them with the gamepad's (``js/*``) into the ``user/*`` keys, as
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
        outputs = WEB_ARBITRATED_OUTPUTS if use_pad else WebController.OUTPUTS
        _seed(V, WebController.INPUTS, exclude=WebController.OUTPUTS)
        # the page reads the effective mode/recording of the previous loop, so it runs before the
        # gamepad and the arbiter
        V.add(web, inputs=list(WebController.INPUTS), outputs=list(outputs), threaded=True)
    if not use_pad:
        return web

    from parts.web.arbiter import ControllerArbiter
    from vehicle.app.assembly.gamepad import add_gamepad

    pad = add_gamepad(V, cfg, outputs=[*ControllerArbiter.INPUTS[:5], "tub/erase", "behavior/step"]
                      if web is not None else None)
    if web is None:
        return pad
    arbiter = ControllerArbiter(cfg.CONTROLLER_PRIORITY, initial_mode=cfg.DEFAULT_MODE)
    V.add(arbiter, inputs=list(ControllerArbiter.INPUTS), outputs=list(ControllerArbiter.OUTPUTS))
    return web


def _seed(V: Any, keys: tuple[str, ...], exclude: tuple[str, ...]) -> None:
    """Seed telemetry keys no part may produce (no pilot, no encoder...) with None."""
    for key in keys:
        if key not in exclude and not key.startswith("loop/") and key not in V.mem:
            V.mem[key] = None
