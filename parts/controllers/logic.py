"""What a gamepad means: turn control events into steering, throttle, mode and button actions.

Pure state machine (no threads, no devices), fed with :class:`~parts.controllers.events.PadEvent`
lists and asked for an :class:`GamepadOutput` once per drive loop.

Safety rules it enforces:

- every axis is read relative to its rest position, learned from the first INIT event of each
  axis after the device opens (later INIT bursts, re-sent after a queue overflow, are state, not
  rest): a released trigger reads 0, never full throttle. An axis the layout calls a stick but
  that rests at one end (a trigger in a wrong layout, or a stick held while connecting) is
  blocked (reads 0, error logged) until the pad reconnects;
- throttle stays 0 until the throttle control has been seen at rest (arming), again after a
  reconnect, a silence and an emergency-stop release;
- a lost or silent pad gives throttle 0 and user mode.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import NamedTuple

from parts.controllers.events import AXIS, AXIS_MAX, BUTTON, PadEvent
from parts.controllers.layouts import BUTTON_ACTIONS, AxisControl, Layout
from vehicle.config import check_settings
from vehicle.keys import MODES

logger = logging.getLogger(__name__)

#: |rest| beyond this fraction of full scale marks an axis as a trigger (it rests at one end)
TRIGGER_REST_FRACTION = 0.5
#: an axis half counts as a pressed button past this fraction of travel
AXIS_PRESS_FRACTION = 0.5


class GamepadOutput(NamedTuple):
    """One loop's worth of gamepad outputs, in the order of the part's output keys."""

    angle: float
    throttle: float
    mode: str
    recording: bool
    estop: bool
    erase: bool  # True for one loop after the erase button was pressed (tub/erase rising edge)
    behavior_step: int  # +1 / -1 for one loop after behaviour next / previous, else 0


@dataclass
class GamepadSettings:
    """Tunables of the gamepad (DonkeyCar's JOYSTICK_* settings)."""

    max_throttle: float = 0.5  # JOYSTICK_MAX_THROTTLE: full stick = this throttle
    steering_scale: float = 1.0  # JOYSTICK_STEERING_SCALE
    throttle_dir: float = -1.0  # JOYSTICK_THROTTLE_DIR: stick up reads negative on Linux
    deadzone: float = 0.01  # JOYSTICK_DEADZONE, fraction of full travel read as 0
    auto_record_on_throttle: bool = True  # AUTO_RECORD_ON_THROTTLE
    throttle_step: float = 0.05  # JOYSTICK_THROTTLE_STEP: change of max_throttle per button press
    silence_timeout_s: float | None = 2.0  # JOYSTICK_SILENCE_TIMEOUT_S
    initial_mode: str = "user"

    def __post_init__(self) -> None:
        check_settings(JOYSTICK_MAX_THROTTLE=self.max_throttle, JOYSTICK_DEADZONE=self.deadzone,
                       JOYSTICK_THROTTLE_DIR=float(self.throttle_dir), JOYSTICK_THROTTLE_STEP=self.throttle_step)
        if self.initial_mode not in MODES:
            raise ValueError(f"mode {self.initial_mode!r} must be one of {', '.join(MODES)}")


def _clamp(x: float, lo: float = -1.0, hi: float = 1.0) -> float:
    return lo if x < lo else hi if x > hi else x


class GamepadLogic:
    """Gamepad state: raw control values, learned rest positions, latched mode/recording/e-stop."""

    def __init__(self, layout: Layout, settings: GamepadSettings | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.layout = layout
        self.settings = settings or GamepadSettings()
        self.clock = clock
        if self.settings.silence_timeout_s is None:
            logger.warning("gamepad: the silence timeout is off (JOYSTICK_SILENCE_TIMEOUT_S = None): a "
                           "Bluetooth link that drops while the throttle is held keeps the car driving; "
                           "set it to 2.0 in myconfig.py")
        self.max_throttle = self.settings.max_throttle
        self.mode = self.settings.initial_mode
        self.recording = False
        self.estop = False
        self.constant_throttle = False
        self.connected = False
        self.silent = False
        self.armed = False
        self._raw: dict[tuple[str, int], int] = {}
        self._rest: dict[int, int] = {}
        self._pressed: dict[str, bool] = {}
        self.presses: dict[str, int] = {}  # button name -> presses so far (for parts that map buttons)
        self._erase = False
        self._behavior_step = 0
        self._last_event = clock()
        self._warned_unarmed = False
        self._blocked: set[str] = set()  # stick axes found resting at an end (already reported)
        # button control name -> actions it fires
        self._button_actions: dict[str, list[str]] = {}
        for action, control in layout.bindings.items():
            if action in BUTTON_ACTIONS:
                self._button_actions.setdefault(control, []).append(action)

    # -- connection -----------------------------------------------------------------------------
    def on_connect(self) -> None:
        """The device (re)opened: forget old state; throttle must be seen at rest again."""
        self._raw.clear()
        self._rest.clear()
        self._pressed.clear()
        self._blocked.clear()
        self.connected, self.silent, self.armed = True, False, False
        self._last_event = self.clock()

    def on_disconnect(self) -> None:
        """The device is gone: throttle 0, user mode, recording off, constant throttle off."""
        self.connected = False
        self._to_safe_state()

    def _to_safe_state(self) -> None:
        self.mode = "user"
        self.recording = False
        self.constant_throttle = False
        self.armed = False

    # -- events ---------------------------------------------------------------------------------
    def feed(self, events: Iterable[PadEvent]) -> None:
        """Apply events in order: INIT events set rest positions, others may fire actions."""
        for ev in events:
            self._last_event = self.clock()
            if self.silent:
                logger.warning("gamepad %s talks again; release the throttle to re-arm", self.layout.name)
                self.silent = False
            if ev.kind == AXIS and ev.init and ev.code not in self._rest:
                self._rest[ev.code] = ev.value
            self._raw[(ev.kind, ev.code)] = ev.value
            if not ev.init:
                self._check_buttons(ev)
            else:  # a button held while connecting is not a press; remember its state
                self._sync_pressed(ev)
            if not self.armed and ev.kind == AXIS:
                self._update_arming()

    def _update_arming(self) -> float:
        """Arm once the throttle controls have reported and read 0 (released); returns the demand."""
        demand = self._throttle_demand()
        if not self.armed and all((AXIS, self.layout.axes[self.layout.bindings[a]].code) in self._raw
                                  for a in ("throttle", "throttle_forward", "throttle_reverse")
                                  if a in self.layout.bindings):
            if demand == 0.0:
                self.armed = True
                self._warned_unarmed = False
            elif not self._warned_unarmed:
                logger.warning("gamepad throttle is not at rest (%.2f): release it to arm", demand)
                self._warned_unarmed = True
        return demand

    def _sync_pressed(self, ev: PadEvent) -> None:
        for name, ctl in self.layout.buttons.items():
            if ctl.code == ev.code and ctl.axis == (ev.kind == AXIS):
                self._pressed[name] = self._is_pressed(name)

    def _is_pressed(self, name: str) -> bool:
        ctl = self.layout.buttons[name]
        if not ctl.axis:
            return bool(self._raw.get((BUTTON, ctl.code), 0))
        raw = self._raw.get((AXIS, ctl.code), 0)
        rest = self._rest.get(ctl.code, 0)
        return ctl.direction * (raw - rest) > AXIS_PRESS_FRACTION * AXIS_MAX

    def _check_buttons(self, ev: PadEvent) -> None:
        for name, ctl in self.layout.buttons.items():
            if ctl.code != ev.code or ctl.axis != (ev.kind == AXIS):
                continue
            now = self._is_pressed(name)
            before = self._pressed.get(name, False)
            self._pressed[name] = now
            if now and not before:
                self.presses[name] = self.presses.get(name, 0) + 1
                for action in self._button_actions.get(name, ()):
                    self._do(action)

    def _do(self, action: str) -> None:
        s = self.settings
        if action == "estop":
            self.estop = not self.estop
            if self.estop:
                self._to_safe_state()
                logger.warning("EMERGENCY STOP: throttle 0, user mode, recording off "
                               "(press the e-stop button again to release)")
            else:
                logger.warning("emergency stop released; release the throttle to re-arm")
        elif action == "mode_toggle":
            if self.estop:
                logger.warning("emergency stop latched: mode stays 'user'")
                return
            self.mode = MODES[(MODES.index(self.mode) + 1) % len(MODES)]
            logger.info("drive mode: %s", self.mode)
        elif action == "record_toggle":
            if s.auto_record_on_throttle:
                logger.info("AUTO_RECORD_ON_THROTTLE is on: recording follows the throttle, toggle ignored")
            elif not self.estop:
                self.recording = not self.recording
                logger.info("recording: %s", "on" if self.recording else "off")
        elif action == "erase_records":
            self._erase = True
            logger.info("erase the last records requested")
        elif action in ("throttle_up", "throttle_down"):
            step = s.throttle_step if action == "throttle_up" else -s.throttle_step
            self.max_throttle = round(_clamp(self.max_throttle + step, s.throttle_step, 1.0), 4)
            logger.info("max throttle: %.2f", self.max_throttle)
        elif action == "constant_throttle":
            self.constant_throttle = not self.constant_throttle and not self.estop
            logger.info("constant throttle: %s", "on" if self.constant_throttle else "off")
        elif action in ("behavior_next", "behavior_prev"):
            self._behavior_step += 1 if action == "behavior_next" else -1

    # -- reading axes ---------------------------------------------------------------------------
    def _axis(self, name: str) -> tuple[float, bool]:
        """(value, is_trigger) of an axis control, relative to its rest position.

        Sticks give -1..1 with the dead zone applied; triggers give 0 (rest) .. 1 (fully pressed).
        """
        ctl: AxisControl = self.layout.axes[name]
        learned = self._rest.get(ctl.code)
        rest = learned if learned is not None else (-AXIS_MAX if ctl.trigger else 0)
        raw = self._raw.get((AXIS, ctl.code), rest)
        if not ctl.trigger and abs(rest) > TRIGGER_REST_FRACTION * AXIS_MAX:
            if name not in self._blocked:
                self._blocked.add(name)
                logger.error("gamepad axis %r (code %#x) rests at %d, at one end of its travel: it is a "
                             "trigger (fix the layout: \"type\": \"trigger\") or was held while the pad "
                             "connected. It reads 0 until the pad reconnects.", name, ctl.code, rest)
            return 0.0, False
        if ctl.trigger:
            far = AXIS_MAX if rest <= 0 else -AXIS_MAX
            frac = (raw - rest) / (far - rest) if far != rest else 0.0
            frac = _clamp(frac, 0.0, 1.0)
            return (0.0 if frac < self.settings.deadzone else frac), True
        value = _clamp(raw / AXIS_MAX)
        if ctl.invert:
            value = -value
        return (0.0 if abs(value) < self.settings.deadzone else value), False

    def _bound_axis(self, action: str) -> tuple[float, bool] | None:
        control = self.layout.bindings.get(action)
        return self._axis(control) if control else None

    def _throttle_demand(self) -> float:
        """Throttle asked for by the controls, -1..1, before arming, limits and modes."""
        t = 0.0
        main = self._bound_axis("throttle")
        if main is not None:
            value, trigger = main
            t = value if trigger else self.settings.throttle_dir * value
        fwd = self._bound_axis("throttle_forward")
        if fwd is not None:
            t += fwd[0]
        rev = self._bound_axis("throttle_reverse")
        if rev is not None:
            t -= rev[0]
        return _clamp(t) + 0.0  # + 0.0 turns -0.0 into 0.0

    def _steering(self) -> float:
        steer = self._bound_axis("steering")
        if steer is None:
            return 0.0
        return _clamp(steer[0] * self.settings.steering_scale)

    # -- output ---------------------------------------------------------------------------------
    def output(self) -> GamepadOutput:
        """The outputs for this loop; consumes the one-loop erase and behaviour-step pulses."""
        erase, self._erase = self._erase, False
        step, self._behavior_step = self._behavior_step, 0
        if not self.connected:
            return GamepadOutput(0.0, 0.0, "user", False, self.estop, erase, step)
        demand = self._update_arming()
        throttle = 0.0
        if self.armed and not self.estop:
            throttle = self.max_throttle if self.constant_throttle else demand * self.max_throttle
        timeout = self.settings.silence_timeout_s
        if (timeout is not None and not self.silent and throttle != 0.0
                and self.clock() - self._last_event > timeout):
            logger.error("gamepad %s silent for more than %.1f s with throttle %.2f: throttle 0, user mode",
                         self.layout.name, timeout, throttle)
            self.silent = True
            self._to_safe_state()
        if self.silent:
            return GamepadOutput(0.0, 0.0, "user", False, self.estop, erase, step)
        recording = self.recording
        if self.settings.auto_record_on_throttle:
            recording = self.mode == "user" and abs(throttle) > self.settings.deadzone
        if self.estop:
            recording = False
        return GamepadOutput(self._steering(), throttle, self.mode, recording, self.estop, erase, step)
