"""Domain randomisation: the conditions of one episode (light, shadows, camera, sensor, latency,
distractors), drawn once per track from a seeded generator.

``draw_conditions(theme, track_seed, randomize, ranges)`` gives the :class:`Conditions` of a
track: with ``randomize = None`` the track keeps its theme's plain look (the per-track lighting of
``SIM_LIGHTING_VARIATION``, an ideal camera, no latency); with an integer seed every quantity of
:data:`RANGES` is drawn uniformly from its range (integers for counts, loops and JPEG quality).
The same (theme, track seed, randomize seed, ranges) always gives the same conditions, so a
randomised recording or evaluation is reproducible, and a held-out draw is just another seed.

What is drawn per episode is applied where it costs nothing per frame: light, colours, cast
shadows and distractors are painted into the track's texture and backdrop, the camera's mounting
is built into its homography. Only the sensor effects (noise, motion blur, vignetting, JPEG) run
on every frame (:mod:`parts.sim.image_sensor`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, NamedTuple

import numpy as np


class RangesError(ValueError):
    """SIM_RANDOMIZE_RANGES names an unknown quantity or gives a pair outside its limits."""


class Interval(NamedTuple):
    """A randomised quantity: its default range, what the renderer can do, and what it means."""

    low: float
    high: float
    meaning: str
    limit_low: float  # SIM_RANDOMIZE_RANGES may not go below this ...
    limit_high: float  # ... nor above this
    integer: bool = False  # drawn as an integer (counts, loops, JPEG quality)


#: every randomised quantity (SIM_RANDOMIZE_RANGES overrides low and high), in the order drawn
RANGES: dict[str, Interval] = {
    "light": Interval(0.55, 1.4, "overall light level, x brightness", 0.05, 4.0),
    "colour_temperature": Interval(3000.0, 8500.0, "colour temperature of the light, kelvin (6500 = neutral)",
                                1500.0, 15000.0),
    "contrast": Interval(0.8, 1.2, "contrast around the mean colour, x", 0.2, 3.0),
    "shade": Interval(0.0, 0.35, "soft large-scale light variation over the ground, strength", 0.0, 1.0),
    "shadows": Interval(0, 6, "shadows cast across the track (trees, buildings; furniture indoors), count", 0, 40,
                     True),
    "shadow_darkness": Interval(0.3, 0.7, "light blocked in a shadow, fraction", 0.0, 0.95),
    "sun_elevation": Interval(25.0, 75.0, "height of the sun (indoors: of the lamps, at least 60), degrees", 5.0, 90.0),
    "camera_height": Interval(-0.03, 0.03, "camera height offset from SIM_CAMERA_HEIGHT, metres", -0.15, 0.5),
    "camera_pitch": Interval(-4.0, 4.0, "camera tilt offset from SIM_CAMERA_PITCH, degrees (+ = down)", -30.0, 30.0),
    "camera_fov": Interval(-8.0, 8.0, "field of view offset from SIM_CAMERA_FOV, degrees", -60.0, 60.0),
    "vignetting": Interval(0.0, 0.45, "darkening of the image corners by the lens, fraction", 0.0, 0.9),
    "noise": Interval(0.0, 8.0, "sensor noise, standard deviation in 0-255 units", 0.0, 60.0),
    "motion_blur": Interval(0.0, 0.015, "exposure time for motion blur at speed, seconds", 0.0, 0.1),
    "jpeg_quality": Interval(35, 95, "JPEG quality of the camera's compression (every frame)", 1, 100, True),
    "latency": Interval(0, 2, "camera-to-command latency, loops (commands act this many loops late)", 0, 20, True),
    "distractors": Interval(0, 8, "cones, boxes and parked cars beside the track, count", 0, 60, True),
    "colour_jitter": Interval(0.0, 0.12, "per-channel variation of ground, road, line and sky colours, fraction",
                           0.0, 0.5),
    "line_wear": Interval(0.0, 0.8, "worn paint or tape: lines fade in patches by up to this fraction (x the "
                       "theme's wear)", 0.0, 1.0),
}


def check_ranges(overrides: Mapping[str, Any] | None) -> dict[str, tuple[float, float]]:
    """The ranges to draw from: :data:`RANGES` with the overrides of SIM_RANDOMIZE_RANGES applied.

    Raises:
        RangesError: an unknown name, a malformed pair, low > high, or a value out of its limits.
    """
    ranges = {k: (r.low, r.high) for k, r in RANGES.items()}
    for name, value in (overrides or {}).items():
        if name not in RANGES:
            raise RangesError(f"SIM_RANDOMIZE_RANGES: unknown quantity {name!r}; known: {', '.join(RANGES)}")
        try:
            lo, hi = (float(v) for v in value)
        except (TypeError, ValueError):
            raise RangesError(f"SIM_RANDOMIZE_RANGES[{name!r}] = {value!r}: give a (low, high) pair of numbers, "
                             f"e.g. {RANGES[name][:2]}") from None
        r = RANGES[name]
        if not r.limit_low <= lo <= hi <= r.limit_high:
            raise RangesError(f"SIM_RANDOMIZE_RANGES[{name!r}] = {value!r}: need {r.limit_low} <= low <= high <= "
                             f"{r.limit_high} ({r.meaning})")
        ranges[name] = (lo, hi)
    return ranges


@dataclass(frozen=True)
class Conditions:
    """Everything drawn for one track/episode besides its geometry (hashable, JSON-able)."""

    theme: str
    randomize: int | None = None  # seed of the draw; None = not randomised
    light: float = 1.0
    colour_temperature: float = 6500.0
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)  # per-track colour cast (SIM_LIGHTING_VARIATION)
    contrast: float = 1.0
    shade: float = 0.0
    shadows: int = 0
    shadow_darkness: float = 0.5
    sun_azimuth: float = 0.8  # radians, world frame, direction towards the sun
    sun_elevation: float = 50.0  # degrees
    own_shadow: bool = False  # the car casts its own shadow on the ground
    camera_height: float = 0.0
    camera_pitch: float = 0.0
    camera_fov: float = 0.0
    vignetting: float = 0.0
    noise: float = 0.0
    motion_blur: float = 0.0
    jpeg_quality: int | None = None
    latency: int = 0
    distractors: int = 0
    colour_jitter: float = 0.0
    line_wear: float = 0.0

    @property
    def gains(self) -> np.ndarray:
        """RGB multipliers of the light: level x colour temperature x tint."""
        return self.light * kelvin_gains(self.colour_temperature) * np.asarray(self.tint)

    @property
    def sun(self) -> np.ndarray:
        """Unit vector from the ground towards the sun (world frame, z up)."""
        el = math.radians(self.sun_elevation)
        return np.array([math.cos(self.sun_azimuth) * math.cos(el), math.sin(self.sun_azimuth) * math.cos(el),
                         math.sin(el)])

    def summary(self) -> dict[str, Any]:
        """The conditions as plain values, rounded (for reports)."""
        out: dict[str, Any] = {}
        for k, v in asdict(self).items():
            if isinstance(v, float):
                v = round(v, 4)
            elif isinstance(v, tuple):
                v = [round(x, 4) for x in v]
            out[k] = v
        return out


def draw_conditions(theme: Any, track_seed: int, randomize: int | None,
                    ranges: Mapping[str, tuple[float, float]] | None = None, *, lighting: float = 0.25,
                    distractors: int = 0) -> Conditions:
    """The conditions of track ``track_seed`` in ``theme`` for the randomisation seed ``randomize``.

    Args:
        theme: a :class:`parts.sim.themes.Theme` (its name and light elevation are used).
        track_seed: the track's seed.
        randomize: None = the theme's plain look; an int = seed of a randomised draw.
        ranges: the ranges to draw from (:func:`check_ranges`; default :data:`RANGES`).
        lighting: SIM_LIGHTING_VARIATION, the per-track light variation when not randomised.
        distractors: SIM_DISTRACTORS, how many stand beside the track when not randomised.
    """
    if randomize is None:
        # the light of SIM_LIGHTING_VARIATION, drawn from the track seed as before themes existed
        rng = np.random.default_rng([int(track_seed) & 0xFFFFFFFF, 0x7E47])
        u = rng.uniform(-1.0, 1.0, 6)
        return Conditions(
            theme=theme.name, light=1.0 + lighting * u[0], contrast=1.0 + 0.6 * lighting * u[1],
            tint=tuple(float(1.0 + 0.3 * lighting * x) for x in u[2:5]),  # type: ignore[arg-type]
            shade=1.2 * lighting, sun_azimuth=float(math.pi * u[5]), distractors=int(distractors))
    r = ranges if ranges is not None else check_ranges(None)
    rng = np.random.default_rng([int(track_seed) & 0xFFFFFFFF, int(randomize) & 0xFFFFFFFF, 0xD0A1])
    values: dict[str, Any] = {}
    for name in RANGES:  # a fixed order: the draw of one quantity never depends on another's range
        lo, hi = r[name]
        if RANGES[name].integer:
            values[name] = int(rng.integers(round(lo), round(hi) + 1))
        else:
            values[name] = float(rng.uniform(lo, hi))
    azimuth = float(rng.uniform(-math.pi, math.pi))
    if theme.light_elevation is not None:
        lo, hi = theme.light_elevation
        values["sun_elevation"] = lo + (hi - lo) * (values["sun_elevation"] - r["sun_elevation"][0]) / max(
            r["sun_elevation"][1] - r["sun_elevation"][0], 1e-9)
    return Conditions(theme=theme.name, randomize=int(randomize), sun_azimuth=azimuth, own_shadow=True, **values)


def kelvin_gains(kelvin: float) -> np.ndarray:
    """RGB multipliers of a light of colour temperature ``kelvin`` as the camera sees it.

    The black-body colour (Tanner Helland's fit, good to a few percent from 1500 to 15000 K)
    relative to 6500 K, of which the camera's automatic white balance removes half (square root
    of the ratio), scaled to keep the luma: 3000 K gives about (1.16, 0.97, 0.77), 8500 K about
    (0.97, 1.0, 1.07).
    """
    def rgb(k: float) -> np.ndarray:
        t = k / 100.0
        if t <= 66:
            r, g = 255.0, 99.4708025861 * math.log(t) - 161.1195681661
            b = 0.0 if t <= 19 else 138.5177312231 * math.log(t - 10) - 305.0447927307
        else:
            r = 329.698727446 * (t - 60) ** -0.1332047592
            g = 288.1221695283 * (t - 60) ** -0.0755148492
            b = 255.0
        return np.clip(np.array([r, g, b]), 1.0, 255.0)

    gains = np.sqrt(rgb(float(kelvin)) / rgb(6500.0))
    return gains / float(np.dot(gains, (0.299, 0.587, 0.114)))
