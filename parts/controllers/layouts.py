"""Controller layouts as data: which kernel code is which stick/button, and which action each drives.

A layout is a JSON file (built-ins in ``parts/controllers/layouts/``; ``vehicle createjs`` writes
custom ones)::

    {"name": "ps4", "backend": "linux", "device_names": ["Wireless Controller"],
     "axis_codes": [0, 1, 2, 3, 4, 5, 16, 17],          # index -> ABS code when ioctls fail
     "button_codes": ["0x130", "0x131", ...],            # index -> BTN code when ioctls fail
     "axes": {"left_stick_x": {"code": 0}, "l2": {"code": 2, "type": "trigger"}},
     "buttons": {"cross": "0x130", "dpad_up": {"axis": 17, "direction": -1}},
     "bindings": {"steering": "left_stick_x", "throttle": "right_stick_y", "estop": "cross"}}

Codes are kernel ABS/BTN codes for the ``linux`` backend and SDL indices for ``pygame``. A
"button" may be half of an axis (a D-pad hat, a trigger): pressed past half travel.
"""

from __future__ import annotations

import difflib
import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from parts.controllers.events import Caps, parse_code
from vehicle.errors import VehicleError

LAYOUTS_DIR = Path(__file__).with_name("layouts")

#: actions bound to an axis
AXIS_ACTIONS = ("steering", "throttle", "throttle_forward", "throttle_reverse")
#: actions bound to a button (or half an axis), fired on press
BUTTON_ACTIONS = ("mode_toggle", "record_toggle", "erase_records", "estop", "throttle_up",
                  "throttle_down", "constant_throttle", "behavior_next", "behavior_prev")
ACTIONS = AXIS_ACTIONS + BUTTON_ACTIONS

#: CONTROLLER_TYPE aliases (DonkeyCar names) -> built-in layout file stem
ALIASES = {"xbox_one": "xbox", "xbox_usb": "xbox", "xboxone": "xbox", "xbox_one_bt": "xbox_bt",
           "f710": "f710", "ps3": "ps3", "ps4": "ps4", "generic": "generic", "default": "generic",
           "pygame": "pygame"}


class LayoutError(VehicleError, ValueError):
    """A layout file is missing, unreadable or inconsistent."""


@dataclass(frozen=True)
class AxisControl:
    """An analog axis: kernel code, whether it is a trigger (rests at one end), inverted or not."""

    code: int
    trigger: bool = False
    invert: bool = False


@dataclass(frozen=True)
class ButtonControl:
    """A button (``axis`` False) or half an axis pressed past half travel in ``direction`` (+1/-1)."""

    code: int
    axis: bool = False
    direction: int = 1


@dataclass(frozen=True)
class Layout:
    """One controller layout: controls by name, and the action -> control bindings."""

    name: str
    backend: str = "linux"
    description: str = ""
    device_names: tuple[str, ...] = ()
    caps: Caps = field(default_factory=lambda: Caps("gamepad"))
    axes: dict[str, AxisControl] = field(default_factory=dict)
    buttons: dict[str, ButtonControl] = field(default_factory=dict)
    bindings: dict[str, str] = field(default_factory=dict)

    def with_bindings(self, overrides: dict[str, str | None]) -> Layout:
        """A copy with some bindings changed (a None or "" value unbinds the action)."""
        merged = dict(self.bindings)
        for action, control in overrides.items():
            if control:
                merged[action] = control
            else:
                merged.pop(action, None)
        out = replace(self, bindings=merged)
        out.validate()
        return out

    def validate(self) -> None:
        """Raise LayoutError if a binding names an unknown action or a control of the wrong kind."""
        where = f"layout {self.name!r}"
        if self.backend not in ("linux", "pygame"):
            raise LayoutError(f"{where}: backend {self.backend!r} must be 'linux' or 'pygame'")
        for action, control in self.bindings.items():
            if action not in ACTIONS:
                close = difflib.get_close_matches(action, ACTIONS, n=1)
                hint = f" Did you mean {close[0]!r}?" if close else ""
                raise LayoutError(f"{where}: unknown action {action!r}.{hint} Actions: {', '.join(ACTIONS)}")
            if action in AXIS_ACTIONS:
                if control not in self.axes:
                    raise LayoutError(f"{where}: {action} is bound to {control!r}, which is not an axis "
                                      f"of this layout; axes: {', '.join(sorted(self.axes))}")
            elif control not in self.buttons:
                raise LayoutError(f"{where}: {action} is bound to {control!r}, which is not a button "
                                  f"of this layout; buttons: {', '.join(sorted(self.buttons))}")
        if self.bindings.get("steering") and self.axes[self.bindings["steering"]].trigger:
            raise LayoutError(f"{where}: steering is bound to the trigger {self.bindings['steering']!r}; "
                              "bind it to a stick axis")
        if "estop" not in self.bindings:
            raise LayoutError(f"{where}: no button is bound to estop; every layout needs an emergency stop")

    def to_json(self) -> dict[str, Any]:
        """The layout as the JSON object :func:`load_layout` reads."""
        def button(b: ButtonControl) -> Any:
            return {"axis": b.code, "direction": b.direction} if b.axis else hex(b.code)

        return {
            "name": self.name, "backend": self.backend, "description": self.description,
            "device_names": list(self.device_names),
            "axis_codes": list(self.caps.axis_codes),
            "button_codes": [hex(c) for c in self.caps.button_codes],
            "axes": {n: {"code": a.code, "type": "trigger" if a.trigger else "stick",
                         **({"invert": True} if a.invert else {})} for n, a in self.axes.items()},
            "buttons": {n: button(b) for n, b in self.buttons.items()},
            "bindings": dict(self.bindings),
        }


def layout_from_json(data: dict[str, Any], source: str = "layout") -> Layout:
    """Build and validate a Layout from its JSON object; errors name ``source`` and the field."""
    if not isinstance(data, dict):
        raise LayoutError(f"{source}: expected a JSON object, got {type(data).__name__}")
    try:
        name = str(data.get("name") or Path(source).stem)
        axes = {}
        for ctl, spec in dict(data.get("axes", {})).items():
            spec = spec if isinstance(spec, dict) else {"code": spec}
            kind = spec.get("type", "stick")
            if kind not in ("stick", "trigger"):
                raise LayoutError(f"{source}: axis {ctl!r} has type {kind!r}; use 'stick' or 'trigger'")
            axes[ctl] = AxisControl(parse_code(spec["code"]), kind == "trigger",
                                    bool(spec.get("invert", False)))
        buttons = {}
        for ctl, spec in dict(data.get("buttons", {})).items():
            if isinstance(spec, dict):
                direction = int(spec.get("direction", 1))
                if direction not in (-1, 1):
                    raise LayoutError(f"{source}: button {ctl!r} direction must be -1 or 1")
                buttons[ctl] = ButtonControl(parse_code(spec["axis"]), True, direction)
            else:
                buttons[ctl] = ButtonControl(parse_code(spec))
        caps = Caps(name, tuple(parse_code(c) for c in data.get("axis_codes", [])),
                    tuple(parse_code(c) for c in data.get("button_codes", [])))
        bindings = {str(k): str(v) for k, v in dict(data.get("bindings", {})).items() if v}
        layout = Layout(name=name, backend=str(data.get("backend", "linux")),
                        description=str(data.get("description", "")),
                        device_names=tuple(data.get("device_names", [])), caps=caps,
                        axes=axes, buttons=buttons, bindings=bindings)
    except LayoutError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise LayoutError(f"{source}: invalid layout ({type(exc).__name__}: {exc})") from exc
    layout.validate()
    return layout


def builtin_layouts() -> list[str]:
    """Names of the layouts shipped with the package."""
    return sorted(p.stem for p in LAYOUTS_DIR.glob("*.json"))


def load_layout(name_or_path: str | Path) -> Layout:
    """Load a built-in layout by name (``ps4``, ``xbox``, ...) or a layout JSON file by path."""
    text = str(name_or_path)
    if text.endswith(".json") or "/" in text or isinstance(name_or_path, Path):
        path = Path(text).expanduser()
        if not path.is_file():
            raise LayoutError(f"no controller mapping file at {path}; create one with `vehicle createjs` "
                              "or fix JOYSTICK_MAPPING_PATH")
    else:
        stem = ALIASES.get(text.lower(), text.lower())
        path = LAYOUTS_DIR / f"{stem}.json"
        if not path.is_file():
            known = builtin_layouts()
            close = difflib.get_close_matches(text.lower(), known + list(ALIASES), n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise LayoutError(f"unknown controller type {text!r}.{hint} Built-in: {', '.join(known)}, "
                              "or 'custom' with JOYSTICK_MAPPING_PATH")
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise LayoutError(f"{path}: cannot read the controller mapping ({exc})") from exc
    return layout_from_json(data, str(path))
