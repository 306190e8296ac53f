"""A world: one track drawn in one theme under one set of conditions, ready to render.

``load_world(seed, theme=..., randomize=...)`` builds (and caches) the track's geometry, its
:class:`~parts.sim.themes.Look`, the texture of its ground with light and shadows baked in, the
backdrop and the distractors. Everything is drawn from generators seeded by the track seed and the
randomisation seed, so the same arguments give the same world on every machine.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import OrderedDict
from collections.abc import Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from parts.sim.backdrops import room, treeline
from parts.sim.randomize import Conditions, check_ranges, draw_conditions
from parts.sim.scenery import Scenery, place_distractors
from parts.sim.texture import TrackTexture, render_texture, texture_bounds
from parts.sim.themes import Look, Theme, get_theme, widen_surface
from parts.sim.track import Track, make_track

logger = logging.getLogger(__name__)

_WORLDS: OrderedDict[tuple[Any, ...], World] = OrderedDict()
_WORLD_CACHE_SIZE = 6
_CUSTOM: dict[int, Track] = {}
_LOCK = threading.Lock()  # guards _WORLDS and _PENDING (worlds are drawn in a background thread too)
_PENDING: dict[tuple[Any, ...], Future[World]] = {}
_EXECUTOR: ThreadPoolExecutor | None = None


@dataclass(frozen=True)
class World:
    """Everything the camera needs to render one track."""

    track: Track
    theme: Theme
    conditions: Conditions
    look: Look
    texture: TrackTexture
    scenery: Scenery

    def summary(self) -> dict[str, Any]:
        """Theme, look and conditions in plain values (what an evaluation report names)."""
        return {"theme": self.theme.name, "look": self.look.summary(), "conditions": self.conditions.summary(),
                "distractors": [d.kind for d in self.scenery.distractors]}


def register_track(track: Track) -> None:
    """Make a hand-made track (see :func:`parts.sim.track.track_from_points`) drivable under its
    seed number: SimCar, evaluation and the CLI then use it instead of generating that seed."""
    if not isinstance(track, Track):
        raise TypeError(f"register_track needs a Track, got {type(track).__name__}")
    _CUSTOM[track.seed] = track
    with _LOCK:
        for key in [k for k in _WORLDS if k[0] == track.seed]:
            del _WORLDS[key]


def registered_tracks() -> dict[int, Track]:
    """The hand-made tracks registered with :func:`register_track`, by seed (a copy)."""
    return dict(_CUSTOM)


def load_track(seed: int, *, size: float = 8.0, width: float = 0.8, min_radius: float = 1.2, lanes: int = 1,
               line_width: float = 0.04, **_: Any) -> Track:
    """The track of a seed: a registered hand-made one, else a generated one (other keyword
    arguments of :func:`load_world` are accepted and ignored)."""
    if int(seed) in _CUSTOM:
        return _CUSTOM[int(seed)]
    return make_track(int(seed), size=size, width=width, min_radius=min_radius, lanes=lanes, line_width=line_width)


def conditions_for(seed: int, theme: str | Theme, randomize: int | None = None,
                   ranges: Mapping[str, Any] | None = None, lighting: float = 0.25, distractors: int = 0,
                   **_: Any) -> Conditions:
    """The conditions of track ``seed`` (see :func:`parts.sim.randomize.draw_conditions`)."""
    return draw_conditions(get_theme(theme), int(seed), randomize, check_ranges(ranges), lighting=lighting,
                           distractors=distractors)


def _key(seed: int, theme: Theme, randomize: int | None, ranges: Mapping[str, Any] | None, size: float,
         width: float, min_radius: float, lanes: int, line_width: float, res: float, lighting: float,
         distractors: int, surface_share: float) -> tuple[Any, ...]:
    range_key = tuple(sorted((k, tuple(v)) for k, v in (ranges or {}).items()))
    return (int(seed), size, width, min_radius, lanes, line_width, res, lighting, theme.name, randomize, range_key,
            distractors, float(surface_share))


def load_world(seed: int, *, theme: str | Theme = "road", randomize: int | None = None,
               ranges: Mapping[str, Any] | None = None, size: float = 8.0, width: float = 0.8,
               min_radius: float = 1.2, lanes: int = 1, line_width: float = 0.04, res: float = 0.01,
               lighting: float = 0.25, distractors: int = 0, surface_share: float = 0.0) -> World:
    """The world of a track seed in a theme (randomised with seed ``randomize`` unless None, its
    road surface from the generic pool with probability ``surface_share``); the last few are
    cached (drawing one takes a few tenths of a second of CPU at 1 cm per pixel).

    Raises:
        ThemeError, TrackError, ValueError: an unknown theme, impossible track or bad ranges.
    """
    th = get_theme(theme)
    key = _key(seed, th, randomize, ranges, size, width, min_radius, lanes, line_width, res, lighting, distractors,
               surface_share)
    with _LOCK:
        if key in _WORLDS:
            _WORLDS.move_to_end(key)
            return _WORLDS[key]
        pending = _PENDING.get(key)
    if pending is not None:
        return pending.result()  # drawn in the background (prefetch_world): wait for it
    track = load_track(seed, size=size, width=width, min_radius=min_radius, lanes=lanes, line_width=line_width)
    cond = conditions_for(seed, th, randomize, ranges, lighting, distractors)
    world = build_world(track, th, cond, res=res, surface_share=surface_share)
    _remember(key, world)
    return world


def prefetch_world(seed: int, **kwargs: Any) -> None:
    """Start drawing a world in a background thread (numpy and OpenCV release the GIL, so it runs on
    another core); :func:`load_world` with the same arguments then waits for it instead of drawing
    it again. Errors surface in that load_world call."""
    th = get_theme(kwargs.get("theme", "road"))
    args = {k: v for k, v in kwargs.items() if k != "theme"}
    key = _key(seed, th, **{**_DEFAULTS, **args})
    with _LOCK:
        if key in _WORLDS or key in _PENDING:
            return
        global _EXECUTOR
        if _EXECUTOR is None:
            _EXECUTOR = ThreadPoolExecutor(max_workers=1, thread_name_prefix="sim-world")
        future = _EXECUTOR.submit(_draw_pending, key, seed, th, args)
        _PENDING[key] = future


def _draw_pending(key: tuple[Any, ...], seed: int, theme: Theme, args: dict[str, Any]) -> World:
    try:
        a = {**_DEFAULTS, **args}
        track = load_track(seed, **a)
        cond = conditions_for(seed, theme, a["randomize"], a["ranges"], a["lighting"], a["distractors"])
        world = build_world(track, theme, cond, res=a["res"], surface_share=a["surface_share"])
        _remember(key, world)
        return world
    finally:
        with _LOCK:
            _PENDING.pop(key, None)


def _remember(key: tuple[Any, ...], world: World) -> None:
    with _LOCK:
        _WORLDS[key] = world
        _WORLDS.move_to_end(key)
        while len(_WORLDS) > _WORLD_CACHE_SIZE:
            _WORLDS.popitem(last=False)


#: load_world's defaults, for prefetch_world's cache key
_DEFAULTS: dict[str, Any] = {"randomize": None, "ranges": None, "size": 8.0, "width": 0.8, "min_radius": 1.2,
                             "lanes": 1, "line_width": 0.04, "res": 0.01, "lighting": 0.25, "distractors": 0,
                             "surface_share": 0.0}


def build_world(track: Track, theme: Theme, conditions: Conditions, *, res: float = 0.01,
                surface_share: float = 0.0) -> World:
    """Draw a world (uncached): look, distractors, cast shadows, texture, backdrop.

    Raises:
        ValueError: ``surface_share`` (SIM_ROAD_SURFACE_SHARE) outside 0..1.
    """
    if not 0.0 <= surface_share <= 1.0:
        raise ValueError(f"SIM_ROAD_SURFACE_SHARE = {surface_share!r}: use a share of tracks from 0 to 1")
    randomize = (conditions.randomize or 0) & 0xFFFFFFFF
    rng = np.random.default_rng([track.seed & 0xFFFFFFFF, randomize, 0x5CE7])
    look = theme.draw_look(rng, track.lanes, conditions.colour_jitter)
    if surface_share > 0:  # a generator of its own: every other draw stays as without it
        look = widen_surface(look, np.random.default_rng([track.seed & 0xFFFFFFFF, randomize, 0x5F0A]),
                             surface_share)
    shading = (conditions.gains, conditions.sun)
    bounds = texture_bounds(track)
    distractors = place_distractors(track, rng, conditions.distractors, theme.distractors, bounds, shading)
    shadows = cast_shadows(track, rng, theme.shadows, conditions)
    shadows += [d.shadow(conditions.sun) for d in distractors]
    texture = render_texture(track, look, conditions, res=res, ragged_edge=theme.ragged_edge, shadows=shadows,
                             shadow_blur=theme.shadow_blur, line_wear=conditions.line_wear * theme.line_wear)
    if theme.backdrop == "room":
        backdrop = room(rng, texture.bounds, conditions.gains)
    elif theme.backdrop == "treeline":
        backdrop = treeline(rng, texture.bounds, conditions.gains, (look.sky_top, look.sky_bottom), look.ground_rgb)
    else:
        backdrop = None
    # the car's shadow is as dark as the others under the sun, half as dark under indoor lamps
    own = conditions.shadow_darkness * (0.5 if theme.backdrop == "room" else 0.8) if conditions.own_shadow else 0.0
    scenery = Scenery(backdrop, distractors, conditions.sun, own, far=min(theme.far_distance, 20.0))
    logger.debug("world: track %d, theme %s, randomize %s, %d distractors", track.seed, theme.name,
                 conditions.randomize, len(distractors))
    return World(track, theme, conditions, look, texture, scenery)


def cast_shadows(track: Track, rng: np.random.Generator, kinds: tuple[str, ...],
                 conditions: Conditions) -> list[np.ndarray]:
    """Ground polygons (metres) of the shadows that trees, buildings or furniture cast across the track."""
    out: list[np.ndarray] = []
    sun = conditions.sun
    along = np.array([-sun[0], -sun[1]]) / max(math.hypot(sun[0], sun[1]), 1e-9)  # shadows point away from the sun
    across = np.array([-along[1], along[0]])
    stretch = 1.0 / max(math.sin(math.radians(conditions.sun_elevation)), 0.3)
    for _ in range(conditions.shadows):
        kind = kinds[int(rng.integers(len(kinds)))]
        s = rng.uniform(0, track.length)
        cx, cy, _h = track.pose_at(s, rng.uniform(-1.0, 1.0) * track.width)
        centre = np.array([cx, cy])
        if kind == "tree":  # a crown of overlapping discs, stretched along the light
            for _ in range(int(rng.integers(3, 7))):
                r = rng.uniform(0.25, 0.8)
                c = centre + rng.uniform(-0.6, 0.6, 2)
                a = np.linspace(0, 2 * np.pi, 20, endpoint=False)
                out.append(c + np.outer(r * stretch * np.cos(a), along) + np.outer(r * np.sin(a), across))
            trunk = rng.uniform(0.05, 0.12)
            base = centre - along * rng.uniform(1.0, 2.5) * stretch
            out.append(np.array([base - across * trunk, centre - across * trunk, centre + across * trunk,
                                 base + across * trunk]))
        elif kind == "building":  # the straight shadow edge of a wall or roof, several metres long
            length, depth = rng.uniform(4.0, 10.0), rng.uniform(0.8, 3.0) * stretch
            turn = rng.uniform(-0.5, 0.5)
            edge = np.array([math.cos(turn) * across[0] - math.sin(turn) * across[1],
                             math.sin(turn) * across[0] + math.cos(turn) * across[1]])
            a, b = centre - edge * length / 2, centre + edge * length / 2
            out.append(np.array([a, b, b - along * depth, a - along * depth]))
        else:  # furniture indoors: soft rectangles under tables and shelves
            length, depth = rng.uniform(0.4, 1.5), rng.uniform(0.3, 0.9)
            turn = rng.uniform(0, np.pi)
            d1 = np.array([math.cos(turn), math.sin(turn)]) * length / 2
            d2 = np.array([-math.sin(turn), math.cos(turn)]) * depth / 2
            out.append(np.array([centre - d1 - d2, centre + d1 - d2, centre + d1 + d2, centre - d1 + d2]))
    return out


def world_params(cfg: Any) -> dict[str, Any]:
    """The load_world() keyword arguments of a Config (all but the theme, which is per track)."""
    return {"size": cfg.SIM_TRACK_SIZE, "width": cfg.SIM_ROAD_WIDTH, "min_radius": cfg.SIM_TRACK_MIN_RADIUS,
            "lanes": cfg.SIM_LANES, "line_width": cfg.SIM_LINE_WIDTH, "res": cfg.SIM_TEXTURE_RES,
            "lighting": cfg.SIM_LIGHTING_VARIATION, "randomize": cfg.SIM_RANDOMIZE,
            "ranges": dict(cfg.SIM_RANDOMIZE_RANGES), "distractors": cfg.SIM_DISTRACTORS,
            "surface_share": cfg.SIM_ROAD_SURFACE_SHARE}

