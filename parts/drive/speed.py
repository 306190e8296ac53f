"""Speed control for pilots: Udacity drive.py's PI controller and Track Driver AI's limit rule, as parts.

- :class:`PIController` – ``SimplePIController`` of the Udacity behavioural-cloning project's drive.py (a PI
  controller that drives the measured speed to a set point), with a time step, output limits and
  anti-windup so that a long stall cannot wind the integral up.
- :func:`limit_throttle` – Track Driver AI's driver rule ``throttle = 1 - speed / limit``: full
  throttle at standstill, falling linearly to 0 at the limit (its later driver divides by
  ``limit * 1.25``: ``headroom``).
- :class:`DrivePyPI` – drive.py's ``SimplePIController(0.1, 0.002)`` exactly, in its own units
  (mph, the integral summed per frame), for the ``udacity-bc`` recipe.

:class:`SpeedControl` wraps either as a part. It takes the pilot's throttle, the measured speed
(``sim/speed`` or ``enc/speed``, m/s) and the target/limit (``user/speed_limit``, m/s) and returns
the throttle to drive with. With no limit (None, and no default limit) the pilot's own throttle
passes through.
"""

from __future__ import annotations

import logging
import math
import time
from typing import ClassVar, Literal

logger = logging.getLogger(__name__)

SpeedControlMode = Literal["off", "pi", "limit", "drivepy"]
SPEED_CONTROL_MODES: tuple[str, ...] = ("off", "pi", "limit", "drivepy")
MS_PER_MPH = 0.44704


def _finite(value: float | None) -> bool:
    return value is not None and isinstance(value, int | float) and math.isfinite(value)


class PIController:
    """Proportional-integral controller to a set point, output clamped to ``[out_min, out_max]``.

    Args:
        kp: proportional gain, output units per unit of error (throttle per m/s).
        ki: integral gain, output units per unit of error per second (throttle per m/s per s).
        out_min, out_max: output limits; the integral stops growing while the output is held at a
            limit in the direction of the error (conditional integration, so no wind-up).
    """

    def __init__(self, kp: float, ki: float, out_min: float = 0.0, out_max: float = 1.0) -> None:
        for name, value in (("kp", kp), ("ki", ki), ("out_min", out_min), ("out_max", out_max)):
            if not _finite(value):
                raise ValueError(f"PIController: {name} must be a finite number, got {value!r}")
        if kp < 0 or ki < 0:
            raise ValueError(f"PIController: gains must be >= 0, got kp={kp}, ki={ki}")
        if out_min >= out_max:
            raise ValueError(f"PIController: out_min ({out_min}) must be below out_max ({out_max})")
        self.kp = float(kp)
        self.ki = float(ki)
        self.out_min = float(out_min)
        self.out_max = float(out_max)
        self.set_point = 0.0
        self.integral = 0.0  # integral of the error, error units x seconds

    def set_desired(self, desired: float) -> None:
        """Change the set point (drive.py's name for it)."""
        self.set_point = float(desired)

    def reset(self) -> None:
        """Forget the accumulated integral (after a stop, a mode change ...)."""
        self.integral = 0.0

    def update(self, measurement: float, dt: float) -> float:
        """One control step: the output for ``measurement`` after ``dt`` seconds."""
        if dt <= 0:
            raise ValueError(f"PIController.update: dt must be > 0 seconds, got {dt}")
        error = self.set_point - measurement
        integral = self.integral + error * dt
        out = self.kp * error + self.ki * integral
        # Anti-windup: while the output saturates in the direction the error pushes it, let the
        # integral grow only up to the value that just reaches the limit (never shrink it here),
        # else a long stall would wind it up and the car would overshoot once it moves.
        if self.ki > 0:
            if out > self.out_max and error > 0:
                integral = min(integral, max(self.integral, (self.out_max - self.kp * error) / self.ki))
            elif out < self.out_min and error < 0:
                integral = max(integral, min(self.integral, (self.out_min - self.kp * error) / self.ki))
        self.integral = integral
        out = self.kp * error + self.ki * integral
        return min(self.out_max, max(self.out_min, out))


def limit_throttle(speed: float, limit: float, max_throttle: float = 1.0, headroom: float = 1.0) -> float:
    """Track Driver AI's rule ``throttle = 1 - speed / (limit * headroom)``, clamped to
    ``[0, max_throttle]``.

    Args:
        speed: measured speed, m/s.
        limit: speed limit, m/s (> 0).
        max_throttle: the throttle at standstill (1.0 in Track Driver AI).
        headroom: the limit's factor (1.0; 1.25 in the document's later driver, which lets the car
            settle nearer the limit).
    """
    if limit <= 0:
        raise ValueError(f"limit_throttle: the speed limit must be > 0 m/s, got {limit}")
    return min(max_throttle, max(0.0, max_throttle * (1.0 - speed / (limit * headroom))))


class DrivePyPI:
    """drive.py's ``SimplePIController`` as the Udacity behavioural-cloning project has it (seed 001):
    ``throttle = kp * error + ki * integral`` with the error in mph and the integral summed once per
    frame (not per second), no output limit. Kept exact so the recipe drives as the document did."""

    def __init__(self, kp: float = 0.1, ki: float = 0.002) -> None:
        self.kp = float(kp)
        self.ki = float(ki)
        self.set_point = 0.0
        self.integral = 0.0

    def set_desired(self, desired_mph: float) -> None:
        self.set_point = float(desired_mph)

    def reset(self) -> None:
        self.integral = 0.0

    def update(self, measurement_mph: float) -> float:
        error = self.set_point - measurement_mph
        self.integral += error
        return self.kp * error + self.ki * self.integral


class SpeedControl:
    """Part: replace the pilot's throttle by a speed controller while a speed limit is set.

    ``run(throttle, speed, speed_limit) -> throttle``. ``speed_limit`` (m/s) is the PI
    controller's target in mode "pi" and the limit of ``1 - speed/limit`` in mode "limit"; while it
    is None, ``default_limit`` applies. No limit at all (or mode "off") passes ``throttle``
    through; a limit <= 0 means stop (throttle 0). An
    unknown or non-finite speed gives throttle 0: without a measurement the car cannot be held under
    the limit.

    Args:
        mode: "pi", "limit", "drivepy" (drive.py's controller in its own units, set point =
            the limit) or "off".
        dt: seconds between two runs (the drive loop period, 1 / DRIVE_LOOP_HZ).
        kp, ki: PI gains (throttle per m/s, throttle per m/s per s).
        max_throttle: upper bound of the controlled throttle.
        default_limit: the limit (m/s) while the ``speed_limit`` input is None; None = no limit.
        headroom: factor of the limit in mode "limit" (see :func:`limit_throttle`).
    """

    warn_interval_s = 5.0  # at most one warning about a missing speed per this many seconds

    def __init__(self, mode: SpeedControlMode = "pi", *, dt: float = 0.05, kp: float = 0.3,
                 ki: float = 0.6, max_throttle: float = 1.0, default_limit: float | None = None,
                 headroom: float = 1.0) -> None:
        if mode not in SPEED_CONTROL_MODES:
            raise ValueError(f"SpeedControl: mode must be one of {SPEED_CONTROL_MODES}, got {mode!r}")
        if not _finite(dt) or dt <= 0:
            raise ValueError(f"SpeedControl: dt must be a positive number of seconds, got {dt!r}")
        if not _finite(max_throttle) or not 0 < max_throttle <= 1:
            raise ValueError(f"SpeedControl: max_throttle must be in (0, 1], got {max_throttle!r}")
        if default_limit is not None and (not _finite(default_limit) or default_limit <= 0):
            raise ValueError(f"SpeedControl: default_limit must be > 0 m/s or None, got {default_limit!r}")
        self.mode = mode
        self.default_limit = default_limit
        self.dt = float(dt)
        self.max_throttle = float(max_throttle)
        if not _finite(headroom) or headroom <= 0:
            raise ValueError(f"SpeedControl: headroom must be > 0, got {headroom!r}")
        self.headroom = float(headroom)
        self.pi = PIController(kp, ki, 0.0, max_throttle)
        self.drivepy = DrivePyPI()
        self._last_warning = -math.inf

    def run(self, throttle: float | None, speed: float | None, speed_limit: float | None) -> float | None:
        """The throttle to drive with (see the class docstring)."""
        if speed_limit is None:
            speed_limit = self.default_limit
        if self.mode == "off" or speed_limit is None:
            self._reset()
            return throttle
        if not _finite(speed_limit) or speed_limit <= 0:
            self._reset()
            return 0.0
        if not _finite(speed):
            self._warn(f"no valid speed measurement ({speed!r}): throttle 0 until there is one")
            self._reset()
            return 0.0
        measured = float(speed)  # type: ignore[arg-type]  # _finite() checked it
        if self.mode == "limit":
            return limit_throttle(measured, float(speed_limit), self.max_throttle, self.headroom)
        if self.mode == "drivepy":
            self.drivepy.set_desired(float(speed_limit) / MS_PER_MPH)
            # unlimited in drive.py; the simulator clamps to [-1, 1], and so do we (max_throttle above)
            return min(self.max_throttle, max(-1.0, self.drivepy.update(measured / MS_PER_MPH)))
        self.pi.set_desired(float(speed_limit))
        return self.pi.update(measured, self.dt)

    def _reset(self) -> None:
        self.pi.reset()
        self.drivepy.reset()

    def _warn(self, message: str) -> None:
        now = time.monotonic()
        if now - self._last_warning >= self.warn_interval_s:
            self._last_warning = now
            logger.warning("SpeedControl: %s", message)


class SpeedLimit:
    """Part: cap the car's final throttle so that its measured speed stays at or below the speed
    limit, in every drive mode. A limit, never a target: the throttle is the smaller of the one
    asked for and the one a PI controller allows, so a car slower than the limit drives exactly as
    commanded. Braking (a throttle against the motion) is never cut.

    ``run(throttle, speed, speed_limit) -> throttle`` with ``speed_limit`` in m/s (None = no
    limit). While limited, the controller starts from the throttle asked for (no jump); a missing
    or non-finite speed with a limit set gives throttle 0 (the limit cannot be held blind).

    Args:
        dt: seconds between two runs (1 / DRIVE_LOOP_HZ).
        kp, ki: PI gains, throttle per m/s and per m/s per second.
    """

    #: a car that measures its speed elsewhere renames ``sim/speed``:
    #: ``V.add(part, inputs=rename(SpeedLimit.INPUTS, {"sim/speed": "enc/speed"}))``
    INPUTS: ClassVar[tuple[str, ...]] = ("throttle", "sim/speed", "user/speed_limit")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("throttle",)
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("user/speed_limit",)
    warn_interval_s = 5.0

    def __init__(self, *, dt: float = 0.05, kp: float = 0.3, ki: float = 0.6) -> None:
        if not _finite(dt) or dt <= 0:
            raise ValueError(f"SpeedLimit: dt must be a positive number of seconds, got {dt!r}")
        self.dt = float(dt)
        self.pi = PIController(kp, ki, 0.0, 1.0)
        self.limiting = False  # whether the limit cut the throttle in the last run
        self._last_warning = -math.inf

    def run(self, throttle: float | None, speed: float | None, speed_limit: float | None) -> float | None:
        """The throttle to drive with (see the class docstring)."""
        self.limiting = False
        if throttle is None or speed_limit is None or not _finite(throttle) or throttle == 0:
            self.pi.reset()
            return throttle
        if not _finite(speed):
            self._warn(f"no valid speed measurement ({speed!r}): throttle 0 while a speed limit is set")
            self.pi.reset()
            return 0.0
        direction = 1.0 if throttle > 0 else -1.0
        along = float(speed) * direction  # speed in the direction the throttle pushes
        if along < 0:  # a throttle against the motion brakes: never cut it
            self.pi.reset()
            return throttle
        asked = abs(float(throttle))
        limit = max(0.0, float(speed_limit))
        self.pi.set_desired(limit)
        allowed = self.pi.update(along, self.dt)
        if asked <= allowed:
            # not limiting: keep the controller where it would give the throttle asked for, so
            # that it takes over from there (no jump) when the car reaches the limit
            if self.pi.ki > 0:
                self.pi.integral = (asked - self.pi.kp * (limit - along)) / self.pi.ki
            return throttle
        self.limiting = True
        return direction * allowed

    def _reset(self) -> None:
        self.pi.reset()
        self.drivepy.reset()

    def _warn(self, message: str) -> None:
        now = time.monotonic()
        if now - self._last_warning >= self.warn_interval_s:
            self._last_warning = now
            logger.warning("SpeedLimit: %s", message)
