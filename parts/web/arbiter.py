"""ControllerArbiter: the web page and a physical gamepad drive the same car; one wins.

Inputs (in order): the gamepad's ``angle, throttle, mode, recording, estop`` then the web page's.
Outputs: ``user/angle, user/throttle, user/mode, recording, estop, controller/active``.

Rules:

- **Steering and throttle** come from one source per loop, chosen by ``priority``:
  ``"gamepad"`` — the gamepad whenever its stick is off centre, else the web page;
  ``"web"`` — the web page whenever its command is off centre, else the gamepad;
  ``"latest"`` — whichever source moved its stick most recently.
- **Mode and recording**: the latest change from either source wins (both can switch them).
- **Emergency stop**: latched if either source latched it (each releases only its own).
"""

from __future__ import annotations

import logging
from typing import Any, ClassVar, Final

from vehicle.keys import MODES

logger = logging.getLogger(__name__)

PRIORITIES: Final = ("gamepad", "web", "latest")
SOURCES: Final = ("gamepad", "web")


def _f(value: Any) -> float:
    try:
        return float(value) if value is not None else 0.0
    except (TypeError, ValueError):
        return 0.0


class ControllerArbiter:
    """Merge two controllers' commands into the ``user/*`` keys.

    Args:
        priority: ``"gamepad"``, ``"web"`` or ``"latest"`` (see the module docstring).
            Default ``"gamepad"``.
        deadzone: |angle| and |throttle| at or below this count as a centred stick. Default 0.02.
        initial_mode: mode until a source changes it. Default ``"user"``.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("js/angle", "js/throttle", "js/mode", "js/recording", "js/estop",
                                         "web/angle", "web/throttle", "web/mode", "web/recording", "web/estop")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/angle", "user/throttle", "user/mode", "recording", "estop",
                                          "controller/active")

    def __init__(self, priority: str = "gamepad", deadzone: float = 0.02,
                 initial_mode: str = "user") -> None:
        if priority not in PRIORITIES:
            raise ValueError(f"priority must be one of {', '.join(PRIORITIES)}, got {priority!r} "
                             "(setting CONTROLLER_PRIORITY)")
        if not 0.0 <= deadzone < 1.0:
            raise ValueError(f"deadzone must be in [0, 1), got {deadzone!r}")
        if initial_mode not in MODES:
            raise ValueError(f"initial_mode must be one of {MODES}, got {initial_mode!r}")
        self.name = "ControllerArbiter"
        self.priority, self.deadzone = priority, deadzone
        self.mode, self.recording = initial_mode, False
        self._seen: dict[str, dict[str, Any]] = {s: {} for s in SOURCES}
        self._last_moved: dict[str, int] = {s: -1 for s in SOURCES}  # loop of the last stick move
        self._prev_cmds: dict[str, tuple[float, float]] = {s: (0.0, 0.0) for s in SOURCES}
        self._active = "gamepad" if priority != "web" else "web"
        self._loop = 0

    def _moving(self, angle: float, throttle: float) -> bool:
        return abs(angle) > self.deadzone or abs(throttle) > self.deadzone

    def run(self, pad_angle: Any, pad_throttle: Any, pad_mode: Any, pad_recording: Any,
            pad_estop: Any, web_angle: Any, web_throttle: Any, web_mode: Any,
            web_recording: Any, web_estop: Any) -> tuple[float, float, str, bool, bool, str]:
        """One loop: ``(angle, throttle, mode, recording, estop, active source)``."""
        self._loop += 1
        cmds = {"gamepad": (_f(pad_angle), _f(pad_throttle)), "web": (_f(web_angle), _f(web_throttle))}
        latched = {"gamepad": (pad_mode, pad_recording), "web": (web_mode, web_recording)}
        # sources in the order their changes apply: the priority source last, so it wins a tie
        order = ("web", "gamepad") if self.priority != "web" else ("gamepad", "web")
        for src in order:
            mode, recording = latched[src]
            seen = self._seen[src]
            if mode in MODES and seen.get("mode") != mode:
                if seen and mode != self.mode:
                    logger.info("controller: %s switches the mode to %s", src, mode)
                self.mode = mode
            if isinstance(recording, bool) and seen.get("recording") != recording:
                self.recording = recording
            seen["mode"], seen["recording"] = mode, recording
            if self._moving(*cmds[src]) and cmds[src] != self._prev_cmds[src]:
                self._last_moved[src] = self._loop
        self._prev_cmds = cmds
        if self.priority == "latest":
            moving = [s for s in SOURCES if self._moving(*cmds[s])]
            if moving:
                self._active = max(moving, key=lambda s: self._last_moved[s])
        else:
            other = "web" if self.priority == "gamepad" else "gamepad"
            self._active = self.priority if self._moving(*cmds[self.priority]) or \
                not self._moving(*cmds[other]) else other
        estop = bool(pad_estop) or bool(web_estop)
        angle, throttle = cmds[self._active]
        if estop:
            throttle = 0.0
        return angle, throttle, self.mode, self.recording, estop, self._active
