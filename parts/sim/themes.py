"""Visual themes of the simulated world: what the ground, the road, its lines and the horizon look like.

A theme is data: the materials it may draw the ground and the road with (see
:mod:`parts.sim.surfaces`), the styles of its edge and centre lines, what stands around the track
(an open horizon, the walls of a room, a tree line: :mod:`parts.sim.backdrops`), which distractors
stand beside the road and which shadows fall across it. Every track draws its own :class:`Look`
from its theme with a seeded generator (a material, colours, line colours and patterns), so tracks
of one theme differ from each other as real tracks do.

Themes:

* ``road``: asphalt with white edge lines and a dashed centre line (yellow; white between two
  lanes) on grass, dry grass, earth, sand or pavement, under an open sky.
* ``indoor``: a DonkeyCar-style track taped on a concrete, wooden or carpet floor (tape white,
  yellow or blue, solid or dashed), in a room whose walls stand at the edge of the floor.
* ``park``: a path of asphalt, gravel or pavers through a lawn, no painted lines (the edges are
  only where the paving meets the grass), a tree line around the lawn. One lane only.

Road-surface randomisation (SIM_ROAD_SURFACE_SHARE, :func:`widen_surface`) swaps the surface a
share of tracks is driven on for one of :data:`SURFACE_POOL`: generic surfaces in broadly drawn
colours, no theme's palette, so a pilot learns that a road is not always asphalt.
"""

from __future__ import annotations

import colorsys
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

RGB = tuple[int, int, int]


class ThemeError(ValueError):
    """An unknown theme, or a theme that cannot draw the requested track."""


@dataclass(frozen=True)
class Material:
    """A surface (a name of :data:`parts.sim.surfaces.SURFACES`) and the colours it comes in."""

    surface: str
    colours: tuple[RGB, ...]


@dataclass(frozen=True)
class LineStyle:
    """How a theme paints one kind of line: colour and pattern choices, width, dash lengths."""

    colours: tuple[RGB, ...]
    patterns: tuple[str, ...] = ("solid",)  # "solid", "dashed" or "none"; repeat one to weight it
    width: float = 1.0  # times SIM_LINE_WIDTH
    dash: tuple[float, float] = (0.2, 0.2)  # metres on, off
    opacity: tuple[float, float] = (0.8, 0.95)


@dataclass(frozen=True)
class Paint:
    """One drawn line: its colour, pattern, width factor, dash lengths and opacity."""

    colour: RGB
    pattern: str
    width: float
    dash: tuple[float, float]
    opacity: float


@dataclass(frozen=True)
class Look:
    """What one track of a theme looks like (drawn by :meth:`Theme.draw_look`)."""

    theme: str
    ground: str
    ground_rgb: RGB
    road: str | None  # None: the track is marked on the floor only (tape)
    road_rgb: RGB | None
    edge: Paint | None
    centre: Paint | None
    sky_top: RGB  # sky, or ceiling in a room
    sky_bottom: RGB

    def summary(self) -> dict[str, Any]:
        """The choices in plain values (for reports)."""
        def paint(p: Paint | None) -> str | None:
            return None if p is None else f"{p.pattern} rgb{p.colour}"

        return {"ground": self.ground, "road": self.road, "edge_lines": paint(self.edge),
                "centre_line": paint(self.centre)}


@dataclass(frozen=True)
class Theme:
    """A visual theme: materials, line styles, backdrop, distractors and shadows (see module doc)."""

    name: str
    description: str
    ground: tuple[Material, ...]
    road: tuple[Material, ...]  # empty: no road surface, the track is taped on the ground
    edge: LineStyle | None
    centre: LineStyle | None  # the centre line of a one-lane track
    divider: LineStyle | None  # the line between two lanes; None: the theme has no two-lane variant
    skies: tuple[tuple[RGB, RGB], ...]  # (top, horizon) colours of the sky or the ceiling
    backdrop: str | None = None  # "room", "treeline" (parts.sim.backdrops) or None: open horizon
    ragged_edge: float = 0.0  # metres: how irregular the road's edge is (grass growing over it)
    distractors: tuple[str, ...] = ("cone", "box", "car")
    shadows: tuple[str, ...] = ("tree", "building")  # what casts shadows across the road
    shadow_blur: float = 0.03  # metres: soft edges of cast shadows (penumbra)
    light_elevation: tuple[float, float] | None = None  # degrees; indoor lamps hang high
    far_distance: float = 12.0  # metres of ground the camera renders before the horizon haze
    line_wear: float = 1.0  # share of the randomised line wear its lines take (tape wears less than paint)

    def draw_look(self, rng: np.random.Generator, lanes: int = 1, colour_jitter: float = 0.0) -> Look:
        """Choose this track's materials, colours and line styles.

        Args:
            rng: the track's generator (seeded: same track and seed, same look).
            lanes: 1 or 2; two lanes need a theme with a lane divider.
            colour_jitter: each chosen colour is scaled per channel by U(1 - j, 1 + j).

        Raises:
            ThemeError: two lanes on a theme without a two-lane variant.
        """
        if lanes == 2 and self.divider is None:
            raise ThemeError(f"theme {self.name!r} has no two-lane variant (it has no lane lines): "
                             "use SIM_LANES = 1 or the road or indoor theme")

        def colour(choices: tuple[RGB, ...]) -> RGB:
            c = np.asarray(choices[int(rng.integers(len(choices)))], float)
            c = c * rng.uniform(0.93, 1.07)  # every track a slightly different shade
            # drawn even without jitter, so that the jitter never changes the other choices
            c = c * (1.0 + colour_jitter * rng.uniform(-1.0, 1.0, 3))
            return tuple(int(v) for v in np.clip(c, 0, 255))  # type: ignore[return-value]

        def paint(style: LineStyle | None) -> Paint | None:
            if style is None:
                return None
            pattern = style.patterns[int(rng.integers(len(style.patterns)))]
            c = colour(style.colours)
            if pattern == "none":
                return None
            return Paint(c, pattern, style.width, style.dash, float(rng.uniform(*style.opacity)))

        ground = self.ground[int(rng.integers(len(self.ground)))]
        ground_rgb = colour(ground.colours)
        road = self.road[int(rng.integers(len(self.road)))] if self.road else None
        road_rgb = colour(road.colours) if road else None
        edge = paint(self.edge)
        centre = paint(self.divider if lanes == 2 else self.centre)
        top, bottom = self.skies[int(rng.integers(len(self.skies)))]
        return Look(self.name, ground.surface, ground_rgb, road.surface if road else None, road_rgb,
                    edge, centre, colour((top,)), colour((bottom,)))


@dataclass(frozen=True)
class PoolSurface:
    """A generic surface of :data:`SURFACE_POOL` and the broad ranges its colour is drawn from."""

    surface: str  # a name of parts.sim.surfaces.SURFACES
    hue: tuple[float, float]  # degrees: 0 red, 30 brown, 60 yellow (a low saturation leaves it grey)
    saturation: tuple[float, float]  # 0 grey .. 1 pure colour
    value: tuple[float, float]  # brightness of the brightest channel, 0-255

    def colour(self, rng: np.random.Generator) -> RGB:
        """A colour drawn uniformly in hue, saturation and brightness (three draws, always)."""
        h, s, v = (rng.uniform(*r) for r in (self.hue, self.saturation, self.value))
        r, g, b = colorsys.hsv_to_rgb((h / 360.0) % 1.0, s, v / 255.0)
        return int(round(r * 255)), int(round(g * 255)), int(round(b * 255))


#: the surfaces of road-surface randomisation (SIM_ROAD_SURFACE_SHARE): ranges wide enough to hold
#: fresh and worn, light and dark, grey and coloured versions of each, drawn afresh for each track
SURFACE_POOL: tuple[PoolSurface, ...] = (
    PoolSurface("asphalt", (0.0, 360.0), (0.0, 0.1), (35.0, 135.0)),  # fresh black to worn pale grey
    PoolSurface("concrete", (0.0, 360.0), (0.0, 0.1), (115.0, 215.0)),
    PoolSurface("gravel", (20.0, 50.0), (0.05, 0.4), (95.0, 210.0)),  # grey to beige and ochre
    PoolSurface("pavers", (0.0, 45.0), (0.0, 0.5), (80.0, 200.0)),  # grey concrete to red clay
    PoolSurface("dirt", (18.0, 45.0), (0.2, 0.55), (75.0, 175.0)),  # packed earth
)


def widen_surface(look: Look, rng: np.random.Generator, share: float) -> Look:
    """With probability ``share``, the look with the surface the car drives on drawn from
    :data:`SURFACE_POOL`: the road, or the floor of a theme whose track is taped on the floor.

    Lines, verges and sky stay as the theme drew them. ``rng`` is a generator of its own (seeded by
    the track and the randomisation seed), so no other draw changes; every value is drawn whatever
    ``share`` is, so a track that takes the pool gets the same surface at any share.
    """
    take = rng.random() < share
    pick = SURFACE_POOL[int(rng.integers(len(SURFACE_POOL)))]
    rgb = pick.colour(rng)
    if not take:
        return look
    if look.road is not None:
        return replace(look, road=pick.surface, road_rgb=rgb)
    return replace(look, ground=pick.surface, ground_rgb=rgb)


_WHITE: tuple[RGB, ...] = ((235, 235, 230), (228, 228, 218))
_YELLOW: tuple[RGB, ...] = ((230, 190, 40), (240, 200, 70))
_TAPE_WHITE, _TAPE_YELLOW, _TAPE_BLUE = (240, 240, 236), (238, 200, 40), (70, 140, 225)  # blue: painter's tape
_OUTDOOR_SKIES: tuple[tuple[RGB, RGB], ...] = (
    ((90, 140, 220), (200, 215, 235)), ((70, 120, 210), (185, 205, 235)), ((140, 160, 190), (215, 218, 222)))

THEMES: dict[str, Theme] = {
    "road": Theme(
        name="road",
        description="asphalt road, white edge lines, dashed centre line, grass or earth verges, open sky",
        ground=(Material("grass", ((70, 120, 50), (85, 125, 55))),
                Material("grass", ((120, 130, 70), (135, 125, 80))),  # dry grass
                Material("dirt", ((140, 110, 80), (175, 160, 120))),  # earth, sand
                Material("concrete", ((150, 150, 140),))),  # pavement
        road=(Material("asphalt", ((60, 60, 62), (75, 75, 75), (90, 88, 85), (70, 72, 76))),),
        edge=LineStyle(_WHITE),
        centre=LineStyle(_YELLOW, ("dashed",), width=0.8),
        divider=LineStyle(_WHITE, ("dashed",), width=0.8),
        skies=_OUTDOOR_SKIES,
    ),
    "indoor": Theme(
        name="indoor",
        description="DonkeyCar-style track: tape on concrete, wood or carpet, walls at the edge of the floor",
        ground=(Material("concrete", ((150, 150, 145), (125, 125, 120), (172, 166, 156))),
                Material("wood", ((160, 115, 70), (185, 145, 95), (125, 85, 55))),
                Material("carpet", ((95, 80, 110), (70, 82, 102), (120, 110, 95), (90, 96, 90), (125, 62, 60)))),
        road=(),
        edge=LineStyle((_TAPE_WHITE, _TAPE_YELLOW, _TAPE_BLUE), ("solid", "solid", "solid", "dashed"),
                       width=1.2, dash=(0.3, 0.15), opacity=(0.9, 0.97)),
        centre=LineStyle((_TAPE_WHITE, _TAPE_YELLOW, _TAPE_BLUE), ("dashed", "dashed", "solid", "none"),
                         width=1.2, dash=(0.3, 0.2), opacity=(0.9, 0.97)),
        divider=LineStyle((_TAPE_WHITE, _TAPE_YELLOW, _TAPE_BLUE), ("dashed", "dashed", "solid"),
                          width=1.2, dash=(0.3, 0.2), opacity=(0.9, 0.97)),
        skies=(((205, 205, 200), (175, 175, 170)), ((228, 226, 220), (192, 190, 185))),  # ceiling
        backdrop="room",
        distractors=("cone", "box", "car"),
        shadows=("furniture",),
        shadow_blur=0.12,
        line_wear=0.5,
        light_elevation=(60.0, 85.0),
        far_distance=30.0,  # the whole room: the walls stand beyond 12 m in its corners
    ),
    "park": Theme(
        name="park",
        description="paved path through a lawn, no painted lines, a tree line around the lawn",
        ground=(Material("grass", ((70, 120, 50), (60, 110, 45), (92, 132, 60))),),
        road=(Material("asphalt", ((95, 95, 95), (110, 108, 104))),
              Material("gravel", ((172, 160, 138), (150, 142, 128))),
              Material("pavers", ((150, 146, 140), (160, 122, 100)))),
        edge=None,
        centre=None,
        divider=None,
        skies=_OUTDOOR_SKIES,
        backdrop="treeline",
        ragged_edge=0.04,
        distractors=("cone", "box", "car"),
        shadows=("tree", "tree", "building"),
        far_distance=30.0,
    ),
}


def get_theme(name: str) -> Theme:
    """The theme called ``name``.

    Raises:
        ThemeError: no such theme (the message lists them).
    """
    if isinstance(name, Theme):
        return name
    try:
        return THEMES[name]
    except (KeyError, TypeError):
        raise ThemeError(f"unknown theme {name!r}: use one of {', '.join(THEMES)} (SIM_THEME)") from None


def theme_list(value: str | list[str] | tuple[str, ...]) -> list[str]:
    """SIM_THEME as a list of theme names (a single name, a list, or "road,indoor"), each checked.

    Raises:
        ThemeError: empty or unknown names.
    """
    names = value.split(",") if isinstance(value, str) else list(value)
    names = [str(n).strip() for n in names if str(n).strip()]
    if not names:
        raise ThemeError(f"SIM_THEME = {value!r} names no theme: use one of {', '.join(THEMES)}")
    for n in names:
        get_theme(n)
    return names


def theme_of(themes: list[str] | tuple[str, ...], index: int) -> str:
    """The theme of the ``index``-th track of a track list: themes are dealt to the tracks in turn."""
    return themes[index % len(themes)]

