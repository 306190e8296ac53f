"""The simulated car as a vehicle part: commands in, camera frames and telemetry out.

``SimCar.run(angle, throttle)`` applies last loop's commands for one fixed step of
``1 / DRIVE_LOOP_HZ`` seconds, updates the telemetry and renders the camera, so the same command
sequence always gives the same frames whatever clock paces the loop.
"""

from __future__ import annotations

import logging
import math
import time
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from parts.sim.camera import Camera, ImageJitter, camera_from_config
from parts.sim.kinematics import Car, CarParams
from parts.sim.telemetry import LapTracker, TelemetryFrame
from parts.sim.texture import TrackTexture, render_texture
from parts.sim.track import Track, make_track

logger = logging.getLogger(__name__)

#: memory keys the part writes, in the order of run()'s return tuple
OUTPUTS: tuple[str, ...] = (
    "cam/image_array", "cam/timestamp", "sim/cte", "sim/heading_error", "sim/speed", "sim/progress",
    "sim/lap", "sim/lap_time", "sim/off_track", "sim/pos", "sim/track", "enc/speed",
)

_WORLDS: OrderedDict[tuple[Any, ...], tuple[Track, TrackTexture]] = OrderedDict()
_WORLD_CACHE_SIZE = 6
_CUSTOM: dict[int, Track] = {}


def register_track(track: Track) -> None:
    """Make a hand-made track (see :func:`parts.sim.track.track_from_points`) drivable under its
    seed number: SimCar, evaluation and the CLI then use it instead of generating that seed."""
    if not isinstance(track, Track):
        raise TypeError(f"register_track needs a Track, got {type(track).__name__}")
    _CUSTOM[track.seed] = track
    for key in [k for k in _WORLDS if k[0] == track.seed]:
        del _WORLDS[key]


def registered_tracks() -> dict[int, Track]:
    """The hand-made tracks registered with :func:`register_track`, by seed (a copy)."""
    return dict(_CUSTOM)


def load_world(seed: int, *, size: float = 8.0, width: float = 0.8, min_radius: float = 1.2,
               lanes: int = 1, line_width: float = 0.04, res: float = 0.01,
               lighting: float = 0.25) -> tuple[Track, TrackTexture]:
    """Track and texture of a seed (a registered hand-made track, else a generated one); the last
    few are cached (a texture takes ~1 s to draw at 1 cm per pixel)."""
    key = (int(seed), size, width, min_radius, lanes, line_width, res, lighting)
    if key in _WORLDS:
        _WORLDS.move_to_end(key)
        return _WORLDS[key]
    if int(seed) in _CUSTOM:  # a registered hand-made track keeps its own geometry
        track = _CUSTOM[int(seed)]
    else:
        track = make_track(int(seed), size=size, width=width, min_radius=min_radius, lanes=lanes,
                           line_width=line_width)
    world = (track, render_texture(track, res=res, lighting=lighting))
    _WORLDS[key] = world
    while len(_WORLDS) > _WORLD_CACHE_SIZE:
        _WORLDS.popitem(last=False)
    return world


def world_params(cfg: Any) -> dict[str, Any]:
    """The load_world() keyword arguments of a Config."""
    return {"size": cfg.SIM_TRACK_SIZE, "width": cfg.SIM_ROAD_WIDTH, "min_radius": cfg.SIM_TRACK_MIN_RADIUS,
            "lanes": cfg.SIM_LANES, "line_width": cfg.SIM_LINE_WIDTH, "res": cfg.SIM_TEXTURE_RES,
            "lighting": cfg.SIM_LIGHTING_VARIATION}


class SimCar:
    """Simulated car part. Inputs: angle, throttle[, reset (rising edge)]. Outputs: :data:`OUTPUTS`.

    Args:
        seeds: track seeds; with several, the car moves to the next track after each lap.
        dt: simulated seconds per run() (1 / DRIVE_LOOP_HZ).
        camera: the camera (default 160x120).
        car_params: the car model (default 1:10 RC car).
        world: keyword arguments of :func:`load_world` (size, width, lanes, res, lighting ...).
        reset_off_track: put the car back on the road when it leaves it.
        reset_to: "start" (start line, lap restarts) or "nearest" (re-centred where it left).
        off_track_cte: |CTE| in metres beyond which the car is off the road (default: half width).
        jitter: optional image degradation.
        realtime: cam/timestamp is the wall clock (True) or start time + simulated time (False).
        start_offset: lateral offset of the start position and of "nearest" resets, metres left of
            the centre line (from_config: the expert's lane on two-lane tracks).
        switch_every: with several seeds, move to the next track every this many steps instead of
            after each lap (spreads a recording evenly over the tracks).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle", "sim/reset")
    #: the commands come from parts added after the simulator (controller, drive mode): it applies
    #: the previous loop's commands, as a real car's actuators act after its camera captured
    FEEDBACK: ClassVar[tuple[str, ...]] = ("angle", "throttle")
    #: a car may have no reset button
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("sim/reset",)
    OUTPUTS: ClassVar[tuple[str, ...]] = OUTPUTS


    def __init__(self, seeds: Sequence[int] = (1,), *, dt: float = 0.05, camera: Camera | None = None,
                 car_params: CarParams | None = None, world: dict[str, Any] | None = None,
                 reset_off_track: bool = True, reset_to: str = "start", off_track_cte: float | None = None,
                 jitter: ImageJitter | None = None, realtime: bool = True, start_offset: float = 0.0,
                 switch_every: int | None = None) -> None:
        seeds = [seeds] if isinstance(seeds, int) else list(seeds)
        if not seeds or not all(isinstance(s, int | np.integer) and not isinstance(s, bool) for s in seeds):
            raise ValueError(f"track seeds must be a non-empty list of ints, got {seeds!r}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s (1 / DRIVE_LOOP_HZ), got {dt}")
        if reset_to not in ("start", "nearest"):
            raise ValueError(f"reset_to must be 'start' or 'nearest', got {reset_to!r}")
        self.seeds = [int(s) for s in seeds]
        self.dt = float(dt)
        self.camera = camera or Camera()
        self.car = Car(car_params)
        self.world = dict(world or {})
        self.reset_off_track = reset_off_track
        self.reset_to = reset_to
        self._off_track_cte = off_track_cte
        self.jitter = jitter if jitter is not None and jitter.active else None
        self.realtime = realtime
        self.start_offset = float(start_offset)
        if switch_every is not None and switch_every < 1:
            raise ValueError(f"switch_every must be >= 1 step or None, got {switch_every}")
        self.switch_every = switch_every
        self.time = 0.0  # simulated seconds since the part was made
        self.steps = 0
        self.resets = 0
        self._wall0 = time.time()
        self._reset_requested = False
        self._reset_input = False
        self._track_index = 0
        self.frame: TelemetryFrame | None = None
        # draw the other tracks now (≈1 s each at 1 cm/px) rather than stall the loop at a switch
        for seed in self.seeds[1:_WORLD_CACHE_SIZE]:
            load_world(seed, **self.world)
        self.select_track(self.seeds[0])

    @classmethod
    def from_config(cls, cfg: Any, seeds: Sequence[int] | None = None, **kwargs: Any) -> SimCar:
        """A SimCar with every setting taken from a Config (SIM_* and DRIVE_LOOP_HZ)."""
        camera = camera_from_config(cfg)
        jitter = ImageJitter(cfg.SIM_IMAGE_NOISE, cfg.SIM_IMAGE_BLUR, cfg.SIM_BRIGHTNESS_JITTER, cfg.SIM_SEED)
        options: dict[str, Any] = {
            "dt": 1.0 / cfg.DRIVE_LOOP_HZ, "camera": camera, "car_params": CarParams.from_config(cfg),
            "world": world_params(cfg), "reset_off_track": cfg.SIM_RESET_OFF_TRACK,
            "reset_to": cfg.SIM_RESET_TO, "off_track_cte": cfg.SIM_OFF_TRACK_CTE, "jitter": jitter,
            "realtime": cfg.SIM_REALTIME}
        if cfg.SIM_LANES == 2:  # start (and re-centre) in the lane the expert keeps to
            lane = "left" if cfg.SIM_EXPERT_LANE == "left" else "right"
            if cfg.SIM_EXPERT_LANE != "center":
                options["start_offset"] = cfg.SIM_ROAD_WIDTH / 4 * (1 if lane == "left" else -1)
        options.update(kwargs)
        return cls(list(seeds) if seeds is not None else cfg.SIM_TRACK_SEEDS, **options)

    # -- track and pose -----------------------------------------------------------------------
    @property
    def seed(self) -> int:
        """Seed of the current track."""
        return self.track.seed

    def select_track(self, seed: int) -> None:
        """Move to the track of ``seed`` (generated on first use) and place the car on its start."""
        self.track, self.texture = load_world(seed, **self.world)
        cte_limit = self._off_track_cte if self._off_track_cte is not None else self.track.width / 2
        self.tracker = LapTracker(self.track, cte_limit)
        self.tracker.restart(self.time)
        self.car.place(*self.track.pose_at(0.0, self.start_offset))
        self.frame = self.tracker.update(self.car.state, self.time)

    def reset(self, to: str | None = None) -> None:
        """Put the car back on the road now: at the start line, or re-centred (in its lane) where it is."""
        to = to or self.reset_to
        self.resets += 1
        if to == "start":
            self.car.place(*self.track.pose_at(0.0, self.start_offset))
            self.tracker.restart(self.time)
        elif to == "nearest":
            s = self.track.project((self.car.state.x, self.car.state.y)).s
            self.car.place(*self.track.pose_at(s, self.start_offset))
            self.tracker.relocate()
        else:
            raise ValueError(f"reset target must be 'start' or 'nearest', got {to!r}")
        logger.debug("sim reset to %s at t=%.2f s", to, self.time)

    def request_reset(self) -> None:
        """Reset at the next step (safe to call from another thread, e.g. a web handler)."""
        self._reset_requested = True

    # -- stepping -------------------------------------------------------------------------------
    def step(self, angle: float | None, throttle: float | None) -> TelemetryFrame:
        """Advance the car by one dt under the commands (None = 0) and return the telemetry.

        When the car leaves the road the returned frame still shows it off the road (so the
        event is seen), and the car is reset afterwards if so configured.
        """
        a = 0.0 if angle is None else float(angle)
        t = 0.0 if throttle is None else float(throttle)
        if not (math.isfinite(a) and math.isfinite(t)):
            raise ValueError(f"sim car got a non-finite command angle={angle!r} throttle={throttle!r}: "
                             "check the part that produces angle/throttle (pilot output?)")
        if self._reset_requested:
            self._reset_requested = False
            self.reset()
        self.car.step(a, t, self.dt)
        self.time += self.dt
        self.steps += 1
        frame = self.tracker.update(self.car.state, self.time)
        self.frame = frame
        if frame.off_track_event:
            logger.info("sim: car left the road on track %d at t=%.1f s (cte %.2f m)",
                        self.seed, self.time, frame.cte)
            if self.reset_off_track:
                self.reset()
        if len(self.seeds) > 1 and (frame.lap_completed if self.switch_every is None
                                    else self.steps % self.switch_every == 0):
            self._track_index = (self._track_index + 1) % len(self.seeds)
            self.select_track(self.seeds[self._track_index])
            frame = self.frame  # the first frame on the new track
        return frame

    def render(self) -> np.ndarray:
        """The camera image for the car's current pose (a new HxWx3 uint8 RGB array)."""
        st = self.car.state
        img = self.camera.render(self.texture, st.x, st.y, st.heading)
        if self.jitter is not None:
            self.jitter.apply(img)
        return img

    def timestamp(self) -> float:
        """Capture time of the current frame: wall clock, or start time + simulated time."""
        return time.time() if self.realtime else self._wall0 + self.time

    def run(self, angle: float | None = None, throttle: float | None = None,
            reset: bool | None = None) -> tuple[Any, ...]:
        """One loop: apply commands, update telemetry, render; returns values for :data:`OUTPUTS`."""
        if reset and not self._reset_input:  # rising edge: a held button resets once
            self.request_reset()
        self._reset_input = bool(reset)
        self.step(angle, throttle)
        return self.observe()

    def observe(self) -> tuple[Any, ...]:
        """Values for :data:`OUTPUTS` at the current state, without stepping (a new frame)."""
        f = self.frame
        assert f is not None  # set by select_track()
        return (self.render(), self.timestamp(), f.cte, f.heading_error, f.speed, f.progress, f.lap,
                f.lap_time, f.off_track, f.pos, self.seed, f.speed)

    def shutdown(self) -> None:
        """Log a short summary of the run."""
        logger.info("sim: %.1f s simulated, %d steps, %d laps on track %d, %d resets",
                    self.time, self.steps, self.tracker.laps, self.seed, self.resets)
