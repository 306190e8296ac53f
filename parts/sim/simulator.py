"""The simulated car as a vehicle part: commands in, camera frames and telemetry out.

``SimCar.run(angle, throttle)`` applies last loop's commands for one fixed step of
``1 / DRIVE_LOOP_HZ`` seconds, updates the telemetry and renders the camera, so the same command
sequence always gives the same frames whatever clock paces the loop.
"""

from __future__ import annotations

import logging
import math
import time
from collections import deque
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from parts.sim.camera import PinholeCamera, camera_from_config
from parts.sim.image_sensor import ImageSensor
from parts.sim.kinematics import Car, CarParams
from parts.sim.randomize import Conditions, RangesError, check_ranges
from parts.sim.telemetry import LapTracker, TelemetryFrame
from parts.sim.themes import ThemeError, get_theme, theme_list, theme_of
from parts.sim.world import (
    World,
    conditions_for,
    load_track,
    load_world,
    prefetch_world,
    register_track,
    registered_tracks,
    world_params,
)
from vehicle.config import ConfigError, check_settings

logger = logging.getLogger(__name__)

#: memory keys the part writes, in the order of run()'s return tuple
OUTPUTS: tuple[str, ...] = (
    "cam/image_array", "cam/timestamp", "sim/cte", "sim/heading_error", "sim/speed", "sim/progress",
    "sim/lap", "sim/lap_time", "sim/off_track", "sim/pos", "sim/track", "enc/speed",
)
#: what a car with side cameras (SIM_SIDE_CAMERAS_OFFSET) writes too, after :data:`OUTPUTS`
SIDE_OUTPUTS: tuple[str, ...] = ("cam/image_array_left", "cam/image_array_right")
__all__ = ["OUTPUTS", "SIDE_OUTPUTS", "SimCar", "load_world", "register_track", "registered_tracks", "world_params"]


class SimCar:
    """Simulated car part. Inputs: angle, throttle[, reset (rising edge)]. Outputs: :data:`OUTPUTS`
    (and :data:`SIDE_OUTPUTS` with ``side_cameras``).

    Args:
        seeds: track seeds; with several, the car moves to the next track after each lap.
        dt: simulated seconds per run() (1 / DRIVE_LOOP_HZ).
        camera: the camera (default 160x120); randomised tracks offset its height, pitch and fov.
        car_params: the car model (default 1:10 RC car).
        world: keyword arguments of :func:`parts.sim.world.load_world` (size, width, lanes, res,
            lighting, randomize, ranges, distractors ...).
        themes: theme names dealt to the seeds in turn (seed i gets ``themes[i % len(themes)]``).
        reset_off_track: put the car back on the road when it leaves it.
        reset_to: "start" (start line, lap restarts) or "nearest" (re-centred where it left).
        off_track_cte: |CTE| in metres beyond which the car is off the road (default: half width).
        sensor: keyword arguments of :class:`parts.sim.image_sensor.ImageSensor` applied to every frame
            (noise, blur, brightness); randomised tracks add their own effects.
        realtime: cam/timestamp is the wall clock (True) or start time + simulated time (False).
        start_offset: lateral offset of the start position and of "nearest" resets, metres left of
            the centre line (from_config: the expert's lane on two-lane tracks).
        switch_every: with several seeds, move to the next track every this many steps instead of
            after each lap (spreads a recording evenly over the tracks).
        render: draw camera frames (False: cam/image_array is None and no texture is drawn, for
            drivers that do not look, like the expert).
        seed: seed of the per-frame random draws (SIM_SEED).
        measured_speed: also write the true speed as ``enc/speed`` (False when simulated encoders
            and the odometer measure it, as on a real car).
        side_cameras: metres left and right of the centre camera where two more cameras of the
            same kind look ahead (SIM_SIDE_CAMERAS_OFFSET), as in the Udacity simulator; their
            frames are ``cam/image_array_left`` and ``cam/image_array_right``. None: no side cameras.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle", "sim/reset")
    #: the commands come from parts added after the simulator (controller, drive mode): it applies
    #: the previous loop's commands, as a real car's actuators act after its camera captured
    FEEDBACK: ClassVar[tuple[str, ...]] = ("angle", "throttle")
    #: a car may have no reset button
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("sim/reset",)
    @property
    def OUTPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """:data:`OUTPUTS`, without enc/speed when the odometer writes it from simulated encoder
        ticks (``measured_speed`` False), with :data:`SIDE_OUTPUTS` when the car has side cameras."""
        return (OUTPUTS if self.measured_speed else OUTPUTS[:-1]) + \
            (SIDE_OUTPUTS if self.side_cameras is not None else ())

    @property
    def RECORDED(self) -> dict[str, str]:  # noqa: N802 - the part declaration read by Vehicle.recorded
        """The side cameras' frames, when the car has them (the three_camera model's data)."""
        return dict.fromkeys(SIDE_OUTPUTS, "image_array") if self.side_cameras is not None else {}

    @property
    def OUTPUT_SHAPES(self) -> dict[str, tuple[int, ...]]:  # noqa: N802 - the part declaration
        """The rendered frames' shape (SIM_CAMERA_H, SIM_CAMERA_W, 3), for the wiring check."""
        return {"cam/image_array": (self.base_camera.height, self.base_camera.width, 3)}

    def __init__(self, seeds: Sequence[int] = (1,), *, dt: float = 0.05, camera: PinholeCamera | None = None,
                 car_params: CarParams | None = None, world: dict[str, Any] | None = None,
                 themes: Sequence[str] | str = ("road",), reset_off_track: bool = True, reset_to: str = "start",
                 off_track_cte: float | None = None, sensor: dict[str, Any] | None = None, realtime: bool = True,
                 start_offset: float = 0.0, switch_every: int | None = None, render: bool = True,
                 seed: int = 0, measured_speed: bool = True, side_cameras: float | None = None) -> None:
        seeds = [seeds] if isinstance(seeds, int) else list(seeds)
        if not seeds or not all(isinstance(s, int | np.integer) and not isinstance(s, bool) for s in seeds):
            raise ValueError(f"track seeds must be a non-empty list of ints, got {seeds!r}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s (1 / DRIVE_LOOP_HZ), got {dt}")
        if reset_to not in ("start", "nearest"):
            raise ValueError(f"reset_to must be 'start' or 'nearest', got {reset_to!r}")
        self.seeds = [int(s) for s in seeds]
        self.themes = theme_list(themes)
        self.dt = float(dt)
        self.base_camera = camera or PinholeCamera()
        self.camera = self.base_camera
        self.car = Car(car_params)
        self.world_args = dict(world or {})
        self.world_args["ranges"] = dict(self.world_args.get("ranges") or {})
        check_ranges(self.world_args["ranges"])  # fail now on bad ranges, not at the first track
        randomize = self.world_args.get("randomize")
        if randomize is not None and (not isinstance(randomize, int | np.integer) or isinstance(randomize, bool)):
            raise ValueError(f"SIM_RANDOMIZE must be None or an integer seed, got {randomize!r}")
        check_settings(SIM_DISTRACTORS=int(self.world_args.get("distractors", 0)))
        self.reset_off_track = reset_off_track
        self.reset_to = reset_to
        self._off_track_cte = off_track_cte
        self.sensor_args = dict(sensor or {})
        ImageSensor(8, 8, **self.sensor_args)  # check the settings now rather than at the first track
        self.realtime = realtime
        self.start_offset = float(start_offset)
        if switch_every is not None and switch_every < 1:
            raise ValueError(f"switch_every must be >= 1 step or None, got {switch_every}")
        self.switch_every = switch_every
        self.render_images = bool(render)
        self.measured_speed = bool(measured_speed)
        if side_cameras is not None and not (math.isfinite(side_cameras) and side_cameras > 0):
            raise ValueError(f"side camera offset must be > 0 m or None, got {side_cameras!r}")
        self.side_cameras = None if side_cameras is None else float(side_cameras)
        self.frame_seed = int(seed)
        self.time = 0.0  # simulated seconds since the part was made
        self.steps = 0
        self.resets = 0
        self._wall0 = time.time()
        self._reset_requested = False
        self._reset_input = False
        self._track_index = 0
        self._pending: deque[tuple[float, float]] = deque()
        self.world: World | None = None
        self.sensor: ImageSensor | None = None
        self.frame: TelemetryFrame | None = None
        for i in range(min(len(self.seeds), len(self.themes))):  # fail now on park with two lanes
            get_theme(self.theme_for(i)).draw_look(np.random.default_rng(0), int(self.world_args.get("lanes", 1)))
        self.select_track(self.seeds[0])

    @classmethod
    def from_config(cls, cfg: Any, seeds: Sequence[int] | None = None, **kwargs: Any) -> SimCar:
        """A SimCar with every setting taken from a Config (SIM_* and DRIVE_LOOP_HZ)."""
        options: dict[str, Any] = {
            "dt": 1.0 / cfg.DRIVE_LOOP_HZ, "camera": camera_from_config(cfg), "car_params": CarParams.from_config(cfg),
            "world": world_params(cfg), "themes": cfg.SIM_THEME, "reset_off_track": cfg.SIM_RESET_OFF_TRACK,
            "reset_to": cfg.SIM_RESET_TO, "off_track_cte": cfg.SIM_OFF_TRACK_CTE,
            "sensor": {"noise": cfg.SIM_IMAGE_NOISE, "blur": cfg.SIM_IMAGE_BLUR,
                       "brightness": cfg.SIM_BRIGHTNESS_JITTER},
            "realtime": cfg.SIM_REALTIME, "seed": cfg.SIM_SEED, "side_cameras": cfg.SIM_SIDE_CAMERAS_OFFSET}
        if cfg.SIM_LANES == 2:  # start (and re-centre) in the lane the expert keeps to
            lane = "left" if cfg.SIM_EXPERT_LANE == "left" else "right"
            if cfg.SIM_EXPERT_LANE != "center":
                options["start_offset"] = cfg.SIM_ROAD_WIDTH / 4 * (1 if lane == "left" else -1)
        options.update(kwargs)
        try:
            return cls(list(seeds) if seeds is not None else cfg.SIM_TRACK_SEEDS, **options)
        except (RangesError, ThemeError) as e:  # the user's settings: one line at their line in myconfig.py
            names = ("SIM_RANDOMIZE_RANGES",) if isinstance(e, RangesError) else ("SIM_THEME", "SIM_LANES")
            raise ConfigError(f"{cfg.where(*names)}{e}") from None

    # -- track and pose -----------------------------------------------------------------------
    @property
    def seed(self) -> int:
        """Seed of the current track."""
        return self.track.seed

    @property
    def texture(self) -> Any:
        """The current track's texture (None when not rendering)."""
        return None if self.world is None else self.world.texture

    def theme_for(self, index: int) -> str:
        """Theme of the ``index``-th track of :attr:`seeds`."""
        return theme_of(self.themes, index)

    def select_track(self, seed: int) -> None:
        """Move to the track of ``seed`` (drawn on first use) and place the car on its start.

        The track's conditions are drawn here (once per episode): camera mounting, sensor effects
        and latency of a randomised track take effect now."""
        if self.seeds[self._track_index] != seed and seed in self.seeds:
            self._track_index = self.seeds.index(seed)
        index = self._track_index
        theme = self.theme_for(index)
        if self.render_images:
            self.world = load_world(seed, theme=theme, **self.world_args)
            self.track, self.conditions = self.world.track, self.world.conditions
            if len(self.seeds) > 1:  # draw the next track while this one is driven: no stall at the switch
                following = (index + 1) % len(self.seeds)
                prefetch_world(self.seeds[following], theme=self.theme_for(following), **self.world_args)
        else:
            self.world = None
            self.track = load_track(seed, **self.world_args)
            self.conditions = conditions_for(seed, theme, **self.world_args)
        self._apply_conditions(self.conditions)
        cte_limit = self._off_track_cte if self._off_track_cte is not None else self.track.width / 2
        self.tracker = LapTracker(self.track, cte_limit)
        self.tracker.restart(self.time)
        self.car.place(*self.track.pose_at(0.0, self.start_offset))
        self._clear_pending()
        self.frame = self.tracker.update(self.car.state, self.time)

    def _apply_conditions(self, cond: Conditions) -> None:
        base = self.base_camera
        theme = get_theme(cond.theme)
        if self.render_images:
            if (cond.camera_height, cond.camera_pitch, cond.camera_fov) == (0.0, 0.0, 0.0) and \
                    base.max_distance == theme.far_distance:
                self.camera = base
            else:
                self.camera = PinholeCamera(base.width, base.height, base.fov_deg + cond.camera_fov,
                                     base.pitch_deg + cond.camera_pitch, base.height_m + cond.camera_height,
                                     base.forward_m, theme.far_distance, distortion=base.distortion)
            args = dict(self.sensor_args)
            noise = float(np.hypot(args.pop("noise", 0.0), cond.noise))
            sensor = ImageSensor(base.width, base.height, noise=noise, vignetting=cond.vignetting,
                            motion_blur=cond.motion_blur, jpeg_quality=cond.jpeg_quality,
                            seed=(self.frame_seed, self.track.seed, cond.randomize or 0), **args)
            self.sensor = sensor if sensor.active else None
        self.latency = int(cond.latency)

    def _clear_pending(self) -> None:
        """Forget commands in flight (a new episode or a reset): the car stands for `latency` loops."""
        self._pending = deque([(0.0, 0.0)] * self.latency)

    def reset(self, to: str | None = None) -> None:
        """Put the car back on the road now: at the start line, or re-centred (in its lane) where it is."""
        to = to or self.reset_to
        self.resets += 1
        self._clear_pending()
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
        if self.latency:  # the command acts `latency` loops after the frame it answers
            self._pending.append((a, t))
            a, t = self._pending.popleft()
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

    def render(self, left: float = 0.0) -> np.ndarray | None:
        """The camera image for the car's current pose (a new HxWx3 uint8 RGB array; None when
        the part does not render); ``left``: of a camera that many metres left of the centre one
        (negative: right), looking the same way."""
        if self.world is None:
            return None
        st = self.car.state
        x, y = st.x - left * math.sin(st.heading), st.y + left * math.cos(st.heading)
        scenery = None if self.world.scenery.empty else self.world.scenery
        img = self.camera.render(self.world.texture, x, y, st.heading, scenery=scenery)
        if self.sensor is not None:
            self.sensor.apply(img, st.speed)
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
        values = (self.render(), self.timestamp(), f.cte, f.heading_error, f.speed, f.progress, f.lap,
                  f.lap_time, f.off_track, f.pos, self.seed)
        if self.measured_speed:
            values = (*values, f.speed)
        if self.side_cameras is None:
            return values
        return (*values, self.render(self.side_cameras), self.render(-self.side_cameras))

    def shutdown(self) -> None:
        """Log a short summary of the run."""
        logger.info("sim: %.1f s simulated, %d steps, %d laps on track %d, %d resets",
                    self.time, self.steps, self.tracker.laps, self.seed, self.resets)
