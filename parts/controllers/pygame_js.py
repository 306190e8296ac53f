"""Gamepad reader on pygame/SDL (any OS; SDL reads evdev or HIDAPI, not /dev/input/js*).

pygame is imported when the reader opens. SDL only updates joystick state while its event queue is
pumped, and pumping needs the video subsystem, so the reader initialises the display with the
``dummy`` driver unless one is set (works headless and never grabs a Pi's console).

Events are translated to :class:`~parts.controllers.events.PadEvent`: axes and buttons keep SDL's
indices as codes, hat ``n`` becomes two axes with codes ``16 + 2n`` (x) and ``17 + 2n`` (y, up
negative), like the kernel's ABS_HAT0X/ABS_HAT0Y, and values are scaled to -32767..32767.
The state read right after opening is reported as INIT events (rest positions).
"""

from __future__ import annotations

import errno
import logging
import os
import time
from collections.abc import Callable
from typing import Any

from parts.controllers.events import AXIS, AXIS_MAX, BUTTON, Caps, DeviceLost, PadEvent

logger = logging.getLogger(__name__)

HAT_BASE = 16


def hat_codes(hat: int) -> tuple[int, int]:
    """Axis codes of hat ``hat``'s x and y."""
    return HAT_BASE + 2 * hat, HAT_BASE + 2 * hat + 1


def init_pygame_headless() -> Any:
    """Import pygame and initialise what joystick reading needs, without a window or sound."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    os.environ.setdefault("SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS", "1")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    try:
        import pygame
    except ImportError as exc:
        raise ImportError("CONTROLLER_TYPE 'pygame' needs pygame: "
                          "pip install 'vehicle-rc[joystick]'") from exc
    if not pygame.display.get_init():
        pygame.display.init()
    if not pygame.joystick.get_init():
        pygame.joystick.init()
    return pygame


class PygameJoystick:
    """Reads one pad through pygame.

    Args:
        index: joystick index (0 = first pad).
        joystick_factory: builds the joystick object from an index (default
            ``pygame.joystick.Joystick``); tests pass a fake with the same methods.
    """

    kind = "pygame"
    reconnectable = True

    def __init__(self, index: int = 0, joystick_factory: Callable[[int], Any] | None = None) -> None:
        if index < 0:
            raise ValueError(f"joystick index {index} must be >= 0")
        self.index = index
        self.path = f"pygame joystick {index}"
        self._factory = joystick_factory
        self._pg: Any = None
        self._js: Any = None
        self._instance_id: int | None = None
        self._pending: list[PadEvent] = []
        self.caps = Caps(self.path)

    def open(self) -> Caps:
        """Open the pad; its current state becomes INIT events. FileNotFoundError if no pad."""
        pg = self._pg = init_pygame_headless()
        factory = self._factory or pg.joystick.Joystick
        try:
            js = factory(self.index)
        except pg.error as exc:
            raise FileNotFoundError(errno.ENODEV, f"no gamepad {self.index} found by SDL ({exc}); "
                                    "is it paired/plugged in?") from exc
        if hasattr(js, "init"):
            js.init()
        self._js = js
        self._instance_id = js.get_instance_id()
        n_axes, n_buttons, n_hats = js.get_numaxes(), js.get_numbuttons(), js.get_numhats()
        init: list[PadEvent] = []
        for i in range(n_buttons):
            init.append(PadEvent(BUTTON, i, 1 if js.get_button(i) else 0, True))
        for i in range(n_axes):
            init.append(PadEvent(AXIS, i, round(js.get_axis(i) * AXIS_MAX), True))
        for h in range(n_hats):
            init.extend(self._hat_events(h, js.get_hat(h), True))
        self._pending = init
        axis_codes = tuple(range(n_axes)) + tuple(c for h in range(n_hats) for c in hat_codes(h))
        self.caps = Caps(str(js.get_name()), axis_codes, tuple(range(n_buttons)))
        logger.info("pygame pad %d: %s, %d axes, %d buttons, %d hats", self.index, self.caps.name,
                    n_axes, n_buttons, n_hats)
        return self.caps

    @staticmethod
    def _hat_events(hat: int, xy: tuple[int, int], init: bool = False) -> list[PadEvent]:
        cx, cy = hat_codes(hat)
        # SDL hat y is +1 for up; the kernel's ABS_HAT0Y is negative for up
        return [PadEvent(AXIS, cx, int(xy[0]) * AXIS_MAX, init),
                PadEvent(AXIS, cy, -int(xy[1]) * AXIS_MAX, init)]

    def _translate(self, ev: Any) -> list[PadEvent]:
        pg = self._pg
        if getattr(ev, "instance_id", self._instance_id) != self._instance_id:
            return []
        if ev.type == pg.JOYAXISMOTION:
            return [PadEvent(AXIS, ev.axis, round(max(-1.0, min(1.0, ev.value)) * AXIS_MAX))]
        if ev.type == pg.JOYBUTTONDOWN:
            return [PadEvent(BUTTON, ev.button, 1)]
        if ev.type == pg.JOYBUTTONUP:
            return [PadEvent(BUTTON, ev.button, 0)]
        if ev.type == pg.JOYHATMOTION:
            return self._hat_events(ev.hat, ev.value)
        if ev.type == pg.JOYDEVICEREMOVED:
            raise DeviceLost(errno.ENODEV, f"{self.path} removed")
        return []

    def read(self, timeout: float) -> list[PadEvent]:
        """Events within ``timeout`` seconds ([] if none). Raises DeviceLost when the pad is removed."""
        if self._js is None:
            raise DeviceLost(errno.EBADF, f"{self.path} is not open")
        pg = self._pg
        kinds = [pg.JOYAXISMOTION, pg.JOYBUTTONDOWN, pg.JOYBUTTONUP, pg.JOYHATMOTION, pg.JOYDEVICEREMOVED]
        out, self._pending = self._pending, []
        deadline = time.monotonic() + timeout
        while True:
            for ev in pg.event.get(kinds):
                out.extend(self._translate(ev))
            if out or time.monotonic() >= deadline:
                return out
            time.sleep(min(0.01, max(0.0, deadline - time.monotonic())))  # SDL has no fd to select on

    def close(self) -> None:
        """Release the pad (pygame stays initialised for other users)."""
        js, self._js = self._js, None
        if js is not None and hasattr(js, "quit"):
            try:
                js.quit()
            except Exception:  # pygame.error after the pad vanished; nothing left to release
                logger.debug("closing %s failed", self.path, exc_info=True)
