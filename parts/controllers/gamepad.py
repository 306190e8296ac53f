"""The gamepad part: a reader thread feeding :class:`~parts.controllers.logic.GamepadLogic`.

Outputs (in order): ``user/angle, user/throttle, user/mode, recording, estop, tub/erase,
behavior/step``. A pad that is missing at start, unplugged, at the end of its stream or silent
gives throttle 0 and user mode, logs an error, and is reopened every ``retry_s`` seconds.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any, ClassVar, Protocol

from parts.controllers.events import Caps, DeviceLost, PadEvent
from parts.controllers.layouts import Layout
from parts.controllers.logic import GamepadLogic, GamepadOutput, GamepadSettings
from vehicle.part import ThreadedPart

logger = logging.getLogger(__name__)


class PadReader(Protocol):
    """What the gamepad part needs from a device reader (LinuxJoystick, PygameJoystick)."""

    path: str
    reconnectable: bool

    def open(self) -> Caps: ...

    def read(self, timeout: float) -> list[PadEvent]: ...

    def close(self) -> None: ...


class Gamepad(ThreadedPart):
    """Threaded gamepad part.

    Args:
        reader: the device reader.
        layout: the controller layout (see :mod:`parts.controllers.layouts`).
        settings: limits and behaviour (see :class:`GamepadSettings`).
        retry_s: seconds between attempts to (re)open a missing or lost pad.
        read_timeout_s: longest a read blocks (bounds how fast shutdown is noticed).
        clock: monotonic seconds (tests inject a fake).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ()
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/angle", "user/throttle", "user/mode", "recording", "estop", "tub/erase",
                                          "behavior/step")

    def __init__(self, reader: PadReader, layout: Layout, settings: GamepadSettings | None = None,
                 retry_s: float = 3.0, read_timeout_s: float = 0.1,
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        if retry_s <= 0 or read_timeout_s <= 0:
            raise ValueError("retry_s and read_timeout_s must be > 0 seconds")
        self.reader = reader
        self.layout = layout
        self.logic = GamepadLogic(layout, settings, clock)
        self.retry_s = retry_s
        self.read_timeout_s = read_timeout_s
        self.clock = clock
        self._next_attempt = clock()
        self._gave_up = False
        self._reported_missing = False

    # -- thread side ----------------------------------------------------------------------------
    def _try_open(self) -> bool:
        self._next_attempt = self.clock() + self.retry_s
        try:
            self.reader.open()
        except OSError as exc:  # missing, no permission, not a joystick, lost while opening
            if not self._reported_missing:
                logger.error("gamepad: %s (retrying every %g s; throttle 0, user mode meanwhile)",
                             exc.strerror or exc, self.retry_s)
                self._reported_missing = True
            return False
        with self._lock:
            self.logic.on_connect()
        if self._reported_missing:
            logger.warning("gamepad %s connected", self.reader.path)
        self._reported_missing = False
        return True

    def _lost(self, exc: BaseException) -> None:
        with self._lock:
            self.logic.on_disconnect()
        self.reader.close()
        if getattr(self.reader, "reconnectable", True):
            logger.error("gamepad lost (%s): throttle 0, user mode; reconnecting every %g s",
                         exc, self.retry_s)
        else:
            logger.error("gamepad lost (%s): throttle 0, user mode", exc)
            self._gave_up = True
        self._next_attempt = self.clock() + self.retry_s
        self._reported_missing = True

    def poll(self) -> Any:
        """Read events (or try to reconnect) and apply them; never publishes a value itself."""
        with self._lock:
            connected = self.logic.connected
        if not connected:
            if self._gave_up or self.clock() < self._next_attempt or not self._try_open():
                self.stop_event.wait(self.read_timeout_s)
            return self.NOTHING
        try:
            events = self.reader.read(self.read_timeout_s)
        except (DeviceLost, OSError) as exc:
            self._lost(exc)
            return self.NOTHING
        if events:
            with self._lock:
                self.logic.feed(events)
        return self.NOTHING

    def close(self) -> None:
        """Release the device."""
        with self._lock:
            self.logic.on_disconnect()
        self.reader.close()

    def status(self) -> str:
        """``"connected"``, ``"silent"`` (connected, no events for JOYSTICK_SILENCE_TIMEOUT_S while
        the throttle was held: the car stopped) or ``"lost"`` (missing or unplugged)."""
        with self._lock:
            if not self.logic.connected:
                return "lost"
            return "silent" if self.logic.silent else "connected"

    def presses(self) -> dict[str, int]:
        """How often each button (by the layout's name) was pressed since the start: a part that
        maps buttons to its own commands (path follow) compares counts, so no press is lost between
        two loops."""
        with self._lock:
            return dict(self.logic.presses)

    # -- loop side ------------------------------------------------------------------------------
    def run_threaded(self, *inputs: Any) -> GamepadOutput:
        """This loop's outputs (see OUTPUTS); never blocks on the device."""
        with self._lock:
            self._inputs = inputs
            return self.logic.output()

    def run(self, *inputs: Any) -> GamepadOutput:
        """Non-threaded use: read what is available now, then return the outputs."""
        self._ensure_open()
        with self._lock:
            connected = self.logic.connected
        if connected:
            try:
                events = self.reader.read(0.0)
            except (DeviceLost, OSError) as exc:
                self._lost(exc)
            else:
                with self._lock:
                    self.logic.feed(events)
        elif not self._gave_up and self.clock() >= self._next_attempt:
            self._try_open()
        return self.run_threaded(*inputs)

    def open(self) -> None:
        """First connection attempt (a missing pad is retried later, not an error)."""
        self._try_open()


class GamepadStatus:
    """Publishes a :class:`Gamepad`'s link as ``js/status`` (``connected``, ``silent``, ``lost``)
    for the web page: whether the car's gamepad can drive it."""

    INPUTS: ClassVar[tuple[str, ...]] = ()
    OUTPUTS: ClassVar[tuple[str, ...]] = ("js/status",)

    def __init__(self, pad: Gamepad) -> None:
        self.pad = pad

    def run(self) -> str:
        return self.pad.status()
