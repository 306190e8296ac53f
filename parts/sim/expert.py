"""Expert driver for automatic demonstrations: pure pursuit + curvature speed profile + noise.

The expert reads the simulated car's true pose (it is privileged: no camera), steers by pure
pursuit towards a point ahead on the centre line (or the lane centre) and sets the throttle to
follow a speed profile that slows for curves and brakes ahead of them. ``NoiseInjector``
perturbs the *executed* steering now and then while the recorded label stays the expert's clean
command, so demonstrations contain recoveries from off-centre poses (as in DART / CIL data
collection). On two-lane tracks the expert can follow the behaviour state (Left_Lane /
Right_Lane) and change lanes smoothly when it changes (the thesis's lane change on demand).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from parts.drive.behavior import behavior_lane
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


def smoothstep(u: float) -> float:
    """Quintic 0 -> 1 ramp on [0, 1] with zero slope and curvature at both ends."""
    u = min(1.0, max(0.0, u))
    return u * u * u * (u * (6.0 * u - 15.0) + 10.0)


class Expert:
    """Pure-pursuit driver of a SimCar. Part outputs: user/angle, user/throttle, user/mode, recording.

    On two-lane tracks the expert keeps to a lane: ``lane``, or with ``behaviors`` (the names of
    BEHAVIOR_LIST, e.g. Left_Lane / Right_Lane) the lane of the behaviour its input
    ``behavior/state`` selects. When that changes it moves over to the new lane along a smooth
    (quintic) path of ``change_distance`` metres; it waits with the manoeuvre while the road over
    that distance curves more than ``change_max_curvature`` (a tight corner), for at most
    ``change_max_delay`` seconds, as the thesis observed its drivers (and its model) do.

    Args:
        sim: the simulated car it drives (read for pose, track and car parameters).
        speed: highest target speed, m/s.
        lat_accel: lateral acceleration allowed in curves, m/s^2.
        lookahead: look-ahead distance at standstill, m.
        lookahead_time: extra look-ahead per m/s of speed, s.
        lane: "auto", "center", "left" or "right".
        speed_gain: throttle per m/s of speed error.
        behaviors: behaviour names whose lane the expert follows (None: always ``lane``).
        change_distance: length of a lane change, m.
        change_max_curvature: 1/m; a lane change starts only where the road is straighter.
        change_max_delay: s; after this a change starts whatever the curvature.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ()
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/angle", "user/throttle", "user/mode", "recording")


    def __init__(self, sim: SimCar, *, speed: float = 2.0, lat_accel: float = 2.5, lookahead: float = 0.5,
                 lookahead_time: float = 0.25, lane: str = "auto", speed_gain: float = 0.6,
                 behaviors: Sequence[str] | None = None, change_distance: float = 2.0,
                 change_max_curvature: float = 0.4, change_max_delay: float = 3.0) -> None:
        if lane not in ("auto", "center", "left", "right"):
            raise ValueError(f"expert lane must be 'auto', 'center', 'left' or 'right', got {lane!r}")
        if lookahead <= 0 or lookahead_time < 0:
            raise ValueError(f"look-ahead must be > 0 m and look-ahead time >= 0 s "
                             f"(got {lookahead}, {lookahead_time})")
        if change_distance <= 0 or change_max_curvature <= 0 or change_max_delay < 0:
            raise ValueError(f"lane change needs distance > 0 m, max curvature > 0 1/m and max delay >= 0 s "
                             f"(got {change_distance}, {change_max_curvature}, {change_max_delay})")
        self.sim = sim
        self.speed, self.lat_accel = float(speed), float(lat_accel)
        self.lookahead, self.lookahead_time = float(lookahead), float(lookahead_time)
        self.lane = lane
        self.speed_gain = float(speed_gain)
        self.behavior_lanes: list[str] | None = None
        if behaviors is not None:
            lanes = [behavior_lane(b) for b in behaviors]
            unknown = [b for b, ln in zip(behaviors, lanes, strict=True) if ln is None]
            if unknown:
                raise ValueError(f"the expert cannot tell which lane behaviours {unknown} mean: name them with "
                                 "Left/Right/Center (e.g. BEHAVIOR_LIST = ['Left_Lane', 'Right_Lane'])")
            self.behavior_lanes = [str(ln) for ln in lanes]
        self.change_distance = float(change_distance)
        self.change_max_curvature = float(change_max_curvature)
        self.change_max_delay = float(change_max_delay)
        self._track: Track | None = None
        self._profile = np.empty(0)
        self._offset = 0.0
        # lane plan along the unwrapped distance travelled (odometer, m): offset goes from
        # _from to _to between _start and _start + change_distance
        self._odo = 0.0
        self._last_s: float | None = None
        self._from = self._to = 0.0
        self._start = -math.inf
        self._target_lane: str | None = None
        self._waiting_since: float | None = None  # sim time the pending change was asked
        self.changes_started = 0
        self.changes_delayed = 0  # changes that had to wait for a straighter road

    @classmethod
    def from_config(cls, cfg: Any, sim: SimCar) -> Expert:
        """An expert with the SIM_EXPERT_* settings; on two-lane tracks with TRAIN_BEHAVIORS it
        follows the lane of BEHAVIOR_LIST's active behaviour."""
        behaviors = cfg.BEHAVIOR_LIST if cfg.TRAIN_BEHAVIORS and cfg.SIM_LANES == 2 else None
        return cls(sim, speed=cfg.SIM_EXPERT_SPEED, lat_accel=cfg.SIM_EXPERT_LAT_ACCEL,
                   lookahead=cfg.SIM_EXPERT_LOOKAHEAD, lookahead_time=cfg.SIM_EXPERT_LOOKAHEAD_TIME,
                   lane=cfg.SIM_EXPERT_LANE, behaviors=behaviors,
                   change_distance=cfg.SIM_EXPERT_LANE_CHANGE_DISTANCE,
                   change_max_curvature=cfg.SIM_EXPERT_LANE_CHANGE_MAX_CURVATURE,
                   change_max_delay=cfg.SIM_EXPERT_LANE_CHANGE_MAX_DELAY)

    def _prepare(self, track: Track) -> None:
        params = self.sim.car.params
        speed = min(self.speed, params.max_speed)
        self._profile = speed_profile(track, speed, self.lat_accel, decel=0.5 * params.brake)
        lane = self.lane if self.lane != "auto" else ("right" if track.lanes == 2 else "center")
        self._offset = track.lane_offset(lane)
        self._track = track
        # on a new track the car moves (smoothly) from where it was placed to the lane asked for
        self._waiting_since = None
        self._last_s = None
        self._move_to(self._offset_of(self._target_lane) if self._target_lane else self._offset)

    def _move_to(self, offset: float) -> None:
        """Plan a smooth move from the car's lateral position to ``offset`` starting now."""
        st = self.sim.car.state
        assert self._track is not None
        here = -self._track.project((st.x, st.y)).cte
        self._from, self._to, self._start = here, offset, self._odo

    def _offset_of(self, lane: str) -> float:
        assert self._track is not None
        return self._track.lane_offset(lane) if self._track.lanes == 2 else 0.0

    def offset_at(self, odo: float) -> float:
        """Planned lateral offset (m, left of the centre line) at odometer reading ``odo``."""
        return self._from + (self._to - self._from) * smoothstep((odo - self._start) / self.change_distance)

    def _follow_behavior(self, state: Any, track: Track, s: float) -> None:
        """Plan a lane change when the behaviour asks for another lane."""
        if self.behavior_lanes is None or state is None or track.lanes != 2:
            return
        try:
            lane = self.behavior_lanes[int(state)]
        except (IndexError, TypeError, ValueError):
            return
        if lane == self._target_lane:
            self._waiting_since = None  # a change asked for and taken back before it began: no wait left over
            return
        if self._target_lane is None:  # first state seen (start of a run): go to that lane now
            self._target_lane = lane
            self._move_to(self._offset_of(lane))
            return
        if self._waiting_since is None:
            self._waiting_since = self.sim.time
        tight = track.curvature_ahead(s, self.change_distance + self.lookahead) > self.change_max_curvature
        if tight and self.sim.time - self._waiting_since < self.change_max_delay:
            return  # wait for a straighter stretch
        if self.sim.time > self._waiting_since:
            self.changes_delayed += 1
        current = self.offset_at(self._odo)
        self._from, self._to, self._start = current, self._offset_of(lane), self._odo
        self._target_lane = lane
        self._waiting_since = None
        self.changes_started += 1
        logger.debug("expert: lane change to %s at t=%.2f s", lane, self.sim.time)

    def command(self, behavior_state: Any = None) -> tuple[float, float]:
        """The expert's (angle, throttle) for the car's current state (and behaviour)."""
        track = self.sim.track
        if track is not self._track:
            self._prepare(track)
        st = self.sim.car.state
        params = self.sim.car.params
        s = track.project((st.x, st.y)).s
        if self._last_s is not None:
            ds = (s - self._last_s) % track.length
            if ds > track.length / 2:  # moved backwards (reversing) or was reset behind
                ds -= track.length
            if abs(ds) > 1.0:  # the car was put somewhere else (a reset): it is in the lane asked for
                self._from = self._to
                self._start = -math.inf
            self._odo += ds
        self._last_s = s
        self._follow_behavior(behavior_state, track, s)
        ld = self.lookahead + self.lookahead_time * max(st.speed, 0.0)
        offset = self.offset_at(self._odo + ld) if self.behavior_lanes is not None else self._offset
        gx, gy, _ = track.pose_at(s + ld, offset)
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

    def run(self, behavior_state: Any = None) -> tuple[float, float, str, bool]:
        """Part entry point (input: ``behavior/state`` when it follows behaviours): the expert drives
        and every loop is recorded."""
        angle, throttle = self.command(behavior_state)
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
