"""The web controller's message protocol: what a browser may send, validated before it is used.

Every message from a browser goes through one of the ``parse_*`` functions here. They return plain,
range-checked values or raise :class:`ProtocolError` with a message saying what was wrong, so a
malformed or out-of-range message never reaches the control state (and so never the actuators).

Client → server events (all payloads are JSON objects):

``drive``         ``{"angle": float in [-1, 1], "throttle": float in [-1, 1]}`` — also the dead-man
                  heartbeat: the driving page sends it continuously (every 50 ms).
``set``           any subset of ``{"mode", "recording", "max_throttle", "constant_throttle",
                  "speed_limit", "model"}`` (see :func:`parse_settings`).
``estop``         ``{"on": bool}`` — latch or release the emergency stop.
``take_control``  no payload — this browser becomes the driver.
``models``        no payload — list the model files again.
``behavior``      ``{"step": 1 | -1}`` — select the next / previous behaviour (e.g. change lane).
``path_command``  ``{"command": "record" | "save" | "load" | "clear" | "reset_origin"}`` — a path
                  button (path follow): handed to the loop once, as ``web/path_command``.

Each handler answers with an acknowledgement ``{"ok": true}`` or ``{"ok": false, "error": "..."}``.
"""

from __future__ import annotations

import math
from typing import Any, Final

from parts.web.pathview import PATH_COMMANDS
from vehicle.keys import MODES

#: drive modes, DonkeyCar's names: human drives, pilot steers, pilot drives.
#: what the page shows for each mode
MODE_LABELS: Final = {"user": "User", "local_angle": "Auto steer", "local": "Full auto"}
#: largest message a browser may send, bytes of JSON (a drive message is ~40 bytes)
MAX_MESSAGE_BYTES: Final = 4096
#: keys of a ``set`` message
SETTING_KEYS: Final = ("mode", "recording", "max_throttle", "constant_throttle", "speed_limit", "model")


class ProtocolError(ValueError):
    """A message from a browser is malformed or out of range; the text says what and why."""


def short(value: Any, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters: an error reply never echoes a huge value."""
    text = repr(value) if not isinstance(value, int) or abs(value) < 10**30 else f"<{value.bit_length()}-bit int>"
    return text if len(text) <= limit else text[:limit] + "..."


def _require_object(payload: Any, event: str) -> dict[str, Any]:
    if not isinstance(payload, dict):
        raise ProtocolError(f"{event}: expected a JSON object, got {type(payload).__name__}")
    return payload


def _number(payload: dict[str, Any], key: str, event: str, low: float, high: float) -> float:
    if key not in payload:
        raise ProtocolError(f"{event}: missing {key!r}")
    value = payload[key]
    # bool is an int in Python; a browser sending true for a throttle is a bug, not 1.0
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ProtocolError(f"{event}: {key} must be a number, got {type(value).__name__}")
    try:
        value = float(value)
    except OverflowError:  # an int too large for a float (10**400)
        raise ProtocolError(f"{event}: {key}={short(value)} is outside [{low:g}, {high:g}]") from None
    if not math.isfinite(value) or not low <= value <= high:
        raise ProtocolError(f"{event}: {key}={value!r} is outside [{low:g}, {high:g}]")
    return value


def _bool(payload: dict[str, Any], key: str, event: str) -> bool:
    value = payload[key]
    if not isinstance(value, bool):
        raise ProtocolError(f"{event}: {key} must be true or false, got {short(value)}")
    return value


def _no_extra(payload: dict[str, Any], allowed: tuple[str, ...], event: str) -> None:
    extra = sorted(set(payload) - set(allowed))
    if extra:
        raise ProtocolError(f"{event}: unknown field(s) {', '.join(map(short, extra[:3]))}; "
                            f"allowed: {', '.join(allowed)}")


def parse_drive(payload: Any) -> tuple[float, float]:
    """Validate a ``drive`` message and return ``(angle, throttle)``, each in [-1, 1]."""
    msg = _require_object(payload, "drive")
    _no_extra(msg, ("angle", "throttle"), "drive")
    return _number(msg, "angle", "drive", -1.0, 1.0), _number(msg, "throttle", "drive", -1.0, 1.0)


def parse_settings(payload: Any, *, models: list[str], max_speed_limit: float) -> dict[str, Any]:
    """Validate a ``set`` message; return only the fields it contains, checked.

    Args:
        payload: the message.
        models: the model file names the browser may pick (the car's models folder).
        max_speed_limit: largest accepted speed limit, m/s.

    Fields: ``mode`` one of :data:`MODES`; ``recording`` and ``constant_throttle`` booleans;
    ``max_throttle`` in [0, 1]; ``speed_limit`` in (0, max_speed_limit] m/s or null (no limit);
    ``model`` the name of a file in ``models`` (a name, never a path).
    """
    msg = _require_object(payload, "set")
    _no_extra(msg, SETTING_KEYS, "set")
    if not msg:
        raise ProtocolError(f"set: empty message; send one or more of {', '.join(SETTING_KEYS)}")
    out: dict[str, Any] = {}
    if "mode" in msg:
        if msg["mode"] not in MODES:
            raise ProtocolError(f"set: mode={short(msg['mode'])} is not one of {', '.join(MODES)}")
        out["mode"] = msg["mode"]
    for key in ("recording", "constant_throttle"):
        if key in msg:
            out[key] = _bool(msg, key, "set")
    if "max_throttle" in msg:
        out["max_throttle"] = _number(msg, "max_throttle", "set", 0.0, 1.0)
    if "speed_limit" in msg:
        if msg["speed_limit"] is None:
            out["speed_limit"] = None
        else:
            limit = _number(msg, "speed_limit", "set", 0.0, max_speed_limit)
            if limit <= 0.0:
                raise ProtocolError("set: speed_limit must be above 0 m/s (send null for no limit)")
            out["speed_limit"] = limit
    if "model" in msg:
        name = msg["model"]
        if not isinstance(name, str) or name not in models:
            raise ProtocolError(f"set: model={short(name)} is not a file of the models folder; "
                                f"choose one of: {', '.join(models) or '(none found)'}")
        out["model"] = name
    return out


def parse_estop(payload: Any) -> bool:
    """Validate an ``estop`` message; return True to latch the emergency stop, False to release."""
    msg = _require_object(payload, "estop")
    _no_extra(msg, ("on",), "estop")
    if "on" not in msg:
        raise ProtocolError("estop: missing 'on' (true latches the stop, false releases it)")
    return _bool(msg, "on", "estop")


def parse_behavior(payload: Any) -> int:
    """Validate a ``behavior`` message; return the step: +1 (next behaviour) or -1 (previous)."""
    msg = _require_object(payload, "behavior")
    _no_extra(msg, ("step",), "behavior")
    step = msg.get("step")
    if isinstance(step, bool) or step not in (1, -1):
        raise ProtocolError(f"behavior: step must be 1 (next) or -1 (previous), got {short(step)}")
    return int(step)


def parse_path_command(payload: Any) -> str:
    """Validate a ``path_command`` message; return the command, one of :data:`PATH_COMMANDS`."""
    msg = _require_object(payload, "path_command")
    _no_extra(msg, ("command",), "path_command")
    command = msg.get("command")
    if not isinstance(command, str) or command not in PATH_COMMANDS:
        raise ProtocolError(f"path_command: command={short(command)} is not one of {', '.join(PATH_COMMANDS)}")
    return command
