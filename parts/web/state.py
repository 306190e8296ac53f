"""The lock-protected slot between the web server thread and the drive loop.

The server thread (browsers) writes commands and reads telemetry; the loop thread writes telemetry
and reads commands. Every access holds one lock and copies plain values, so neither thread ever sees
a half-updated state. The dead-man rule is applied on the loop's side (:meth:`ControlState.outputs`),
so it holds even when the server thread is stuck.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from parts.web.protocol import MODE_LABELS, MODES

logger = logging.getLogger(__name__)

#: |value| below this counts as zero for the dead-man rule
NEUTRAL_EPS = 1e-3
#: path buttons that may wait for the loop (it takes one per loop); more are refused
MAX_PATH_COMMANDS = 4


@dataclass
class Commands:
    """What the browsers asked for (the web controller's own view, before arbitration)."""

    angle: float = 0.0  # [-1, 1], as sent by the driving browser
    throttle: float = 0.0  # [-1, 1], before max_throttle scaling
    mode: str = "user"
    recording: bool = False
    estop: bool = False
    max_throttle: float = 0.5  # scale applied to the browser's throttle, [0, 1]
    constant_throttle: bool = False  # throttle = max_throttle while the page drives
    speed_limit: float | None = None  # m/s, for the speed controller; None = no limit
    model_request: str | None = None  # path of the model file asked for (handed to the loop once)
    behavior_step: int = 0  # behaviour steps asked since the loop last read them (+ next, - previous)
    path_command: str | None = None  # a path button for this loop only (web/path_command), else None

    def user_throttle(self) -> float:
        """The throttle the controller outputs: scaled, or constant when that mode is on."""
        if self.estop:
            return 0.0
        if self.constant_throttle:
            return self.max_throttle
        return self.throttle * self.max_throttle


@dataclass
class Telemetry:
    """What the loop reports to the page (inputs of the latest loop; None = not produced)."""

    mode: str | None = None
    recording: bool | None = None
    estop: bool | None = None
    num_records: int | None = None
    angle: float | None = None
    throttle: float | None = None
    pilot_angle: float | None = None
    pilot_throttle: float | None = None
    pilot_model: str | None = None
    speed: float | None = None
    loop_rate_hz: float | None = None
    loop_overruns: int | None = None
    behavior: str | None = None  # label of the active behaviour (e.g. Left_Lane), None = no behaviours
    pilot_active: bool | None = None  # the pilot ran this loop (run_pilot): its outputs are live
    pilot_error: str | None = None  # why the last model asked for was not loaded
    sim_cte: float | None = None  # m, signed cross-track error (simulator)
    sim_laps: int | None = None  # laps completed (simulator)
    sim_off_track: bool | None = None  # off the road now (simulator)
    car_gamepad: str | None = None  # the car's own gamepad: connected | silent | lost (None: none)
    battery_v: float | None = None  # V, battery/voltage from a part that measures it (None: none does)
    sensors: dict[str, bool] = field(default_factory=dict)  # sensor family (enc, imu ...) -> fresh
    obstacle_stop: bool | None = None  # the obstacle stop cuts the throttle now (None: no obstacle stop)
    obstacle_distance: float | None = None  # m, nearest LiDAR return ahead
    path: dict[str, Any] | None = None  # pose, target, state of path follow (pathview.path_telemetry)
    off_track_events: int = 0  # times the car left the road since the controller started
    loops: int = 0  # loops seen by the controller


@dataclass
class Roles:
    """Which connected browser drives; the others watch."""

    driver: str | None = None
    viewers: set[str] = field(default_factory=set)


class ControlState:
    """Commands, telemetry and the dead-man timer behind one lock.

    Args:
        deadman_s: seconds without a control message from the driving browser after which a
            non-zero throttle (or a pilot mode) falls back to throttle 0 and user mode.
        init_mode: drive mode at start, one of ``user``, ``local_angle``, ``local``.
        max_throttle: initial throttle scale in [0, 1].
        clock: monotonic time source in seconds (injectable for tests). Default ``time.monotonic``.
    """

    def __init__(self, deadman_s: float = 0.5, init_mode: str = "user", max_throttle: float = 0.5,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not deadman_s > 0:
            raise ValueError(f"deadman_s must be > 0 seconds, got {deadman_s!r}")
        if init_mode not in MODES:
            raise ValueError(f"init_mode must be one of {MODES}, got {init_mode!r}")
        if not 0.0 <= max_throttle <= 1.0:
            raise ValueError(f"max_throttle must be in [0, 1], got {max_throttle!r}")
        self.deadman_s = deadman_s
        self._clock = clock
        self._lock = threading.Lock()
        self._cmd = Commands(mode=init_mode, max_throttle=max_throttle)
        self._tel = Telemetry()
        self._roles = Roles()
        self._last_control: float | None = None  # clock() of the driver's latest message
        self._reported_at: float | None = None  # clock() of the loop's latest report
        self._armed = False  # the driving browser holds a command the dead-man must guard
        self._dirty: set[str] = set()  # fields the browser changed since the loop read them
        self._path_commands: deque[str] = deque()  # path buttons pressed, one handed out per loop
        self._notice: str | None = None  # what the page says about a change it did not ask for
        self.deadman_trips = 0

    # -- server thread ----------------------------------------------------------------------------
    def connect(self, sid: str) -> str:
        """Register a browser; the first one becomes the driver. Returns its role."""
        with self._lock:
            if self._roles.driver is None:
                self._roles.driver = sid
                return "driver"
            self._roles.viewers.add(sid)
            return "viewer"

    def disconnect(self, sid: str) -> bool:
        """Forget a browser; returns whether it was the driver. A leaving driver stops the car at
        once (throttle 0; user mode if it had the car moving). The driver's seat then stays free
        until a browser connects or presses "take control"."""
        with self._lock:
            self._roles.viewers.discard(sid)
            if self._roles.driver != sid:
                return False
            self._roles.driver = None
            self._cmd.angle = self._cmd.throttle = 0.0
            if self._armed:
                self._stop_locked("driver disconnected")
            return True

    def take_control(self, sid: str) -> str | None:
        """Make ``sid`` the driver; returns the previous driver's sid (now a viewer). The command
        is reset to neutral so the new driver starts from a stopped car."""
        with self._lock:
            previous = self._roles.driver
            if previous == sid:
                return None
            self._roles.viewers.discard(sid)
            if previous is not None:
                self._roles.viewers.add(previous)
            self._roles.driver = sid
            self._cmd.angle = self._cmd.throttle = 0.0
            self._last_control = self._clock()
            return previous

    def role(self, sid: str) -> str:
        """``driver``, ``viewer`` or ``unknown``."""
        with self._lock:
            if self._roles.driver == sid:
                return "driver"
            return "viewer" if sid in self._roles.viewers else "unknown"

    def is_driver(self, sid: str) -> bool:
        """Whether ``sid`` drives."""
        with self._lock:
            return self._roles.driver == sid

    def drive(self, angle: float, throttle: float) -> None:
        """Set the driver's (validated) stick and restart the dead-man timer."""
        with self._lock:
            self._cmd.angle, self._cmd.throttle = angle, throttle
            self._last_control = self._clock()
            self._armed = True

    def refusal(self, settings: dict[str, Any]) -> str | None:
        """Why validated ``settings`` cannot be applied now, in words for the page, or None: while
        the emergency stop is latched nothing that moves the car or records may be chosen; a pilot
        mode and a model need a pilot in the car, a speed limit a measured speed (known once the
        loop has reported)."""
        with self._lock:
            cmd, tel = self._cmd, self._tel
            if cmd.estop:
                moving = [k for k in ("mode", "recording", "constant_throttle")
                          if k in settings and settings[k] not in ("user", False)]
                if moving:
                    return (f"The emergency stop is latched: release it (STOP) before setting "
                            f"{', '.join(moving)}.")
            # a pilot part reports pilot/model (ours) or has written pilot/angle (one of the user's)
            no_pilot = tel.loops > 0 and tel.pilot_model is None and tel.pilot_angle is None
            if no_pilot and settings.get("mode", "user") != "user":
                return (f"{MODE_LABELS[settings['mode']]} needs a pilot and this car has no pilot: "
                        f"start it with a model (manage.py drive --model models/NAME.pt).")
            if tel.loops and "model" in settings and tel.pilot_model is None:  # no ModelSwitch
                return ("This car has no pilot, so it cannot load a model: start it with one "
                        "(manage.py drive --model models/NAME.pt).")
            if tel.loops and settings.get("speed_limit") is not None and tel.speed is None:
                return ("This car measures no speed (no simulator, and no wheel encoder, GPS or VESC writing "
                        "enc/speed, or its sensor is stale), so a speed limit cannot be held.")
            return None

    def apply(self, settings: dict[str, Any], model_path: str | None = None) -> None:
        """Apply validated settings (see ``protocol.parse_settings``); ``model_path`` is the
        resolved file for a ``model`` setting."""
        with self._lock:
            for key in ("mode", "recording", "max_throttle", "constant_throttle", "speed_limit"):
                if key in settings:
                    setattr(self._cmd, key, settings[key])
                    self._dirty.add(key)
            if "model" in settings:
                self._cmd.model_request = model_path
            if settings.get("mode", "user") != "user" or settings.get("constant_throttle"):
                # a pilot mode or constant throttle moves the car: the dead-man must guard it
                self._last_control = self._clock()
                self._armed = True

    def switch_model(self, model_path: str, name: str) -> str | None:
        """Ask the loop to switch the pilot to ``model_path`` for the paired laptop; returns why it
        cannot (no pilot in this car, emergency stop), else None. A car in a pilot mode first drops
        to user mode (throttle 0) and the page says why: a human engages the new pilot."""
        with self._lock:
            if self._cmd.estop:
                return "the emergency stop is latched on the car: release it on the car's page first"
            if self._tel.loops and self._tel.pilot_model is None:
                return ("this car has no pilot, so it cannot load a model: restart it with one "
                        "(manage.py drive --model models/NAME.pt)")
            if self._cmd.mode != "user" or (self._tel.mode not in (None, "user")):
                self._stop_locked("pilot switch")
                self._notice = (f"Pilot switch to {name} asked by the paired laptop: the car was put in user "
                                "mode (throttle 0). Choose a pilot mode again once it has loaded.")
            else:
                self._notice = f"Pilot switch to {name} asked by the paired laptop."
            self._cmd.model_request = model_path
            return None

    def set_notice(self, text: str | None) -> None:
        """What the page shows about a change it did not ask for (None: nothing)."""
        with self._lock:
            self._notice = text

    def step_behavior(self, step: int) -> None:
        """Ask for the next (+1) or previous (-1) behaviour; the loop applies it once."""
        with self._lock:
            self._cmd.behavior_step += step

    def path_command(self, command: str) -> str | None:
        """Queue a (validated) path button for the loop, which gets one per loop as
        ``web/path_command``; returns why it is refused, in words for the page, or None. Refused
        in a car without path follow (known once the loop has reported) and when
        :data:`MAX_PATH_COMMANDS` are already waiting. None of them moves the car, so the
        emergency stop does not refuse them."""
        with self._lock:
            if self._tel.loops and self._tel.path is None:
                return ("This car has no path follow (nothing writes path/state or loc/x): make it "
                        "with vehicle createcar --template path_follow.")
            if len(self._path_commands) >= MAX_PATH_COMMANDS:
                return f"path_command: {MAX_PATH_COMMANDS} path commands are already waiting for the car's loop"
            self._path_commands.append(command)
            return None

    def set_estop(self, on: bool) -> None:
        """Latch (True) or release (False) the emergency stop. Latching stops the car (throttle 0,
        user mode, recording off); releasing leaves it so: a pilot mode or recording has to be
        chosen again."""
        with self._lock:
            was = self._cmd.estop
            self._cmd.estop = on
            if on or was:
                self._stop_locked("emergency stop" if on else "emergency stop released")
                self._cmd.recording = False
                self._dirty.add("recording")

    def snapshot(self) -> dict[str, Any]:
        """Everything the page shows, as plain JSON-able values."""
        with self._lock:
            cmd = asdict(self._cmd)
            cmd["user_throttle"] = self._cmd.user_throttle()
            age = None if self._reported_at is None else max(0.0, self._clock() - self._reported_at)
            return {"command": cmd, "telemetry": asdict(self._tel),
                    "driver": self._roles.driver, "viewers": len(self._roles.viewers),
                    "deadman_trips": self.deadman_trips, "age_s": age, "notice": self._notice}

    # -- loop thread ------------------------------------------------------------------------------
    def report(self, telemetry: Telemetry) -> None:
        """Store the latest loop's telemetry and adopt mode/recording changed by other parts."""
        with self._lock:
            telemetry.loops = self._tel.loops + 1
            if telemetry.sim_off_track and not self._tel.sim_off_track:
                telemetry.off_track_events = self._tel.off_track_events + 1
            else:
                telemetry.off_track_events = self._tel.off_track_events
            self._tel = telemetry
            self._reported_at = self._clock()
            # another controller (gamepad) or part may have changed these: follow it unless the
            # browser changed them since the loop last read them
            if telemetry.mode in MODES and "mode" not in self._dirty:
                self._cmd.mode = telemetry.mode
            if isinstance(telemetry.recording, bool) and "recording" not in self._dirty:
                self._cmd.recording = telemetry.recording
            if self._cmd.estop:  # while stopped, another controller cannot start a pilot or recording
                self._cmd.mode, self._cmd.recording = "user", False

    def outputs(self) -> Commands:
        """The commands for this loop, after the dead-man rule. Called by the loop thread."""
        with self._lock:
            cmd = self._cmd
            if self._armed and self._last_control is not None:
                moving = abs(cmd.user_throttle()) > NEUTRAL_EPS or cmd.mode != "user"
                silent = self._clock() - self._last_control
                if moving and silent > self.deadman_s:
                    self.deadman_trips += 1
                    logger.warning("web dead-man: no control message for %.2f s (limit %.2f s): "
                                   "throttle 0, user mode", silent, self.deadman_s)
                    self._stop_locked("dead-man")
            self._dirty.clear()
            out = Commands(**asdict(cmd))
            out.path_command = self._path_commands.popleft() if self._path_commands else None
            cmd.behavior_step = 0  # a step is applied once
            cmd.model_request = None  # handed over once: asking for the same file again reloads it
            return out

    def _stop_locked(self, why: str) -> None:
        logger.debug("web controller stop: %s", why)
        self._cmd.angle = self._cmd.throttle = 0.0
        self._cmd.constant_throttle = False
        self._cmd.mode = "user"
        self._dirty.update(("mode", "constant_throttle"))
        self._armed = False
