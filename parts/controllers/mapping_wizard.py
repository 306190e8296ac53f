"""The `vehicle createjs` wizard: map an unknown gamepad by asking the user to move each control.

It opens the pad, learns rest positions (INIT events, then a moment of stillness), then for each
action asks the user to move the stick / press the button meant for it, recognises the control by
its kernel code (an axis moved past 60 % of its travel, a button pressed, or half a D-pad axis), and
writes a layout JSON that ``CONTROLLER_TYPE = "custom"`` + ``JOYSTICK_MAPPING_PATH`` loads.
Pressing Enter skips an optional action.
"""

from __future__ import annotations

import json
import logging
import select
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from parts.controllers.events import AXIS, AXIS_MAX, BUTTON, DeviceLost, PadEvent
from parts.controllers.layouts import AxisControl, ButtonControl, Layout
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

#: travel past which a moved axis counts as chosen (fraction of full scale from rest)
MOVE_FRACTION = 0.6
#: travel under which an axis counts as released
RELEASE_FRACTION = 0.25

BUTTON_STEPS: tuple[tuple[str, str, bool], ...] = (
    ("estop", "EMERGENCY STOP (throttle 0, user mode)", True),
    ("mode_toggle", "DRIVE MODE toggle (user -> pilot steers -> pilot drives)", False),
    ("record_toggle", "RECORD toggle", False),
    ("erase_records", "ERASE the last records", False),
    ("throttle_up", "MAX THROTTLE UP", False),
    ("throttle_down", "MAX THROTTLE DOWN", False),
    ("constant_throttle", "CONSTANT THROTTLE toggle", False),
    ("behavior_next", "NEXT BEHAVIOUR", False),
    ("behavior_prev", "PREVIOUS BEHAVIOUR", False),
)


class WizardError(VehicleError, RuntimeError):
    """The wizard could not finish (no pad, pad lost, nothing moved in time)."""


class _Skip(Exception):
    pass


class CreateJsWizard:
    """Interactive mapping of a gamepad.

    Args:
        reader: an unopened LinuxJoystick / PygameJoystick.
        out, inp: where prompts go and where Enter (skip) is read from.
        step_timeout_s: how long one question waits for the user.
        settle_s: how long the pad must be left alone at the start (rest positions).
    """

    def __init__(self, reader: Any, out: TextIO, inp: TextIO | None = None, step_timeout_s: float = 30.0,
                 settle_s: float = 0.5, clock: Callable[[], float] = time.monotonic) -> None:
        self.reader = reader
        self.out = out
        self.inp = inp
        self.step_timeout_s = step_timeout_s
        self.settle_s = settle_s
        self.clock = clock
        self.rest: dict[int, int] = {}
        self.raw: dict[tuple[str, int], int] = {}
        self._queue: deque[PadEvent] = deque()
        self._inp_open = inp is not None
        self.axes: dict[str, AxisControl] = {}
        self.buttons: dict[str, ButtonControl] = {}
        self.bindings: dict[str, str] = {}
        self._used: dict[tuple[bool, int, int], str] = {}  # (is_axis, code, direction) -> action

    # -- io -------------------------------------------------------------------------------------
    def say(self, text: str) -> None:
        """Print a line for the user."""
        self.out.write(text + "\n")
        self.out.flush()

    def _enter_pressed(self) -> bool:
        if not self._inp_open or self.inp is None:
            return False
        try:
            ready, _, _ = select.select([self.inp], [], [], 0)
        except (ValueError, OSError, TypeError):  # no fileno: a StringIO, read it directly
            ready = [self.inp]
        if not ready:
            return False
        line = self.inp.readline()
        if line == "":
            self._inp_open = False  # end of input: nobody can press Enter any more
            return False
        return True

    def _next_event(self, timeout: float) -> PadEvent | None:
        if not self._queue:
            try:
                self._queue.extend(self.reader.read(timeout))
            except DeviceLost as exc:
                raise WizardError(f"the gamepad went away: {exc}") from exc
        if not self._queue:
            return None
        ev = self._queue.popleft()
        self.raw[(ev.kind, ev.code)] = ev.value
        if ev.kind == AXIS and (ev.init or ev.code not in self.rest):
            self.rest[ev.code] = ev.value if ev.init else self.rest.get(ev.code, 0)
        return ev

    # -- steps ----------------------------------------------------------------------------------
    def _settle(self) -> None:
        self.say("Leave every stick and trigger alone for a moment...")
        deadline = self.clock() + self.settle_s
        while self.clock() < deadline:
            if self._queue and not self._queue[0].init:
                break  # the INIT burst is over and the user already moves something
            ev = self._next_event(0.05)
            if ev is not None and not ev.init and ev.kind == AXIS and ev.code not in self.rest:
                self.rest[ev.code] = ev.value

    def _wait_control(self, optional: bool) -> tuple[bool, int, int]:
        """(is_axis, code, direction) of the next control the user moves; _Skip on Enter."""
        deadline = self.clock() + self.step_timeout_s
        while True:
            if self.clock() > deadline:
                if optional:
                    self.say("  (nothing moved: skipped)")
                    raise _Skip
                raise WizardError(f"nothing moved within {self.step_timeout_s:.0f} s")
            ev = self._next_event(0.05)
            if ev is None:
                if self._enter_pressed():
                    if optional:
                        self.say("  skipped")
                        raise _Skip
                    self.say("  this one is needed: move the control (or Ctrl-C to stop)")
                continue
            if ev.init:
                continue
            if ev.kind == BUTTON and ev.value:
                return False, ev.code, 1
            if ev.kind == AXIS:
                delta = ev.value - self.rest.get(ev.code, 0)
                if abs(delta) > MOVE_FRACTION * AXIS_MAX:
                    return True, ev.code, 1 if delta > 0 else -1

    def _wait_release(self, is_axis: bool, code: int) -> None:
        deadline = self.clock() + self.step_timeout_s
        while self.clock() < deadline:
            if is_axis:
                if abs(self.raw.get((AXIS, code), 0) - self.rest.get(code, 0)) < RELEASE_FRACTION * AXIS_MAX:
                    return
            elif not self.raw.get((BUTTON, code), 0):
                return
            self._next_event(0.05)
        self.say("  (still held; going on)")

    def _is_trigger(self, code: int) -> bool:
        return abs(self.rest.get(code, 0)) > 0.5 * AXIS_MAX

    def _ask_axis(self, action: str, prompt: str, optional: bool = False) -> tuple[int, int] | None:
        while True:
            self.say(prompt + ("  [Enter: skip]" if optional else ""))
            try:
                is_axis, code, direction = self._wait_control(optional)
            except _Skip:
                return None
            self._wait_release(is_axis, code)
            if not is_axis:
                self.say(f"  that was button {code:#x}; {action} needs a stick or trigger. Again:")
                continue
            if (True, code, 0) in self._used:
                self.say(f"  axis {code:#x} is already used for {self._used[(True, code, 0)]}. Again:")
                continue
            self._used[(True, code, 0)] = action
            self.say(f"  -> axis {code:#x}{' (trigger)' if self._is_trigger(code) else ''}")
            return code, direction

    def _ask_button(self, action: str, label: str, required: bool) -> None:
        while True:
            self.say(f"Press the button for {label}" + ("" if required else "  [Enter: skip]"))
            try:
                is_axis, code, direction = self._wait_control(not required)
            except _Skip:
                return
            self._wait_release(is_axis, code)
            key = (is_axis, code, direction if is_axis else 1)
            if key in self._used or (is_axis and (True, code, 0) in self._used):
                self.say(f"  that control is already used for "
                         f"{self._used.get(key) or self._used.get((True, code, 0))}. Another one:")
                continue
            self._used[key] = action
            self.buttons[action] = ButtonControl(code, is_axis, direction)
            self.bindings[action] = action
            where = f"axis {code:#x} {'+' if direction > 0 else '-'}" if is_axis else f"button {code:#x}"
            self.say(f"  -> {where}")
            return

    # -- the whole session ----------------------------------------------------------------------
    def run(self, name: str = "custom") -> Layout:
        """Ask every question and return the validated layout (the reader is closed at the end)."""
        try:
            caps = self.reader.open()
        except OSError as exc:
            raise WizardError(str(exc)) from exc
        try:
            self.say(f"Gamepad: {caps.name} ({len(caps.axis_codes)} axes, {len(caps.button_codes)} buttons)")
            self._settle()
            steer = self._ask_axis("steering", "Move the STEERING stick fully to the RIGHT, then let go")
            if steer is None:
                raise WizardError("steering is needed")
            code, direction = steer
            if self._is_trigger(code):
                raise WizardError(f"axis {code:#x} rests at one end (a trigger); steering needs a stick")
            self.axes["steering"] = AxisControl(code, invert=direction < 0)
            self.bindings["steering"] = "steering"
            thr = self._ask_axis("throttle", "Push the THROTTLE stick fully FORWARD (or pull the forward "
                                 "trigger), then let go")
            if thr is None:
                raise WizardError("throttle is needed")
            code, direction = thr
            if self._is_trigger(code):
                self.axes["throttle_forward"] = AxisControl(code, trigger=True)
                self.bindings["throttle_forward"] = "throttle_forward"
                rev = self._ask_axis("throttle_reverse", "Pull the REVERSE/BRAKE trigger, then let go",
                                     optional=True)
                if rev is not None:
                    self.axes["throttle_reverse"] = AxisControl(rev[0], trigger=True)
                    self.bindings["throttle_reverse"] = "throttle_reverse"
            else:
                # forward must read negative (Linux: stick up is negative), JOYSTICK_THROTTLE_DIR -1
                self.axes["throttle"] = AxisControl(code, invert=direction > 0)
                self.bindings["throttle"] = "throttle"
            for action, label, required in BUTTON_STEPS:
                self._ask_button(action, label, required)
        finally:
            self.reader.close()
        layout = Layout(name=name, backend=getattr(self.reader, "kind", "linux"),
                        description=f"mapped by `vehicle createjs` from {caps.name}",
                        device_names=(caps.name,), caps=caps, axes=dict(self.axes),
                        buttons=dict(self.buttons), bindings=dict(self.bindings))
        layout.validate()
        return layout


def save_layout(layout: Layout, path: str | Path) -> Path:
    """Write ``layout`` as JSON (creating folders); returns the path."""
    target = Path(path).expanduser()
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(target.name + ".tmp")
    tmp.write_text(json.dumps(layout.to_json(), indent=2) + "\n")
    tmp.replace(target)
    return target
