"""Expert driver for automatic demonstrations: pure pursuit + curvature speed profile + noise.

The expert reads the simulated car's true pose (it is privileged: no camera), steers by pure
pursuit towards a point ahead on the centre line (or the lane centre) and sets the throttle to
follow a speed profile that slows for curves and brakes ahead of them. ``NoiseInjector``
perturbs the *executed* steering now and then while the recorded label stays the expert's clean
command, so demonstrations contain recoveries from off-centre poses (as in DART / CIL data
collection).
"""

from __future__ import annotations

import logging
import math
from typing import Any, ClassVar

import numpy as np

from parts.sim.simulator import SimCar
from parts.sim.track import Track

logger = logging.getLogger(__name__)


def speed_profile(track: Track, v_max: float, lat_accel: float, decel: float,
                  smooth: float = 0.3) -> np.ndarray:
    """Target speed (m/s) at each centre-line sample.

    ``sqrt(lat_accel / |curvature|)`` capped at ``v_max``, with curvature averaged over ±``smooth``
    metres, then limited backwards along the track so the car can brake to every corner speed with
    ``decel`` m/s^2.
    """
    if v_max <= 0 or lat_accel <= 0 or decel <= 0:
        raise ValueError(f"speed profile needs v_max, lat_accel and decel > 0 "
                         f"(got {v_max}, {lat_accel}, {decel})")
    n = track.n
    ds = track.length / n
    half = max(1, int(round(smooth / ds)))
    kernel = np.ones(2 * half + 1) / (2 * half + 1)
    padded = np.concatenate([track.curvature[-half:], track.curvature, track.curvature[:half]])
    curv = np.abs(np.convolve(padded, kernel, mode="valid"))
    v = np.minimum(v_max, np.sqrt(lat_accel / np.maximum(curv, 1e-6)))
    for _ in range(2):  # twice round the loop so the wrap-around is braked for too
        for i in range(n - 1, -1, -1):
            v[i] = min(v[i], math.sqrt(v[(i + 1) % n] ** 2 + 2 * decel * ds))
    return v


class Expert:
    """Pure-pursuit driver of a SimCar. Part outputs: user/angle, user/throttle, user/mode, recording.

    Args:
        sim: the simulated car it drives (read for pose, track and car parameters).
        speed: highest target speed, m/s.
        lat_accel: lateral acceleration allowed in curves, m/s^2.
        lookahead: look-ahead distance at standstill, m.
        lookahead_time: extra look-ahead per m/s of speed, s.
        lane: "auto", "center", "left" or "right".
        speed_gain: throttle per m/s of speed error.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ()
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/angle", "user/throttle", "user/mode", "recording")


    def __init__(self, sim: SimCar, *, speed: float = 2.0, lat_accel: float = 2.5, lookahead: float = 0.5,
                 lookahead_time: float = 0.25, lane: str = "auto", speed_gain: float = 0.6) -> None:
        if lane not in ("auto", "center", "left", "right"):
            raise ValueError(f"expert lane must be 'auto', 'center', 'left' or 'right', got {lane!r}")
        if lookahead <= 0 or lookahead_time < 0:
            raise ValueError(f"look-ahead must be > 0 m and look-ahead time >= 0 s "
                             f"(got {lookahead}, {lookahead_time})")
        self.sim = sim
        self.speed, self.lat_accel = float(speed), float(lat_accel)
        self.lookahead, self.lookahead_time = float(lookahead), float(lookahead_time)
        self.lane = lane
        self.speed_gain = float(speed_gain)
        self._track: Track | None = None
        self._profile = np.empty(0)
        self._offset = 0.0

    @classmethod
    def from_config(cls, cfg: Any, sim: SimCar) -> Expert:
        """An expert with the SIM_EXPERT_* settings."""
        return cls(sim, speed=cfg.SIM_EXPERT_SPEED, lat_accel=cfg.SIM_EXPERT_LAT_ACCEL,
                   lookahead=cfg.SIM_EXPERT_LOOKAHEAD, lookahead_time=cfg.SIM_EXPERT_LOOKAHEAD_TIME,
                   lane=cfg.SIM_EXPERT_LANE)

    def _prepare(self, track: Track) -> None:
        params = self.sim.car.params
        speed = min(self.speed, params.max_speed)
        self._profile = speed_profile(track, speed, self.lat_accel, decel=0.5 * params.brake)
        lane = self.lane if self.lane != "auto" else ("right" if track.lanes == 2 else "center")
        self._offset = track.lane_offset(lane)
        self._track = track

    def command(self) -> tuple[float, float]:
        """The expert's (angle, throttle) for the car's current state."""
        track = self.sim.track
        if track is not self._track:
            self._prepare(track)
        st = self.sim.car.state
        params = self.sim.car.params
        s = track.project((st.x, st.y)).s
        ld = self.lookahead + self.lookahead_time * max(st.speed, 0.0)
        gx, gy, _ = track.pose_at(s + ld, self._offset)
        dx, dy = gx - st.x, gy - st.y
        c, si = math.cos(st.heading), math.sin(st.heading)
        lx, ly = c * dx + si * dy, -si * dx + c * dy  # goal in the car frame (x ahead, y left)
        dist2 = max(lx * lx + ly * ly, 1e-6)
        wheel = math.atan(2.0 * params.wheelbase * ly / dist2)  # pure pursuit: curvature 2 y / d^2
        angle = max(-1.0, min(1.0, -wheel / params.max_steer))
        i = int((s + 0.3 * max(st.speed, 0.0)) / track.length * track.n) % track.n
        target = float(self._profile[i])
        throttle = (params.drag * target + params.rolling) / params.max_accel
        throttle += self.speed_gain * (target - st.speed)
        return angle, max(-1.0, min(1.0, throttle))

    def run(self) -> tuple[float, float, str, bool]:
        """Part entry point: the expert drives and every loop is recorded."""
        angle, throttle = self.command()
        return angle, throttle, "user", True


class NoiseInjector:
    """Perturbs the executed steering with occasional triangular pulses (seeded).

    Part: inputs angle, throttle → outputs angle, throttle. A pulse starts with probability
    ``dt / every`` per step, lasts ``duration`` seconds, peaks at ±U(0.5, 1)·``amplitude`` half-way.
    Throttle passes through unchanged.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle")

    def __init__(self, amplitude: float, every: float = 3.0, duration: float = 0.8, dt: float = 0.05,
                 seed: int = 0) -> None:
        if amplitude < 0 or every <= 0 or duration <= 0 or dt <= 0:
            raise ValueError(f"noise injection needs amplitude >= 0 and every, duration, dt > 0 "
                             f"(got {amplitude}, {every}, {duration}, {dt})")
        self.amplitude, self.every, self.duration, self.dt = float(amplitude), float(every), float(duration), float(dt)
        self.rng = np.random.default_rng([seed & 0xFFFFFFFF, 0x401E])
        self._left = 0  # steps left in the current pulse
        self._steps = 1
        self._peak = 0.0
        self.pulses = 0
        self.current = 0.0  # perturbation added on the last step

    def offset(self) -> float:
        """Advance one step and return the steering perturbation for it."""
        if self._left == 0 and self.amplitude > 0 and self.rng.random() < self.dt / self.every:
            self._steps = self._left = max(2, int(round(self.duration / self.dt)))
            self._peak = self.amplitude * self.rng.uniform(0.5, 1.0) * self.rng.choice((-1.0, 1.0))
            self.pulses += 1
        if self._left == 0:
            self.current = 0.0
            return 0.0
        phase = (self._steps - self._left + 0.5) / self._steps  # 0..1 through the pulse
        self._left -= 1
        self.current = self._peak * (1.0 - abs(2.0 * phase - 1.0))
        return self.current

    def run(self, angle: float | None, throttle: float | None) -> tuple[float | None, float | None]:
        """Part entry point."""
        noise = self.offset()
        if angle is None:
            return angle, throttle
        return max(-1.0, min(1.0, float(angle) + noise)), throttle
