"""Throttle shaping for ESCs: slew-rate limit and the reverse "double-tap" state machine.

Both are pure and driven by the time passed to ``step(value, now)`` (seconds on any monotonic
scale), so they behave the same in the drive loop, in simulated time and in tests.
"""

from __future__ import annotations

import logging
import math
from enum import Enum
from typing import Literal

from vehicle.config import check_settings

logger = logging.getLogger(__name__)

ReverseMode = Literal["direct", "double_tap"]
REVERSE_MODES: tuple[str, ...] = ("direct", "double_tap")


class SlewLimiter:
    """Limits how fast the throttle *magnitude* may grow, in full-scale units per second.

    Moves toward zero are never delayed (releasing the throttle stops at once), and a sign change
    drops to zero first. ``rate_per_s=None`` passes commands through unchanged.

    >>> s = SlewLimiter(2.0); [round(s.step(1.0, t), 2) for t in (0.0, 0.1, 0.2, 0.3)]
    [0.0, 0.2, 0.4, 0.6]
    """

    def __init__(self, rate_per_s: float | None) -> None:
        check_settings(THROTTLE_SLEW_RATE=rate_per_s)  # full-scale units per second, None: no limit
        self.rate = rate_per_s
        self.value = 0.0
        self._last: float | None = None

    def step(self, target: float, now: float) -> float:
        """The limited command for ``target`` at time ``now``."""
        dt = 0.0 if self._last is None else max(0.0, now - self._last)
        self._last = now
        if self.rate is None:
            self.value = target
            return target
        if target * self.value < 0:
            self.value = 0.0  # through neutral at once, then ramp in the new direction
        if abs(target) <= abs(self.value):
            self.value = target
        else:
            grow = min(abs(target) - abs(self.value), self.rate * dt)
            self.value += math.copysign(grow, target)
        return self.value

    def reset(self) -> None:
        """Back to zero (after neutral): the next command ramps up from standstill."""
        self.value = 0.0
        self._last = None


class ReverseState(Enum):
    """Where the double-tap sequence is."""

    DRIVE = "drive"  # forward or stopped: commands pass
    BRAKE = "brake"  # first reverse-range pulse: the ESC brakes
    PAUSE = "pause"  # neutral, so the ESC accepts the next reverse pulse as reverse
    REVERSE = "reverse"  # reverse engaged: negative commands pass


class ReverseStateMachine:
    """Turns a negative throttle into what a forward/brake/reverse car ESC needs to back up.

    Such ESCs brake on the first reverse-range pulse and only drive backwards after a return to
    neutral ("reverse, zero, reverse"). In ``double_tap`` mode a negative command coming from
    ``DRIVE`` goes ``BRAKE`` (the command, for ``brake_s``) -> ``PAUSE`` (0, for ``neutral_s``) ->
    ``REVERSE`` (the command). Any command >= 0 returns to ``DRIVE``. ``direct`` mode passes every
    command (crawler ESCs, or when the throttle filter of the drive logic already does this).

    >>> sm = ReverseStateMachine("double_tap", brake_s=0.1, neutral_s=0.1)
    >>> [sm.step(-0.5, t) for t in (0.0, 0.05, 0.1, 0.15, 0.2, 0.25)]
    [-0.5, -0.5, 0.0, 0.0, -0.5, -0.5]
    """

    def __init__(self, mode: ReverseMode = "direct", brake_s: float = 0.1, neutral_s: float = 0.1) -> None:
        if mode not in REVERSE_MODES:
            raise ValueError(f"ESC_REVERSE_MODE must be one of {REVERSE_MODES}, got {mode!r}")
        for name, value in (("ESC_REVERSE_BRAKE_S", brake_s), ("ESC_REVERSE_NEUTRAL_S", neutral_s)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value <= 5:
                raise ValueError(f"{name} must be 0-5 seconds, got {value!r}")
        self.mode = mode
        self.brake_s = float(brake_s)
        self.neutral_s = float(neutral_s)
        self.state = ReverseState.DRIVE
        self._since = 0.0

    def step(self, throttle: float, now: float) -> float:
        """The throttle to send for the command ``throttle`` at time ``now``."""
        if self.mode == "direct":
            return throttle
        if throttle >= 0:
            self.state = ReverseState.DRIVE
            return throttle
        if self.state is ReverseState.DRIVE:
            self._enter(ReverseState.BRAKE, now)
        if self.state is ReverseState.BRAKE and now - self._since >= self.brake_s:
            self._enter(ReverseState.PAUSE, now)
        if self.state is ReverseState.PAUSE:
            if now - self._since < self.neutral_s:
                return 0.0
            self._enter(ReverseState.REVERSE, now)
        return throttle

    def _enter(self, state: ReverseState, now: float) -> None:
        logger.debug("reverse sequence: %s -> %s", self.state.value, state.value)
        self.state = state
        self._since = now

    def reset(self) -> None:
        """Forget the sequence (after neutral): the next reverse starts with a brake pulse again."""
        self.state = ReverseState.DRIVE
