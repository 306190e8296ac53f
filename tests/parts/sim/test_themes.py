"""Themes, domain randomisation, distractors, backdrops and sensor effects of the simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parts.sim.backdrops import Backdrop
from parts.sim.camera import PinholeCamera
from parts.sim.image_sensor import ImageSensor
from parts.sim.randomize import RANGES, check_ranges, draw_conditions, kelvin_gains
from parts.sim.scenery import CLEARANCE, Scenery, make_distractor, place_distractors
from parts.sim.simulator import SimCar
from parts.sim.texture import TrackTexture, texture_bounds
from parts.sim.themes import THEMES, ThemeError, get_theme, theme_list
from parts.sim.world import load_track, load_world, prefetch_world


def colour_distance(img: np.ndarray, rgb) -> np.ndarray:
    return np.abs(img.astype(int) - np.asarray(rgb, int)).sum(axis=-1)


def test_the_expert_does_not_draw_images(cfg):
    sim = SimCar.from_config(cfg.replace(SIM_THEME="indoor", SIM_RANDOMIZE=1), seeds=[3], render=False)
    assert sim.world is None and sim.run(0.0, 0.3)[0] is None
    assert sim.conditions.randomize == 1  # conditions (latency) still apply


def test_themes_look_like_what_they_claim(world):
    # road: blue sky above, grey asphalt ahead
    road = load_world(21, theme="road", **world)
    cam = PinholeCamera(160, 120)
    x, y, h = road.track.pose_at(2.0)
    img = cam.render(road.texture, x, y, h, scenery=road.scenery)
    sky = img[:10].reshape(-1, 3).astype(float)
    assert (sky[:, 2] > sky[:, 0] + 20).mean() > 0.9
    assert road.look.road == "asphalt" and road.look.edge is not None and road.look.centre is not None

    # indoor: tape on the floor (no road surface), a wall (not sky) above the floor
    indoor = load_world(21, theme="indoor", **world)
    assert indoor.look.road is None and indoor.look.ground in ("concrete", "wood", "carpet")
    assert indoor.look.edge is not None and indoor.look.edge.colour is not None
    cam_in = PinholeCamera(160, 120, max_distance=indoor.theme.far_distance)
    img = cam_in.render(indoor.texture, x, y, h, scenery=indoor.scenery)
    top = img[:8].reshape(-1, 3).astype(float)
    assert (top[:, 2] > top[:, 0] + 20).mean() < 0.5  # walls and ceiling, no blue sky
    bare = cam_in.render(indoor.texture, x, y, h)  # the same view without the walls
    assert np.abs(img[:30].astype(int) - bare[:30].astype(int)).mean() > 5
    # the edge tape is painted along the road's edges (solid or dashed: most points)
    tex = indoor.texture
    tape = np.asarray(indoor.look.edge.colour) * indoor.conditions.gains
    edge = -(indoor.track.width / 2 - indoor.track.line_width / 2 - 0.01)
    s_at = np.linspace(0, indoor.track.length, 200, endpoint=False)

    def texels(offset: float) -> np.ndarray:
        px = tex.to_pixels(np.array([indoor.track.pose_at(v, offset)[:2] for v in s_at])).round().astype(int)
        return tex.image[px[:, 1], px[:, 0]]

    on_tape = colour_distance(texels(edge), tape) < colour_distance(texels(edge + 0.15), tape)
    assert on_tape.mean() > 0.6
    # the camera shows that floor where the geometry says (the walls do not cover it)
    ex, ey, _ = indoor.track.pose_at(2.0 + 0.2 + 1.0, edge)
    c, s = math.cos(h), math.sin(h)
    u, v = cam_in.ground_to_image(np.array([[(ex - x) * c + (ey - y) * s, -(ex - x) * s + (ey - y) * c]]))[0]
    texel = tex.image[tuple(tex.to_pixels(np.array([[ex, ey]])).round().astype(int)[0][::-1])]
    assert colour_distance(img[int(round(v)), int(round(u))], texel) < 60

    # park: a path on grass without painted lines; the lawn is green, the path is not
    park = load_world(21, theme="park", **world)
    assert park.look.edge is None and park.look.centre is None
    assert park.look.road in ("asphalt", "gravel", "pavers") and park.look.ground == "grass"
    tex = park.texture.image.astype(int)
    greenish = (tex[..., 1] > tex[..., 0] + 28) & (tex[..., 1] > tex[..., 2] + 28)  # beyond any tint
    px = park.texture.to_pixels(park.track.points).astype(int)
    assert greenish[px[:, 1], px[:, 0]].mean() < 0.05  # the centre line runs on paving
    assert greenish.mean() > 0.6  # most of the ground is lawn
    whites = (tex.min(axis=-1) > 215).mean()
    assert whites < 0.001  # no white paint anywhere


def test_two_lanes_where_the_theme_has_lanes(world):
    for name in ("road", "indoor"):
        w = load_world(22, theme=name, lanes=2, width=1.2, **world)
        assert w.look.centre is not None and w.look.centre.pattern in ("dashed", "solid")
    with pytest.raises(ThemeError, match="no two-lane variant"):
        load_world(22, theme="park", lanes=2, width=1.2, **world)


def test_theme_names_are_checked():
    assert theme_list("road, indoor") == ["road", "indoor"] and theme_list(["park"]) == ["park"]
    with pytest.raises(ThemeError, match="road, indoor, park"):
        get_theme("desert")
    with pytest.raises(ThemeError, match="names no theme"):
        theme_list("")
    from parts.sim.surfaces import SURFACES

    for theme in THEMES.values():  # every material a theme names exists
        assert {m.surface for m in theme.ground + theme.road} <= set(SURFACES)


def test_randomised_draws_are_reproducible_and_within_their_ranges():
    theme = get_theme("road")
    ranges = check_ranges(None)
    draws = [draw_conditions(theme, seed, 3, ranges) for seed in range(200)]
    assert draws[7] == draw_conditions(theme, 7, 3, ranges)  # same seeds, same conditions
    assert draws[7] != draw_conditions(theme, 7, 4, ranges)  # another randomisation seed
    for name, (lo, hi, *_) in RANGES.items():
        values = [getattr(d, name) for d in draws]
        assert all(lo <= v <= hi for v in values), name
        assert max(values) - min(values) > 0.6 * (hi - lo), name  # the whole range is used
    assert {d.latency for d in draws} == {0, 1, 2}
    assert all(isinstance(d.jpeg_quality, int) for d in draws)
    indoor = [draw_conditions(get_theme("indoor"), seed, 3, ranges) for seed in range(50)]
    assert all(60.0 <= d.sun_elevation <= 85.0 for d in indoor)  # lamps hang high
    plain = draw_conditions(theme, 7, None, ranges, lighting=0.25)
    assert plain.latency == 0 and plain.jpeg_quality is None and plain.camera_pitch == 0 and not plain.own_shadow
    assert abs(plain.light - 1.0) <= 0.25


def test_randomisation_ranges_are_checked():
    assert check_ranges({"latency": (1, 1)})["latency"] == (1.0, 1.0)
    for bad, message in [({"lite": (0, 1)}, "unknown quantity 'lite'"), ({"light": 2}, "pair"),
                         ({"light": (1.5, 1.0)}, "low <= high"), ({"jpeg_quality": (0, 200)}, "1 <= low")]:
        with pytest.raises(ValueError, match=message):
            check_ranges(bad)
    gains = kelvin_gains(3000)
    assert gains[0] > 1.0 > gains[2] and kelvin_gains(6500) == pytest.approx([1, 1, 1])


def test_randomised_tracks_differ_and_repeat(cfg):
    def frames(randomize: int, n: int = 25) -> list[np.ndarray]:
        sim = SimCar.from_config(cfg.replace(SIM_THEME="indoor", SIM_RANDOMIZE=randomize), seeds=[31])
        return [sim.run(0.1, 0.5)[0] for _ in range(n)]

    a, b, c = frames(1), frames(1), frames(2)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert np.abs(a[-1].astype(int) - c[-1].astype(int)).mean() > 5


def test_camera_jitter_and_latency_follow_the_conditions(cfg):
    c = cfg.replace(SIM_RANDOMIZE=4, SIM_RANDOMIZE_RANGES={"latency": (2, 2), "camera_pitch": (3, 3),
                                                           "camera_height": (0.02, 0.02)})
    sim = SimCar.from_config(c, seeds=[5])
    assert sim.camera.pitch_deg == pytest.approx(cfg.SIM_CAMERA_PITCH + 3)
    assert sim.camera.height_m == pytest.approx(cfg.SIM_CAMERA_HEIGHT + 0.02)
    speeds = [sim.step(0.0, 1.0).speed for _ in range(4)]
    assert speeds[:2] == [0.0, 0.0] and speeds[2] > 0  # full throttle acts two loops late
    sim.reset("nearest")  # a reset drops the commands in flight
    assert [sim.step(0.0, 1.0).speed for _ in range(3)][:2] == [0.0, 0.0]


def test_distractors_never_stand_on_the_road(world):
    shading = (np.ones(3), np.array([0.5, 0.5, 0.7]))
    placed = 0
    for seed in range(40, 70):
        track = load_track(seed)
        bounds = texture_bounds(track)
        for d in place_distractors(track, np.random.default_rng(seed), 8, ("cone", "box", "car"), bounds, shading):
            placed += 1
            for vx, vy, _ in d.vertices:
                assert abs(track.project((vx, vy)).cte) >= track.width / 2 + CLEARANCE - 1e-6, (seed, d.kind)
                assert bounds[0] < vx < bounds[2] and bounds[1] < vy < bounds[3]
    assert placed > 200  # nearly 8 per track fit
    counts = [len(load_world(s, randomize=s, **world).scenery.distractors) for s in range(60, 64)]
    assert max(counts) > 0 and all(c <= RANGES["distractors"].high for c in counts)


def synthetic_world(size: float = 10.0):
    """A green floor of size x size metres with red walls 2 m high, and a camera looking along +x."""
    res = 0.02
    n = int(size / res)
    tex = TrackTexture(np.full((n, n, 3), (0, 200, 0), np.uint8), res, 0.0, size, (0, 200, 0), (0, 0, 255),
                       (0, 0, 255))
    wall = np.full((int(2.0 / 0.025), int(4 * size / 0.025), 3), (220, 0, 0), np.uint8)
    backdrop = Backdrop(np.concatenate([wall, wall], axis=1), 0.025, 2.0, (0.0, 0.0, size, size))
    return tex, backdrop


def test_walls_meet_the_floor_where_the_geometry_says():
    tex, backdrop = synthetic_world()
    cam = PinholeCamera(160, 120, max_distance=30.0)
    x, y = 4.8, 5.0  # camera at x = 5.0 (0.2 m ahead), 5 m from the wall at x = 10
    img = cam.render(tex, x, y, 0.0, scenery=Scenery(backdrop))
    uv, _ = cam.project(np.array([[10.0, 5.0, 0.0], [10.0, 5.0, 2.0]]), x, y, 0.0)
    base_row, top_row = uv[0, 1], uv[1, 1]
    col = img[:, 80]
    red = (col[:, 0] > 150) & (col[:, 1] < 60)
    green = (col[:, 1] > 150) & (col[:, 0] < 60)
    assert red[int(top_row) + 2:int(base_row) - 1].all()  # wall between its top and its base
    assert green[int(base_row) + 2:].all()  # floor below the base
    assert not red[:int(top_row) - 1].any()  # ceiling (the sky colour here) above the wall
    # turned to look into a corner (across the seam of the panorama), still walls then floor
    img = cam.render(tex, 8.0, 8.0, math.radians(45), scenery=Scenery(backdrop))
    assert ((img[20:30, :, 0] > 150) & (img[20:30, :, 1] < 60)).mean() > 0.9


def test_distractors_are_drawn_where_they_stand():
    tex, _ = synthetic_world()
    rng = np.random.default_rng(0)
    box = make_distractor("box", 7.0, 5.0, 0.0, rng, (np.ones(3), np.array([0.0, 0.0, 1.0])))
    cam = PinholeCamera(160, 120)
    img = cam.render(tex, 4.8, 5.0, 0.0, scenery=Scenery(distractors=[box], far=12.0))
    u, v = cam.project(np.array([[7.0, 5.0, 0.05]]), 4.8, 5.0, 0.0)[0][0]
    assert colour_distance(img[int(v), int(u)], (0, 200, 0)) > 100  # the box hides the floor there
    behind = cam.render(tex, 9.0, 5.0, 0.0, scenery=Scenery(distractors=[box], far=12.0))
    assert (colour_distance(behind[70:], (0, 200, 0)) < 10).all()  # not drawn when behind the camera


def test_own_shadow_falls_away_from_the_sun():
    tex, _ = synthetic_world()
    cam = PinholeCamera(160, 120)
    behind = Scenery(sun=np.array([-0.7, 0.0, 0.7]), own_shadow=0.5)  # sun behind: shadow ahead
    ahead = Scenery(sun=np.array([0.7, 0.0, 0.7]), own_shadow=0.5)
    lit = cam.render(tex, 5.0, 5.0, 0.0)[-10:, 60:100, 1].mean()
    assert cam.render(tex, 5.0, 5.0, 0.0, scenery=behind)[-10:, 60:100, 1].mean() < 0.7 * lit
    assert cam.render(tex, 5.0, 5.0, 0.0, scenery=ahead)[-5:, 75:85, 1].mean() > 0.6 * lit


def test_sensor_effects():
    rng = np.random.default_rng(0)
    img = np.clip(rng.normal(128, 40, (120, 160, 3)), 0, 255).astype(np.uint8)
    vig = ImageSensor(160, 120, vignetting=0.4).apply(img.copy())
    assert vig[0, 0].mean() < 0.7 * img[0, 0].mean() + 2
    assert vig[60, 80].mean() == pytest.approx(img[60, 80].mean(), abs=3)
    jpeg = ImageSensor(160, 120, jpeg_quality=20).apply(img.copy())
    assert 3 < np.abs(jpeg.astype(int) - img.astype(int)).mean() < 40
    still = ImageSensor(160, 120, motion_blur=0.02).apply(img.copy(), speed=0.0)
    moving = ImageSensor(160, 120, motion_blur=0.02).apply(img.copy(), speed=2.0)
    assert np.array_equal(still, img)
    rough = lambda a: np.abs(np.diff(a[100:].astype(int), axis=0)).mean()  # noqa: E731
    assert rough(moving) < 0.5 * rough(img) and np.array_equal(moving[:50], img[:50])
    with pytest.raises(ValueError, match="JPEG"):
        ImageSensor(160, 120, jpeg_quality=0)


def test_the_documented_ranges_are_the_ranges():
    import re
    from pathlib import Path

    doc = (Path(__file__).parents[3] / "docs" / "simulator.md").read_text()
    rows = re.findall(r"^\| `(\w+)` \| ([−+\d.]+) – ([−+\d.]+)", doc, flags=re.M)
    documented = {name: (float(lo.replace("−", "-")), float(hi.replace("−", "-"))) for name, lo, hi in rows}
    assert documented == {name: (r.low, r.high) for name, r in RANGES.items()}


def test_worlds_drawn_in_the_background_are_the_ones_loaded(world):
    from parts.sim import world as worlds

    prefetch_world(77, theme="park", randomize=5, **world)
    w = load_world(77, theme="park", randomize=5, **world)
    assert w.theme.name == "park" and w.conditions.randomize == 5
    assert load_world(77, theme="park", randomize=5, **world) is w and not worlds._PENDING
    prefetch_world(78, theme="park", lanes=2, width=1.2, **world)  # an error surfaces when loaded
    with pytest.raises(ThemeError, match="two-lane"):
        load_world(78, theme="park", lanes=2, width=1.2, **world)


@pytest.mark.parametrize("text, found", [
    ('SIM_RANDOMIZE = 3\nSIM_RANDOMIZE_RANGES = {"lite": (0.5, 1.0)}\n',
     "line 2: SIM_RANDOMIZE_RANGES: unknown quantity 'lite'"),
    ('SIM_RANDOMIZE_RANGES = {"latency": (0, 30)}\n', "line 1: SIM_RANDOMIZE_RANGES['latency'] = (0, 30): need"),
    ('SIM_THEME = "road"\nSIM_THEME = "desert"\n', "line 2: unknown theme 'desert': use one of road, indoor, park"),
    ('SIM_LANES = 2\nSIM_ROAD_WIDTH = 1.2\nSIM_THEME = "park"\n', "line 3: theme 'park' has no two-lane variant"),
])
def test_bad_theme_or_ranges_in_myconfig_are_one_line_errors_at_their_line(tmp_path, text, found):
    from parts.sim.simulator import SimCar
    from vehicle.config import ConfigError, load_config

    (tmp_path / "myconfig.py").write_text(text)
    cfg = load_config(car_path=tmp_path)
    with pytest.raises(ConfigError) as info:
        SimCar.from_config(cfg)
    assert str(info.value).startswith(f"{tmp_path.resolve() / 'myconfig.py'}, {found}")
    assert "\n" not in str(info.value)


def test_road_surfaces_from_the_pool_on_every_track_at_share_1():
    from parts.sim.themes import SURFACE_POOL

    pool = {p.surface for p in SURFACE_POOL}
    themes_palette = {c for t in THEMES.values() for m in t.road + t.ground for c in m.colours}
    looks = [load_world(seed, theme="road", randomize=1, res=0.1, surface_share=1.0).look for seed in range(1, 21)]
    plain = [load_world(seed, theme="road", randomize=1, res=0.1).look for seed in range(1, 21)]
    assert len({look.road for look in looks}) >= 3 and {look.road for look in looks} <= pool
    assert {look.road for look in plain} == {"asphalt"}
    assert not {look.road_rgb for look in looks} & themes_palette  # no theme's colours, the park's included
    brightness = [max(look.road_rgb) for look in looks]
    assert max(brightness) - min(brightness) > 60  # dark and light roads
    for look, before in zip(looks, plain, strict=True):  # only the road changes: lines, verges and sky stay
        assert (look.ground, look.ground_rgb, look.edge, look.centre, look.sky_top) == \
               (before.ground, before.ground_rgb, before.edge, before.centre, before.sky_top)
    indoor = load_world(2, theme="indoor", randomize=1, res=0.1, surface_share=1.0).look
    assert indoor.road is None and indoor.ground == looks[1].road  # no road surface: the floor is drawn instead
    assert indoor.edge == load_world(2, theme="indoor", randomize=1, res=0.1).look.edge


def test_road_surfaces_are_drawn_per_track_and_randomisation_seed_and_change_no_other_draw():
    def world(seed: int, randomize: int | None, share: float):
        return load_world(seed, theme="road", randomize=randomize, res=0.1, surface_share=share)

    a, b = world(9, 1, 1.0), world(9, 1, 1.0)
    assert a.look == b.look and np.array_equal(a.texture.image, b.texture.image)
    roads = lambda randomize: [world(s, randomize, 1.0).look.road_rgb for s in range(1, 6)]  # noqa: E731
    assert roads(1) != roads(2)  # another randomisation seed, other surfaces
    plain = world(9, 1, 0.0)
    spots = lambda w: [(d.kind, d.x, d.y) for d in w.scenery.distractors]  # noqa: E731
    assert a.conditions == plain.conditions and spots(a) == spots(plain) and len(spots(a)) > 0
    assert a.look.road_rgb != plain.look.road_rgb
    # at share 0.5 a track takes the pool or keeps its theme's road exactly (the same frame as at 0)
    halves = [(world(s, None, 0.5), world(s, None, 0.0)) for s in range(1, 9)]
    kept = [p.look == h.look for h, p in halves]
    assert 0 < sum(kept) < len(halves)
    for (h, p), same in zip(halves, kept, strict=True):
        if same:
            assert np.array_equal(h.texture.image, p.texture.image)
        else:  # a track that takes the pool takes the same surface at any share
            assert h.look == world(h.track.seed, None, 1.0).look


def test_road_surfaces_are_off_by_default_and_the_share_is_checked(cfg, tmp_path):
    from parts.sim.world import build_world, world_params
    from vehicle.config import ConfigError, load_config

    assert world_params(cfg)["surface_share"] == 0.0
    default = load_world(4, theme="road", res=0.1)
    assert load_world(4, theme="road", res=0.1, surface_share=0.0) is default  # one cache entry: the same world
    with pytest.raises(ValueError, match="SIM_ROAD_SURFACE_SHARE = 1.5: use a share of tracks from 0 to 1"):
        build_world(default.track, default.theme, default.conditions, res=0.1, surface_share=1.5)
    (tmp_path / "myconfig.py").write_text("SIM_ROAD_SURFACE_SHARE = 1.5\n")
    with pytest.raises(ConfigError, match="SIM_ROAD_SURFACE_SHARE = 1.5 is out of range; valid: 0 to 1"):
        load_config(car_path=tmp_path)
