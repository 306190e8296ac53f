"""The safety logic every drivetrain shares, whatever moves the wheels.

:class:`Drivetrain` is the part (inputs ``angle``, ``throttle`` in [-1, 1]). A concrete drivetrain
says how to open its hardware, drive it, put it in neutral and release it; this class decides
*when*:

- the constructor touches no hardware; :meth:`open` (called by the assembly before the loop
  starts, or lazily by the first ``run``) opens it and writes neutral at once;
- arming: the throttle stays at neutral for ``arm_s`` seconds after open (ESCs arm on neutral),
  and then until a command at neutral arrives, so a throttle held at start never launches the car;
  where steering alone moves the car (``STEERING_MOVES_CAR``: differential drive), steering is held
  too, and arming needs commands at neutral in steering and throttle for the whole ``arm_s``;
- command watchdog: no fresh command for ``watchdog_s`` -> neutral from the watchdog's own thread
  (it fires when the loop itself is stuck), and the throttle waits for neutral again;
- :meth:`neutral` (the Vehicle calls it first on every stop path: exception, Ctrl-C, SIGTERM,
  SIGHUP, end of loops) writes neutral now; :meth:`shutdown` writes it again, holds it
  ``hold_s`` seconds, then releases the hardware.

"Neutral" is the driver's safest state: servo centred and ESC at its stop pulse, or both motor
inputs driven to brake, or a VESC's brake current.
"""

from __future__ import annotations

import logging
import math
import numbers
import threading
import time
from collections.abc import Callable
from typing import ClassVar

from parts.actuators.esc import ReverseStateMachine, SlewLimiter
from parts.actuators.watchdog import CommandWatchdog
from vehicle.config import check_settings
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)


class DrivetrainError(VehicleError, RuntimeError):
    """The drivetrain's hardware cannot be opened (no GPIO, no serial port, missing library); the
    message names the setting and what to check."""


def clamp(x: float, lo: float, hi: float) -> float:
    """``x`` limited to [lo, hi]."""
    return lo if x < lo else hi if x > hi else x


def check_number(name: str, value: object) -> float:
    """``value`` as a float; TypeError naming the setting when it is not a finite number."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise TypeError(f"{name} must be a finite number, got {value!r}")
    return float(value)


class Drivetrain:
    """Base of the drivetrain parts: arming, watchdog, neutral and shutdown (see the module doc).

    Subclasses implement :meth:`_open_hardware`, :meth:`_drive`, :meth:`_neutral_outputs` and
    :meth:`_close_hardware`; all four run under the part's lock.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle")
    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    #: |throttle| at or below this counts as "at neutral" for arming and re-arming
    NEUTRAL_BAND = 0.05
    #: True where steering alone moves the car (differential drive turns on the spot): then the
    #: steering is held at neutral too while the throttle is
    STEERING_MOVES_CAR = False

    def __init__(self, *, slew_rate: float | None = None, reverse: ReverseStateMachine | None = None,
                 arm_s: float = 0.0, watchdog_s: float | None = 0.5, hold_s: float = 0.1,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        check_settings(ESC_ARM_TIME_S=arm_s, PWM_SHUTDOWN_HOLD_S=hold_s, ACTUATOR_WATCHDOG_S=watchdog_s,
                       THROTTLE_SLEW_RATE=slew_rate)
        self.name = getattr(self, "name", type(self).__name__)
        self.slew = SlewLimiter(slew_rate)
        self.reverse = reverse or ReverseStateMachine("direct")
        self.arm_s = float(arm_s)
        self.hold_s = float(hold_s)
        self.clock = clock
        self._sleep = sleep
        self._lock = threading.RLock()
        self._opened_at: float | None = None
        self._armed = False
        self._neutral_since: float | None = None  # start of the current run of neutral commands
        self._closed = False
        self.watchdog = CommandWatchdog(watchdog_s, self._on_watchdog, clock) if watchdog_s else None

    # -- what a concrete drivetrain provides ------------------------------------------------------
    def _open_hardware(self) -> None:
        """Open the device (bus, pins, serial port); errors say what to check."""
        raise NotImplementedError

    def _drive(self, angle: float, throttle: float) -> None:
        """Send the commands (already validated, armed, limited; in [-1, 1])."""
        raise NotImplementedError

    def _neutral_outputs(self) -> None:
        """Put the hardware in its neutral state now."""
        raise NotImplementedError

    def _drive_without_throttle(self, angle: float) -> None:
        """Steer with the throttle at neutral (the throttle command is missing or NaN)."""
        self._drive(angle, 0.0)

    def _close_hardware(self) -> None:
        """Release the device (after neutral has been held)."""
        raise NotImplementedError

    def _hold_seconds(self) -> float:
        """How long shutdown holds neutral before releasing the device."""
        return self.hold_s

    def describe(self) -> str:
        """One line for the log: what drives the car and how it is wired."""
        return self.name

    def _limit(self, throttle: float) -> float:
        """The throttle command after the driver's own limits (default: clamped to [-1, 1])."""
        return clamp(throttle, -1.0, 1.0)

    # -- life cycle -------------------------------------------------------------------------------
    def open(self) -> Drivetrain:
        """Open the hardware, write neutral, start the arming time and the watchdog."""
        with self._lock:
            if self._opened_at is not None:
                return self
            self._open_hardware()
            try:
                self._write_neutral()
            except BaseException:
                self._close_hardware()
                raise
            self._opened_at = self.clock()
        if self.watchdog is not None:
            self.watchdog.start()
        else:
            logger.warning("drivetrain: the command watchdog is off (ACTUATOR_WATCHDOG_S = None): if the "
                           "loop stalls, the last throttle stays on; set it to 0.5 in myconfig.py")
        logger.info("drivetrain ready: %s; throttle passes after %.1f s and a command at neutral",
                    self.describe(), self.arm_s)
        return self

    def run(self, angle: float | None, throttle: float | None) -> None:
        """Drive: validate, arm, limit, then send."""
        if self._opened_at is None:
            self.open()
        with self._lock:
            if self._closed:
                return
            now = self.clock()
            fresh = self._valid(throttle)
            if not fresh and throttle is not None:
                logger.warning("throttle command %r is not a finite number: neutral", throttle)
            a = float(angle) if self._valid(angle) else 0.0
            t = float(throttle) if fresh else 0.0
            if fresh and self.watchdog is not None:
                self.watchdog.feed()
            if not self._armed:
                self._arm(now, a, t)
                if not self._armed:
                    t = 0.0
                    if self.STEERING_MOVES_CAR:
                        a = 0.0
            if self.STEERING_MOVES_CAR and not fresh:
                a = 0.0
            if not fresh:  # no throttle command: neutral now, not a slew-limited ramp to 0
                self.slew.reset()
                self.reverse.reset()
                self._drive_without_throttle(clamp(a, -1.0, 1.0))
                return
            t = self.reverse.step(self.slew.step(self._limit(t), now), now)
            self._drive(clamp(a, -1.0, 1.0), t)

    def neutral(self) -> None:
        """Neutral now (the Vehicle calls this first on every stop path)."""
        with self._lock:
            if self._opened_at is None or self._closed:
                return
            self._write_neutral()

    def shutdown(self) -> None:
        """Stop the watchdog, write neutral and hold it, then release the hardware (idempotent)."""
        if self.watchdog is not None:
            self.watchdog.shutdown()
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if self._opened_at is None:
                return
            try:
                self._write_neutral()
                self._sleep(self._hold_seconds())
            finally:
                self._close_hardware()

    # -- internals --------------------------------------------------------------------------------
    def _arm(self, now: float, angle: float, throttle: float) -> None:
        """Arm on a command at neutral once the arming time is over. Where steering alone moves the
        car, neutral means steering too, held for the whole arming time (a steering command starts
        it again), so the command that arms never turns the car on the spot."""
        neutral = abs(throttle) <= self.NEUTRAL_BAND
        start: float = self._opened_at  # type: ignore[assignment]
        if self.STEERING_MOVES_CAR:
            neutral = neutral and abs(angle) <= self.NEUTRAL_BAND
            if not neutral:
                self._neutral_since = None
                return
            if self._neutral_since is None:
                self._neutral_since = now
            start = max(start, self._neutral_since)
        if neutral and now - start >= self.arm_s:
            self._armed = True
            logger.info("drivetrain armed: throttle commands now reach the motors")

    def _on_watchdog(self) -> None:
        with self._lock:
            if self._closed or self._opened_at is None:
                return
            self._write_neutral()  # also disarms: throttle waits for a command at neutral again

    def _write_neutral(self) -> None:
        self.slew.reset()
        self.reverse.reset()
        self._armed = False
        self._neutral_since = None
        self._neutral_outputs()

    def _valid(self, x: object) -> bool:
        """A usable command: a finite real number (numpy scalars too). None and NaN mean "no
        command"; anything else is a wiring mistake."""
        if x is None:
            return False
        if isinstance(x, bool) or not isinstance(x, numbers.Real):
            raise TypeError(f"{self.name}: drive commands must be numbers in [-1, 1] or None, got "
                            f"{type(x).__name__} {x!r}; check what feeds the angle/throttle keys")
        return math.isfinite(x)
