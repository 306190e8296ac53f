"""The built-in simulator as a Gymnasium environment, ``vehicle/Track-v0``.

The environment drives the same :class:`parts.sim.simulator.SimCar` that ``manage.py drive`` adds
(:meth:`SimCar.from_config`: the car's camera, themes, randomisation, latency, car model and loop
rate), so what an agent learns transfers to the Vehicle loop. One step is one loop: the action is
applied for ``1 / DRIVE_LOOP_HZ`` simulated seconds (throttle scaled by AI_THROTTLE_MULT, as
DriveMode does for a pilot), then the camera renders the next observation.

- Observation: the camera frame, uint8 HxWx3 (or, with ``frame``, what that function makes of it,
  e.g. a pilot's stage-1 preprocessing ``Preprocess.frame``: crop, resize, colour), optionally
  with a vector ``[speed m/s, last angle, last throttle]`` (``vector_obs=True``: a Dict observation).
- Action: ``[angle, throttle]`` in [-1, 1], or ``[angle]`` with a fixed ``throttle``. With
  ``throttle_range=(low, high)`` the throttle action's [-1, 1] spans [low, high]
  (:func:`throttle_from_action`): exploration cannot reverse or floor it, and 0 is mid-range.
- ``reset(seed=...)`` draws a track of ``tracks`` (by default tracks 1-6, so different seeds give
  different episodes), a theme of ``themes`` and one of ``randomize_draws``
  randomisation draws (with SIM_RANDOMIZE set) from the environment's generator.
- terminated: the car left the road, or drove ``laps`` laps (states of the task that end it);
  truncated: ``max_steps`` steps passed first (a time limit, not part of the task).
- Reward: a DeepRacer-style function (:mod:`parts.sim.reward`).
- ``info``: the simulator's telemetry (cte, speed, progress, laps, lap times, off-track ...).

Importing this module imports gymnasium and registers the id (:func:`register`), so
``gymnasium.make("parts.sim.gym_env:vehicle/Track-v0")`` works with nothing imported first.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from parts.sim.reward import RewardFn, TrackWaypoints, load_reward_function, reward_params
from parts.sim.simulator import SimCar
from parts.sim.themes import theme_list
from parts.sim.world import world_params

logger = logging.getLogger(__name__)

ENV_ID = "vehicle/Track-v0"
#: tracks episodes are drawn from when neither ``tracks`` nor the car's SIM_TRACK_SEEDS says, so that
#: ``reset(seed=...)`` gives different episodes for different seeds. Six: the simulator keeps the
#: last six tracks it drew (parts.sim.world), so after each is drawn once a reset costs ~60 ms
#: instead of ~390 ms for a track drawn anew (measured on an AMD EPYC, 160x120 camera)
DEFAULT_TRACKS = tuple(range(1, 7))
#: what ``reset(options=...)`` may fix
RESET_OPTIONS = ("track", "theme", "draw")
#: simulated seconds allowed per lap before an episode is truncated, when max_steps is not given
SECONDS_PER_LAP = 60.0


def throttle_from_action(a: float, throttle_range: tuple[float, float] | None) -> float:
    """The throttle of a throttle action ``a`` in [-1, 1]: ``a`` itself, or with ``(low, high)`` the
    affine map of [-1, 1] onto [low, high]."""
    if throttle_range is None:
        return float(a)
    low, high = throttle_range
    return low + (float(a) + 1.0) * 0.5 * (high - low)


def check_throttle_range(value: Any) -> tuple[float, float] | None:
    """``throttle_range`` checked: None or ``(low, high)`` with ``-1 <= low < high <= 1``."""
    if value is None:
        return None
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"throttle_range must be None or (low, high), got {value!r}") from None
    if not -1.0 <= low < high <= 1.0:
        raise ValueError(f"throttle_range must have -1 <= low < high <= 1, got {value!r}")
    return low, high


def check_options(options: dict[str, Any]) -> dict[str, Any]:
    """``reset``'s options checked and converted; a bad one raises ValueError naming it."""
    from parts.sim.themes import THEMES

    unknown = sorted(set(options) - set(RESET_OPTIONS))
    if unknown:
        raise ValueError(f"reset(options=...): unknown option {unknown[0]!r}; the options are "
                         f"{', '.join(RESET_OPTIONS)}")
    out: dict[str, Any] = {}
    for name, value in options.items():
        if name == "theme":
            if value not in THEMES:
                raise ValueError(f"options['theme'] = {value!r}: give one of {', '.join(THEMES)}")
            out[name] = str(value)
            continue
        limit = 2**32 - 1
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 0 <= int(value) <= limit:
            what = "a track seed" if name == "track" else "a randomisation draw"
            raise ValueError(f"options[{name!r}] = {value!r}: give {what}, an int from 0 to {limit}")
        out[name] = int(value)
    return out


def register() -> None:
    """Register ``vehicle/Track-v0`` with gymnasium (idempotent)."""
    if ENV_ID not in gym.registry:
        gym.register(id=ENV_ID, entry_point="parts.sim.gym_env:TrackEnv")


def _config(config: Any) -> Any:
    from vehicle.config import Config, load_config

    if config is None:
        return Config.defaults()
    if isinstance(config, str):
        return load_config(config)
    return config


class TrackEnv(gym.Env):
    """The built-in simulator as a Gymnasium environment (see the module's docstring).

    Args:
        config: the car's settings (a Config, a myconfig.py path, or None for the defaults).
        tracks: track seeds episodes are drawn from (default: SIM_TRACK_SEEDS when the car's
            myconfig.py sets it, else :data:`DEFAULT_TRACKS`, tracks 1-6).
        themes: themes episodes are drawn from (default SIM_THEME).
        randomize_draws: distinct randomisation draws per track (SIM_RANDOMIZE + 0 .. n-1);
            each new draw costs a few tenths of a second to paint. Ignored without SIM_RANDOMIZE.
        throttle: None: the agent drives the throttle; a number: steering only at this throttle.
        throttle_range: None, or ``(low, high)``: the throttle action's [-1, 1] spans this range
            (e.g. (0.2, 0.7): never reversing, never stopping, never flat out while exploring).
        laps: laps that complete an episode (terminated).
        max_steps: steps before truncation (default SECONDS_PER_LAP s per lap).
        reward: a reward file (``reward_function(params)``), a callable, or None for the default.
        frame: a function of a uint8 HxWx3 camera frame returning the uint8 HxWxC observation
            (e.g. ``Preprocess.frame`` of :mod:`parts.pilots.preprocess`: crop, resize, colour);
            picklable for vectorised environments. None: the frames as they are.
        vector_obs: add ``[speed, last angle, last throttle]`` (Dict observation).
        render_mode: None or "rgb_array" (the camera frame).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, config: Any = None, *, tracks: Sequence[int] | None = None,
                 themes: Sequence[str] | str | None = None, randomize_draws: int = 1,
                 throttle: float | None = None, throttle_range: Sequence[float] | None = None,
                 laps: int = 1, max_steps: int | None = None,
                 reward: Any = None, frame: Any = None, vector_obs: bool = False,
                 render_mode: str | None = None) -> None:
        self.cfg = _config(config)
        cfg = self.cfg
        if tracks is None:
            tracks = cfg.SIM_TRACK_SEEDS if "SIM_TRACK_SEEDS" in cfg.overridden else DEFAULT_TRACKS
        self.tracks = [int(s) for s in tracks]
        if not self.tracks:
            raise ValueError("tracks must name at least one track seed")
        self.themes = theme_list(themes if themes is not None else cfg.SIM_THEME)
        if randomize_draws < 1:
            raise ValueError(f"randomize_draws must be >= 1, got {randomize_draws}")
        self.randomize_draws = int(randomize_draws)
        if throttle is not None and not -1.0 <= float(throttle) <= 1.0:
            raise ValueError(f"throttle must be in [-1, 1] or None, got {throttle}")
        self.fixed_throttle = None if throttle is None else float(throttle)
        self.throttle_range = check_throttle_range(throttle_range)
        if self.throttle_range is not None and self.fixed_throttle is not None:
            raise ValueError("give throttle (steering only) or throttle_range (the agent's throttle), not both")
        if laps < 1:
            raise ValueError(f"laps must be >= 1, got {laps}")
        self.laps = int(laps)
        self.dt = 1.0 / cfg.DRIVE_LOOP_HZ
        self.max_steps = int(max_steps) if max_steps is not None else int(round(laps * SECONDS_PER_LAP / self.dt))
        self.throttle_mult = float(getattr(cfg, "AI_THROTTLE_MULT", 1.0))
        self.reward_fn: RewardFn = reward if callable(reward) else \
            load_reward_function(reward, cfg.RL_REWARD_TIME_LIMIT_S)
        if frame is not None and not callable(frame):
            raise TypeError(f"frame must be a function of a camera frame or None, got {type(frame).__name__}")
        self.frame = frame
        self.vector_obs = bool(vector_obs)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": cfg.DRIVE_LOOP_HZ}
        h, w = cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W
        shape = (h, w, 3) if self.frame is None else self.frame(np.zeros((h, w, 3), np.uint8)).shape
        image = spaces.Box(0, 255, shape, np.uint8)
        if self.vector_obs:
            hi = np.array([cfg.SIM_MAX_SPEED, 1.0, 1.0], np.float32)
            lo = np.array([-cfg.SIM_MAX_REVERSE_SPEED, -1.0, -1.0], np.float32)
            self.observation_space = spaces.Dict({"image": image, "vector": spaces.Box(lo, hi, dtype=np.float32)})
        else:
            self.observation_space = image
        n = 1 if self.fixed_throttle is not None else 2
        self.action_space = spaces.Box(-1.0, 1.0, (n,), np.float32)
        self.sim: SimCar | None = None
        self._waypoints: dict[int, TrackWaypoints] = {}
        self._image: np.ndarray | None = None

    # -- episodes ---------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Start an episode on a track, theme and randomisation draw from the seeded generator;
        ``options`` may fix ``track`` (a seed), ``theme`` and ``draw`` (ValueError for any other key
        or a bad value)."""
        super().reset(seed=seed)
        options = check_options(options or {})
        rng = self.np_random
        # drawn whether fixed or not, so that fixing one option does not change the others' draws
        track = self.tracks[int(rng.integers(len(self.tracks)))]
        theme = self.themes[int(rng.integers(len(self.themes)))]
        draw = int(rng.integers(self.randomize_draws))
        track, theme, draw = options.get("track", track), options.get("theme", theme), options.get("draw", draw)
        world = world_params(self.cfg)
        if world["randomize"] is not None:
            world["randomize"] = (int(world["randomize"]) + draw) % 2**32
        self.sim = SimCar.from_config(self.cfg, seeds=[track], themes=[theme], world=world,
                                      reset_off_track=False, realtime=False)
        if track not in self._waypoints:
            self._waypoints = {track: TrackWaypoints(self.sim.track)}  # one track at a time
        self.track_seed, self.theme, self.draw = track, theme, draw
        self.steps = 0
        self.last_action = (0.0, 0.0)
        self.total_reward = 0.0
        return self._observe(), self._info()

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Apply ``action`` for one loop; returns (obs, reward, terminated, truncated, info)."""
        if self.sim is None:
            raise RuntimeError("call reset() before step()")
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(-1), -1.0, 1.0)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {np.shape(action)}")
        angle = float(a[0])
        throttle = self.fixed_throttle if self.fixed_throttle is not None \
            else throttle_from_action(a[1], self.throttle_range)
        applied = throttle * self.throttle_mult  # what DriveMode sends for a pilot
        frame = self.sim.step(angle, applied)
        self.steps += 1
        self.last_action = (angle, throttle)
        st = self.sim.car.state
        params = reward_params(frame, self._waypoints[self.track_seed], steer_rad=st.steer, heading_rad=st.heading,
                               steps=self.steps, best_distance=self.sim.tracker.best, throttle=applied, dt=self.dt)
        reward = self.reward_fn(params)
        self.total_reward += reward
        terminated = bool(frame.off_track) or self.sim.tracker.laps >= self.laps
        truncated = not terminated and self.steps >= self.max_steps
        return self._observe(), reward, terminated, truncated, self._info()

    def _observe(self) -> Any:
        assert self.sim is not None
        img = self.sim.render()
        self._image = img
        obs = img if self.frame is None else self.frame(img)
        if not self.vector_obs:
            return obs
        speed = self.sim.frame.speed if self.sim.frame is not None else 0.0
        vec = np.array([speed, *self.last_action], np.float32)
        return {"image": obs, "vector": np.clip(vec, self.observation_space["vector"].low,
                                                 self.observation_space["vector"].high)}

    def _info(self) -> dict[str, Any]:
        assert self.sim is not None and self.sim.frame is not None
        f, tracker = self.sim.frame, self.sim.tracker
        return {"track": self.track_seed, "theme": self.theme, "draw": self.draw, "steps": self.steps,
                "cte": f.cte, "heading_error": f.heading_error, "speed": f.speed, "progress": f.progress,
                "laps": tracker.laps, "laps_driven": tracker.best / self.sim.track.length,
                "lap_times": list(tracker.lap_times), "off_track": f.off_track, "time": self.steps * self.dt,
                "is_success": tracker.laps >= self.laps}

    def render(self) -> np.ndarray | None:
        """The current camera frame (render_mode "rgb_array"), else None."""
        if self.render_mode != "rgb_array" or self._image is None:
            return None
        return self._image.copy()

    def close(self) -> None:
        self.sim = None


register()
