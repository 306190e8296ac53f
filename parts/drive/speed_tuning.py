"""Step-response tuning of the speed controller: drive a throttle step, fit a first-order model
with dead time to the measured speed, and suggest PI gains (PILOT_SPEED_KP, PILOT_SPEED_KI).

The model (FOPDT) is ``v(t) = K u (1 - exp(-(t - theta) / tau))`` after a step of throttle ``u``
at t = 0: K in m/s per unit throttle, tau the time constant and theta the dead time, seconds.
The fit is least squares over (tau, theta), and the gains follow Skogestad's SIMC rules (2003):
``kp = tau / (K (tau_c + theta))``,
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

    Least squares over a grid of time constants and dead times (the final speed, for each pair,
    in closed form), so noisy speeds (a coarse encoder) and a step cut short by the distance both
    fit; the step must have lasted at least one time constant beyond the dead time.

    Raises:
        TuningError: too few samples, the car did not move, or the speed was still rising steeply.
    """
    import numpy as np

    pts = [(float(t), float(v)) for t, v in zip(times, speeds, strict=True) if t >= 0 and v is not None
           and math.isfinite(v)]
    if len(pts) < 10:
        raise TuningError(f"only {len(pts)} speed readings after the step: is the speed sensor working?")
    if throttle <= 0:
        raise TuningError(f"the step throttle must be > 0, got {throttle}")
    t = np.array([p[0] for p in pts])
    v = np.array([p[1] for p in pts])
    t_end = float(t[-1])
    if float(np.mean(v[-max(3, len(v) // 5):])) <= 0.05:
        raise TuningError("the car did not move (final speed under 0.05 m/s): raise the step throttle")
    taus = np.geomspace(0.02, 20.0, 240)
    deads = np.linspace(0.0, min(1.0, 0.5 * t_end), 41)
    best = (math.inf, 0.0, 1.0, 0.0)
    for dead in deads:
        shifted = np.clip(t - dead, 0.0, None)[None, :]
        g = 1.0 - np.exp(-shifted / taus[:, None])  # (taus, samples)
        gg = (g * g).sum(axis=1)
        final = np.where(gg > 0, (g * v).sum(axis=1) / np.maximum(gg, 1e-12), 0.0)
        sse = ((v[None, :] - final[:, None] * g) ** 2).sum(axis=1)
        k = int(np.argmin(sse))
        if sse[k] < best[0]:
            best = (float(sse[k]), float(final[k]), float(taus[k]), float(dead))
    _, final, tau, dead = best
    if tau > t_end - dead:
        raise TuningError(f"the speed was still rising at the end of the step (time constant {tau:.1f} s, step "
                          f"{t_end:.1f} s): make the step longer (more distance or duration) or the throttle smaller")
    return StepModel(final / throttle, tau, dead, final)


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
