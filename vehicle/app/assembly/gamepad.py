"""Assembly of the gamepad: layout from CONTROLLER_TYPE, reader, and the threaded Gamepad part."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def load_gamepad_layout(cfg: Config) -> Any:
    """The layout for CONTROLLER_TYPE ("custom": JOYSTICK_MAPPING_PATH) with JOYSTICK_BINDINGS applied."""
    from parts.controllers.layouts import LayoutError, load_layout

    try:
        if cfg.CONTROLLER_TYPE == "custom":
            layout = load_layout(cfg.path("JOYSTICK_MAPPING_PATH"))
        else:
            layout = load_layout(cfg.CONTROLLER_TYPE)
        if cfg.JOYSTICK_BINDINGS:
            layout = layout.with_bindings(cfg.JOYSTICK_BINDINGS)
    except LayoutError as exc:
        raise UserError(f"{exc} (CONTROLLER_TYPE = {cfg.CONTROLLER_TYPE!r})") from exc
    return layout


def make_reader(cfg: Config, layout: Any) -> Any:
    """The device reader for the layout's backend."""
    if layout.backend == "pygame":
        from parts.controllers.pygame_js import PygameJoystick

        return PygameJoystick(cfg.JOYSTICK_INDEX)
    from parts.controllers.linux_js import LinuxJoystick

    return LinuxJoystick(str(cfg.path("JOYSTICK_DEVICE_FILE")), fallback_caps=layout.caps)


def gamepad_settings(cfg: Config) -> Any:
    """GamepadSettings from the JOYSTICK_* settings."""
    from parts.controllers.logic import GamepadSettings

    try:
        return GamepadSettings(max_throttle=cfg.JOYSTICK_MAX_THROTTLE, steering_scale=cfg.JOYSTICK_STEERING_SCALE,
                               throttle_dir=cfg.JOYSTICK_THROTTLE_DIR, deadzone=cfg.JOYSTICK_DEADZONE,
                               auto_record_on_throttle=cfg.AUTO_RECORD_ON_THROTTLE,
                               throttle_step=cfg.JOYSTICK_THROTTLE_STEP,
                               silence_timeout_s=cfg.JOYSTICK_SILENCE_TIMEOUT_S, initial_mode=cfg.DEFAULT_MODE)
    except ValueError as exc:
        raise UserError(str(exc)) from exc


def add_gamepad(V: Any, cfg: Config, outputs: Sequence[str] | None = None) -> Any:
    """Add the gamepad (threaded) -> ``user/angle, user/throttle, user/mode, recording, estop,
    tub/erase, behavior/step``.

    ``outputs`` renames the keys (same order; see :func:`vehicle.keys.rename`), e.g. ``js/angle``
    ... when a controller arbiter combines the gamepad with the web page. The pad may be absent
    at start: it is opened again every JOYSTICK_RETRY_S and gives throttle 0 and user mode
    meanwhile.
    """
    from parts.controllers.gamepad import Gamepad, GamepadStatus

    if outputs is not None and len(outputs) != len(Gamepad.OUTPUTS):
        raise ValueError(f"add_gamepad outputs needs {len(Gamepad.OUTPUTS)} keys in the order "
                         f"{list(Gamepad.OUTPUTS)}, got {list(outputs)}")
    layout = load_gamepad_layout(cfg)
    part = Gamepad(make_reader(cfg, layout), layout, gamepad_settings(cfg), retry_s=cfg.JOYSTICK_RETRY_S)
    V.add(part, outputs=outputs, threaded=True)
    V.add(GamepadStatus(part))  # js/status: the web page shows whether the car's pad is there
    logger.info("gamepad: %s layout on %s", layout.name, part.reader.path)
    return part
