"""Step-response tuning of the speed controller: drive a throttle step, fit a first-order model
with dead time to the measured speed, and suggest PI gains (PILOT_SPEED_KP, PILOT_SPEED_KI).

The model (FOPDT) is ``v(t) = K u (1 - exp(-(t - theta) / tau))`` after a step of throttle ``u``
at t = 0: K in m/s per unit throttle, tau the time constant and theta the dead time, seconds.
The fit uses the classic two-point method (times at 28.3 % and 63.2 % of the final speed), and
the gains Skogestad's SIMC rules (2003): ``kp = tau / (K (tau_c + theta))``,
``Ti = min(tau, 4 (tau_c + theta))``, ``ki = kp / Ti``, with the closed-loop time constant
``tau_c`` (default: the larger of theta and a tenth of tau, a fast but robust choice).

:class:`StepTest` is the part that drives the step and records the speed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar


@dataclass(frozen=True)
class StepModel:
    """A fitted first-order-plus-dead-time speed response."""

    gain: float  # K, m/s per unit throttle
    tau: float  # s, time constant
    dead_time: float  # s, theta
    final_speed: float  # m/s reached


@dataclass(frozen=True)
class PIGains:
    """Suggested PI gains (PILOT_SPEED_KP: throttle per m/s, PILOT_SPEED_KI: per m/s per s)."""

    kp: float
    ki: float
    tau_c: float  # s, the closed-loop time constant they aim at


class TuningError(ValueError):
    """The recorded response cannot be fitted (the message says why and what to change)."""


def fit_step(times: Sequence[float], speeds: Sequence[float], throttle: float) -> StepModel:
    """Fit the FOPDT model to a step of ``throttle`` applied at t = 0 (``times`` in s from the step).

    The final speed is the mean of the last fifth of the samples; when they still vary (a step cut
    short by the distance), it is extrapolated from the exponential approach.

    Raises:
        TuningError: too few samples, the car did not move, or the speed approached no final value.
    """
    pts = [(float(t), float(v)) for t, v in zip(times, speeds, strict=True) if t >= 0 and v is not None
           and math.isfinite(v)]
    if len(pts) < 10:
        raise TuningError(f"only {len(pts)} speed readings after the step: is the speed sensor working?")
    if throttle <= 0:
        raise TuningError(f"the step throttle must be > 0, got {throttle}")
    tail_pts = pts[-max(3, len(pts) // 5):]
    tail = [v for _, v in tail_pts]
    final = sum(tail) / len(tail)
    if final <= 0.05:
        raise TuningError(f"the car did not move (final speed {final:.2f} m/s): raise the step throttle")
    # a trend over the tail (least squares) tells a rise that goes on from measurement noise
    tm = sum(t for t, _ in tail_pts) / len(tail_pts)
    den = sum((t - tm) ** 2 for t, _ in tail_pts)
    slope = sum((t - tm) * (v - final) for t, v in tail_pts) / den if den > 0 else 0.0
    rise = slope * (tail_pts[-1][0] - tail_pts[0][0])
    ahead = _extrapolated_final(pts)  # where a still rising first-order approach ends
    if ahead is not None and ahead > 1.02 * final and rise > 0.02 * final:
        final = ahead
    elif rise > 0.1 * final:
        raise TuningError(f"the speed was still rising by {rise:.2f} m/s over the end of the step and does not "
                          "approach a final speed: make the step longer (more distance) or the throttle smaller")

    def crossing(fraction: float) -> float:
        level = fraction * final
        for (t0, v0), (t1, v1) in zip(pts, pts[1:], strict=False):
            if v0 < level <= v1:
                return t0 + (t1 - t0) * (level - v0) / (v1 - v0)
        return pts[0][0] if pts[0][1] >= level else pts[-1][0]

    t28, t63 = crossing(0.283), crossing(0.632)
    tau = max(1.5 * (t63 - t28), 1e-3)
    dead = max(0.0, t63 - tau)
    return StepModel(final / throttle, tau, dead, final)


def _speed_at(pts: list[tuple[float, float]], t: float, half_width: float) -> float:
    """Mean speed of the samples within ``half_width`` seconds of ``t`` (noise averaged)."""
    near = [v for ti, v in pts if abs(ti - t) <= half_width]
    if near:
        return sum(near) / len(near)
    return min(pts, key=lambda p: abs(p[0] - t))[1]


def _extrapolated_final(pts: list[tuple[float, float]]) -> float | None:
    """The final speed of a first-order approach not yet settled: Aitken's extrapolation from
    three equally spaced speeds of its second half (exact for an exponential); None when the
    speeds do not approach a limit (still accelerating linearly, or noise)."""
    t_end = pts[-1][0]
    w = 0.08 * t_end
    last, step = t_end - w, 0.3 * t_end  # centres last - 2 step, last - step, last: equally spaced
    va, vb, vc = (_speed_at(pts, last - k * step, w) for k in (2, 1, 0))
    denom = va + vc - 2.0 * vb
    if not denom < -1e-6 * max(abs(vc), 1e-9):  # not decelerating towards a limit
        return None
    final = (va * vc - vb * vb) / denom
    if not vc <= final <= 2.0 * vc:
        return None
    return final


def simc_gains(model: StepModel, tau_c: float | None = None, min_dead_time: float = 0.0) -> PIGains:
    """SIMC PI gains for ``model`` (see the module docstring). ``min_dead_time`` (s) is the delay
    the control loop itself adds (a command acts a loop later, the speed is measured over a loop):
    a fit that finds less uses this."""
    if min_dead_time > model.dead_time:
        model = StepModel(model.gain, model.tau, min_dead_time, model.final_speed)
    if tau_c is None:
        tau_c = max(model.dead_time, 0.1 * model.tau)
    if not tau_c > 0:
        raise TuningError(f"the closed-loop time constant must be > 0 s, got {tau_c}")
    kp = model.tau / (model.gain * (tau_c + model.dead_time))
    ti = min(model.tau, 4.0 * (tau_c + model.dead_time))
    return PIGains(kp, kp / ti, tau_c)


class StepTest:
    """Part: drive straight, hold neutral for ``settle`` s, then a throttle step until ``duration``
    s or ``distance`` m have passed, then neutral; record (time from the step, speed).

    ``run(speed, distance) -> (angle, throttle, tune/done)``. Time is counted in loops of ``dt``
    seconds, so the test runs the same under a simulated clock.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("enc/speed", "enc/distance")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("enc/distance",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle", "tune/done")

    def __init__(self, throttle: float = 0.3, *, dt: float = 0.05, settle: float = 0.5, duration: float = 4.0,
                 distance: float = 5.0) -> None:
        if not 0 < throttle <= 1:
            raise TuningError(f"step throttle must be in (0, 1], got {throttle}")
        self.throttle, self.dt = float(throttle), float(dt)
        self.settle, self.duration, self.max_distance = float(settle), float(duration), float(distance)
        self.loops = 0
        self.times: list[float] = []
        self.speeds: list[float] = []
        self._start_distance: float | None = None
        self.done = False
        self.stopped_by = ""

    def run(self, speed: float | None, distance: float | None = None) -> tuple[float, float, bool]:
        """The commands of this loop."""
        t = self.loops * self.dt - self.settle
        self.loops += 1
        if self.done:
            return 0.0, 0.0, True
        if t < 0:
            return 0.0, 0.0, False
        if distance is not None and self._start_distance is None:
            self._start_distance = distance
        if speed is not None and math.isfinite(speed):
            self.times.append(t)
            self.speeds.append(float(speed))
        driven = 0.0 if distance is None or self._start_distance is None else distance - self._start_distance
        if t >= self.duration or driven >= self.max_distance:
            self.done = True
            self.stopped_by = "time" if t >= self.duration else "distance"
            return 0.0, 0.0, True
        return 0.0, self.throttle, False

    def result(self, tau_c: float | None = None) -> tuple[StepModel, PIGains]:
        """The fitted model and suggested gains (raises TuningError)."""
        model = fit_step(self.times, self.speeds, self.throttle)
        return model, simc_gains(model, tau_c, min_dead_time=1.5 * self.dt)  # one loop + a half-loop hold
