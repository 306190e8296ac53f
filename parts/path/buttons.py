"""Path commands from the gamepad's buttons and the driver page's buttons -> ``path/command``."""

from __future__ import annotations

import logging
from typing import Any, ClassVar

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

class PathButtonError(VehicleError):
    """A path button setting names a button the gamepad does not have."""


#: the pad's own actions a path button may share in a path-follow car (no tub, no behaviours)
HARMLESS = ("record_toggle", "erase_records", "behavior_next", "behavior_prev")
#: command -> the setting naming its button (DonkeyCar's names)
BUTTON_SETTINGS: dict[str, str] = {"record": "TOGGLE_RECORDING_BTN", "save": "SAVE_PATH_BTN",
                                   "load": "LOAD_PATH_BTN", "clear": "ERASE_PATH_BTN",
                                   "reset_origin": "RESET_ORIGIN_BTN"}
#: a PS-style face button -> its position, and the names other pads give that position
POSITIONS: dict[str, str] = {"cross": "south", "x": "south", "circle": "east", "square": "west", "triangle": "north"}
POSITION_NAMES: dict[str, tuple[str, ...]] = {"south": ("cross", "a", "south"), "east": ("circle", "b", "east"),
                                              "west": ("square", "x", "west"), "north": ("triangle", "y", "north")}


def resolve_button(name: str, buttons: set[str], setting: str) -> str:
    """The layout's name for button ``name``: itself when the layout has it, else the button at the same
    position (a PS pad's "square" is an Xbox pad's "x").

    Raises:
        PathButtonError: the layout has no such button (the message names the setting and the buttons).
    """
    if name in buttons:
        return name
    position = POSITIONS.get(name.lower(), name.lower())
    for candidate in POSITION_NAMES.get(position, ()):
        if candidate in buttons:
            return candidate
    raise PathButtonError(f"{setting} = {name!r}: this gamepad has no such button; use one of "
                          f"{', '.join(sorted(buttons))} or None")


class PathCommands:
    """Part: ``path/command`` for this loop, from a gamepad's button presses (each press counts
    once, however short) or else the driver page's ``web/path_command``.

    Args:
        pad: the :class:`parts.controllers.gamepad.Gamepad` (its ``presses()``), or None.
        buttons: command -> button name of the pad's layout (see :func:`resolve_button`).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("web/path_command",)
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("web/path_command",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("path/command",)

    def __init__(self, pad: Any = None, buttons: dict[str, str] | None = None) -> None:
        self.pad = pad
        self.buttons = dict(buttons or {})
        self._seen: dict[str, int] = dict(pad.presses()) if pad is not None else {}
        self._queue: list[str] = []

    @classmethod
    def from_config(cls, cfg: Any, pad: Any = None) -> PathCommands:
        """The *_BTN settings, resolved against the pad's layout."""
        buttons: dict[str, str] = {}
        if pad is not None:
            names = set(pad.layout.buttons)
            bound = {control: action for action, control in pad.layout.bindings.items()}
            for command, setting in BUTTON_SETTINGS.items():
                if cfg[setting]:
                    button = resolve_button(cfg[setting], names, setting)
                    buttons[command] = button
                    if button in bound and bound[button] not in HARMLESS:
                        logger.warning("%s = %r also does the pad's %s", setting, button, bound[button])
        return cls(pad, buttons)

    def run(self, web_command: str | None) -> str | None:
        """One command per loop: the pad's presses in order, then the page's."""
        if self.pad is not None:
            counts = self.pad.presses()
            for command, button in self.buttons.items():
                new = counts.get(button, 0) - self._seen.get(button, 0)
                self._queue += [command] * max(0, new)
            self._seen = counts
        if web_command:
            self._queue.append(web_command)
        return self._queue.pop(0) if self._queue else None
