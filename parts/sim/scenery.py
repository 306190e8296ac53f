"""What the camera sees above the ground: the backdrop (walls, tree line), distractors beside the
track (cones, boxes, parked cars) and the car's own shadow.

The ground is rendered by one perspective warp (:mod:`parts.sim.camera`); these are drawn over
it, cheaply:

* **Backdrop**: rays of a coarse grid of pixels (every 4th row and column) are cast onto the
  vertical sides of the texture's rectangle; the hit positions give a remap of the unrolled
  panorama, upsampled to full resolution. Pixels whose ray meets the floor before the wall
  (height below 0) are left alone (``BORDER_TRANSPARENT``), which is the floor/wall boundary.
* **Distractors**: convex pieces (prisms and frusta) with flat-shaded faces, drawn far to near
  with ``cv2.fillConvexPoly``; round pieces (cones, wheels) by their silhouette. Their shadows are
  painted into the texture when the world is built.
* **The car's own shadow**: a ground polygon next to the car away from the sun, darkened in place.

Distractors are placed so that no part of them comes closer than :data:`CLEARANCE` to the road's
edge: they never block the track.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from parts.sim.backdrops import Backdrop
from parts.sim.track import Track

#: metres between a distractor's footprint and the edge of the road, at least
CLEARANCE = 0.15
#: the car's body seen from above, metres in the car frame (rear axle at 0): x from, x to, half width
#: (its front stops where the default camera's view of the ground begins)
CAR_BODY = (-0.08, 0.3, 0.1)
#: height of the car's body, metres (length of its shadow per 1/tan(sun elevation))
CAR_HEIGHT = 0.12
_SHIFT = 4
_NEAR = 0.03  # metres: pieces closer to the camera plane than this are not drawn


@dataclass(frozen=True)
class Piece:
    """A convex solid: vertices (N, 3) in world metres and faces (vertex indices, shaded RGB)."""

    vertices: np.ndarray
    faces: tuple[tuple[np.ndarray, tuple[int, int, int]], ...]
    normals: np.ndarray  # (F, 3) outward unit normals
    round: bool = False  # drawn as one silhouette in the colour of its first face
    bias: float = 0.0  # metres: drawn as if this much nearer (a cabin always over its car's body)

    @property
    def centre(self) -> np.ndarray:
        """Mean of the vertices."""
        return self.vertices.mean(axis=0)

    def __post_init__(self) -> None:
        # a vertex of each face, for the back-face test of every frame
        object.__setattr__(self, "anchors", self.vertices[[f[0] for f, _ in self.faces]])


@dataclass(frozen=True)
class Distractor:
    """A static object beside the track, made of pieces (drawn far to near)."""

    kind: str
    x: float
    y: float
    radius: float  # metres: a circle around (x, y) that holds the whole footprint
    pieces: tuple[Piece, ...]

    def __post_init__(self) -> None:
        # every piece's vertices in one array, so a frame projects an object with one product
        object.__setattr__(self, "vertices", np.concatenate([p.vertices for p in self.pieces]))
        ends = np.cumsum([len(p.vertices) for p in self.pieces])
        object.__setattr__(self, "spans", list(zip([0, *ends[:-1]], ends, strict=True)))
        object.__setattr__(self, "centres", np.array([p.centre for p in self.pieces]))
        object.__setattr__(self, "biases", np.array([p.bias for p in self.pieces]))

    def shadow(self, sun: np.ndarray) -> np.ndarray:
        """Ground polygon (K, 2) of the object's shadow for the sun direction ``sun`` (unit, z up)."""
        pts = np.concatenate([p.vertices for p in self.pieces])
        drop = sun[:2] / max(sun[2], 0.2)  # ground shift per metre of height, away from the sun
        ground = pts[:, :2] - pts[:, 2:3] * drop
        hull = cv2.convexHull(np.concatenate([pts[:, :2], ground]).astype(np.float32))
        return hull.reshape(-1, 2).astype(float)


def _frustum(x: float, y: float, yaw: float, bottom: np.ndarray, top: np.ndarray, z0: float, z1: float,
             colours: Sequence[tuple[int, int, int]], cap: bool, shading: tuple[np.ndarray, np.ndarray],
             round_: bool = False, bias: float = 0.0) -> Piece:
    """A frustum from polygon ``bottom`` at z0 to ``top`` at z1 (both (K, 2) counter-clockwise, object
    frame), placed at (x, y) turned by ``yaw``; sides (and the top if ``cap``) flat-shaded."""
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    k = len(bottom)
    b = bottom @ rot.T + (x, y)
    t = top @ rot.T + (x, y)
    vertices = np.concatenate([np.column_stack([b, np.full(k, z0)]), np.column_stack([t, np.full(k, z1)])])
    faces = [np.array([i, (i + 1) % k, k + (i + 1) % k, k + i]) for i in range(k)]
    if cap:
        faces.append(np.arange(k, 2 * k))
    centre = vertices.mean(axis=0)
    normals = []
    for f in faces:
        p = vertices[f]
        n = np.cross(p[1] - p[0], p[2] - p[0])
        n = n / max(np.linalg.norm(n), 1e-9)
        if np.dot(n, p.mean(axis=0) - centre) < 0:
            n = -n
        normals.append(n)
    normals_a = np.array(normals)
    gains, sun = shading
    shaded = []
    for i, f in enumerate(faces):
        base = np.asarray(colours[-1] if cap and i == k else colours[0], float)
        light = 0.55 + 0.6 * max(0.0, float(np.dot(normals_a[i], sun)))
        shaded.append((f, tuple(int(v) for v in np.clip(base * gains * light, 0, 255))))
    return Piece(vertices, tuple(shaded), normals_a, round_, bias)  # type: ignore[arg-type]


def _polygon(n: int, r: float) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def _rect(length: float, width: float, dx: float = 0.0, dy: float = 0.0) -> np.ndarray:
    return np.array([[-length / 2, -width / 2], [length / 2, -width / 2], [length / 2, width / 2],
                     [-length / 2, width / 2]]) + (dx, dy)


_CONE_ORANGE = (245, 95, 20)
_BOX_COLOURS = ((170, 125, 80), (150, 110, 70), (60, 90, 170), (80, 80, 85), (190, 40, 40), (230, 200, 60))
_CAR_COLOURS = ((200, 30, 30), (30, 80, 190), (240, 240, 240), (30, 30, 30), (250, 190, 0), (40, 150, 60))


def make_distractor(kind: str, x: float, y: float, yaw: float, rng: np.random.Generator,
                    shading: tuple[np.ndarray, np.ndarray]) -> Distractor:
    """A cone, box or parked (RC-scale) car standing at (x, y), turned by ``yaw`` radians."""
    if kind == "cone":
        r, h = rng.uniform(0.06, 0.11), rng.uniform(0.18, 0.32)
        band = np.float64(0.45), np.float64(0.62)  # the white band, fractions of the height
        radius_at = lambda f: r * (1 - f) + 0.012 * f  # noqa: E731 - radius of the cone at a height fraction
        pieces = [
            _frustum(x, y, yaw, _rect(2.6 * r, 2.6 * r), _rect(2.6 * r, 2.6 * r), 0.0, 0.02, [_CONE_ORANGE],
                     True, shading),
            _frustum(x, y, yaw, _polygon(10, r), _polygon(10, radius_at(band[0])), 0.02, band[0] * h,
                     [_CONE_ORANGE], False, shading, True, 0.01),
            _frustum(x, y, yaw, _polygon(10, radius_at(band[0])), _polygon(10, radius_at(band[1])), band[0] * h,
                     band[1] * h, [(245, 245, 240)], False, shading, True, 0.02),
            _frustum(x, y, yaw, _polygon(10, radius_at(band[1])), _polygon(10, 0.012), band[1] * h, h,
                     [_CONE_ORANGE], True, shading, True, 0.03),
        ]
        return Distractor(kind, x, y, 1.9 * r, tuple(pieces))
    if kind == "box":
        length, width, h = rng.uniform(0.15, 0.6), rng.uniform(0.15, 0.45), rng.uniform(0.1, 0.45)
        colour = _BOX_COLOURS[int(rng.integers(len(_BOX_COLOURS)))]
        top = tuple(int(min(255, c * 1.08)) for c in colour)
        piece = _frustum(x, y, yaw, _rect(length, width), _rect(length, width), 0.0, h, [colour, top], True, shading)
        return Distractor(kind, x, y, 0.5 * math.hypot(length, width), (piece,))
    if kind == "car":
        colour = _CAR_COLOURS[int(rng.integers(len(_CAR_COLOURS)))]
        glass, tyre = (40, 50, 60), (25, 25, 25)
        wheels = [_frustum(x, y, yaw, _rect(0.075, 0.035, dx, dy), _rect(0.075, 0.035, dx, dy), 0.0, 0.075, [tyre],
                           True, shading, True)
                  for dx in (-0.13, 0.13) for dy in (-0.1, 0.1)]
        body = _frustum(x, y, yaw, _rect(0.44, 0.19), _rect(0.44, 0.19), 0.03, 0.1, [colour], True, shading)
        cabin = _frustum(x, y, yaw, _rect(0.22, 0.16, -0.02), _rect(0.16, 0.13, -0.03), 0.1, 0.16, [glass, colour],
                         True, shading, bias=1.0)
        return Distractor(kind, x, y, 0.26, (*wheels, body, cabin))
    raise ValueError(f"unknown distractor {kind!r}: use 'cone', 'box' or 'car'")


def place_distractors(track: Track, rng: np.random.Generator, count: int, kinds: Sequence[str],
                      bounds: tuple[float, float, float, float], shading: tuple[np.ndarray, np.ndarray]
                      ) -> list[Distractor]:
    """Up to ``count`` distractors beside the road, each at least :data:`CLEARANCE` from its edge
    (measured to every part of the road, curves included), inside ``bounds`` and apart."""
    placed: list[Distractor] = []
    x0, y0, x1, y1 = bounds
    for _ in range(count * 20):
        if len(placed) >= count or not kinds:
            break
        kind = kinds[int(rng.integers(len(kinds)))]
        s = rng.uniform(0, track.length)
        side = 1.0 if rng.random() < 0.5 else -1.0
        gap = rng.uniform(0.0, 1.2)
        shape_seed = int(rng.integers(1 << 32))  # the probe and the placed object get the same size
        probe = make_distractor(kind, 0.0, 0.0, 0.0, np.random.default_rng(shape_seed), shading)
        offset = side * (track.width / 2 + CLEARANCE + probe.radius + gap)
        x, y, heading = track.pose_at(s, offset)
        d2 = ((track.points - (x, y)) ** 2).sum(axis=1).min()
        if math.sqrt(d2) < track.width / 2 + CLEARANCE + probe.radius + 0.01:
            continue  # on the inside of a bend the road comes back closer
        if not (x0 + probe.radius + 0.2 < x < x1 - probe.radius - 0.2 and y0 + probe.radius + 0.2 < y < y1
                - probe.radius - 0.2):
            continue
        if any(math.hypot(x - d.x, y - d.y) < d.radius + probe.radius + 0.1 for d in placed):
            continue
        yaw = heading + (rng.uniform(-0.3, 0.3) if kind == "car" else rng.uniform(0, math.pi))
        placed.append(make_distractor(kind, x, y, yaw, np.random.default_rng(shape_seed), shading))
    return placed


class Scenery:
    """The backdrop, distractors and the car's shadow of one world, drawn over the ground.

    Args:
        backdrop: the walls or tree line around the texture (None: open horizon).
        distractors: objects beside the track.
        sun: unit vector towards the sun (world frame).
        own_shadow: darkness of the car's own shadow (0 = none).
        far: metres beyond which distractors are not drawn.
    """

    def __init__(self, backdrop: Backdrop | None = None, distractors: Sequence[Distractor] = (),
                 sun: np.ndarray | None = None, own_shadow: float = 0.0, far: float = 12.0) -> None:
        self.backdrop = backdrop
        self.distractors = list(distractors)
        self.sun = np.array([0.5, 0.5, 0.707]) if sun is None else np.asarray(sun, float)
        self.own_shadow = float(own_shadow)
        self.far = float(far)
        if self.distractors:
            self._centres = np.array([(d.x, d.y) for d in self.distractors])
            self._radii = np.array([d.radius for d in self.distractors])

    @property
    def empty(self) -> bool:
        """Whether there is nothing to draw."""
        return self.backdrop is None and not self.distractors and self.own_shadow <= 0

    def draw(self, cam, out: np.ndarray, x: float, y: float, heading: float) -> None:
        """Draw over the ground rendered in ``out`` for the car at (x, y, heading)."""
        if self.own_shadow > 0:
            self._draw_own_shadow(cam, out, heading)
        if self.backdrop is not None:
            self._draw_backdrop(cam, out, x, y, heading)
        if self.distractors:
            self._draw_distractors(cam, out, x, y, heading)

    # -- backdrop ---------------------------------------------------------------------------------
    def _draw_backdrop(self, cam, out: np.ndarray, x: float, y: float, heading: float) -> None:
        bd = self.backdrop
        assert bd is not None
        c, s = math.cos(heading), math.sin(heading)
        cx, cy = x + cam.forward_m * c, y + cam.forward_m * s  # the camera, world frame
        x0, y0, x1, y1 = bd.bounds
        nearest = min(cx - x0, x1 - cx, cy - y0, y1 - cy)
        if nearest <= 0.05:
            return  # the camera is outside the room (a car driven off the floor)
        rows = cam.rows_reaching(nearest)
        if rows <= 0:
            return
        dx, dy, slope = cam.ray_grid(rows)
        wx = c * dx - s * dy
        wy = s * dx + c * dy
        with np.errstate(divide="ignore", invalid="ignore"):
            tx = (np.where(wx > 0, x1, x0) - cx) / wx
            ty = (np.where(wy > 0, y1, y0) - cy) / wy
        on_x = tx < ty  # the ray meets a side x = x0 or x1 first
        d = np.where(on_x, tx, ty)
        hx, hy = cx + d * wx, cy + d * wy
        lx, ly = x1 - x0, y1 - y0
        # unrolled perimeter, clockwise seen from above: bottom (x1 -> x0), left, top, right
        u = np.where(on_x, np.where(wx > 0, 2 * lx + ly + (y1 - hy), lx + (hy - y0)),
                     np.where(wy > 0, lx + ly + (hx - x0), x1 - hx))
        perimeter = bd.perimeter
        if u.max() - u.min() > perimeter / 2:  # the view spans the seam: use the second copy
            u = np.where(u < perimeter / 2, u + perimeter, u)
        z = cam.height_m + d * slope
        mx = (u / bd.res - 0.5).astype(np.float32)
        my = ((bd.height - z) / bd.res - 0.5).astype(np.float32)
        mx, my = cam.upsample(mx, rows), cam.upsample(my, rows)
        cv2.remap(bd.image, mx, my, cv2.INTER_LINEAR, dst=out[:rows], borderMode=cv2.BORDER_TRANSPARENT)

    # -- distractors ------------------------------------------------------------------------------
    def _draw_distractors(self, cam, out: np.ndarray, x: float, y: float, heading: float) -> None:
        c, s = math.cos(heading), math.sin(heading)
        rel = self._centres - (x, y)
        ahead = rel[:, 0] * c + rel[:, 1] * s - cam.forward_m
        side = -rel[:, 0] * s + rel[:, 1] * c
        dist = np.hypot(ahead, side)
        # in front, within range and within the horizontal field of view (plus the object's size)
        visible = (ahead > -self._radii) & (dist < self.far) & (
            np.abs(side) - self._radii < ahead * cam.half_width_slope + self._radii)
        if not visible.any():
            return
        cam_pos = np.array([x + cam.forward_m * c, y + cam.forward_m * s, cam.height_m])
        to_camera = cam.world_to_camera(x, y, heading)
        for i in np.flatnonzero(visible)[np.argsort(-dist[visible])]:
            d = self.distractors[i]
            uv, depth = cam.project_with(to_camera, d.vertices)
            # vertices behind the camera project anywhere: keep them in int32 range (their pieces are skipped)
            pts = np.round(np.clip(uv, -1e5, 1e5) * (1 << _SHIFT)).astype(np.int32)
            far_first = d.biases - np.hypot(d.centres[:, 0] - cam_pos[0], d.centres[:, 1] - cam_pos[1])
            for k in np.argsort(far_first, kind="stable"):
                a, b = d.spans[k]
                if depth[a:b].min() >= _NEAR:
                    self._draw_piece(out, d.pieces[k], pts[a:b], cam_pos)

    @staticmethod
    def _draw_piece(out: np.ndarray, piece: Piece, pts: np.ndarray, cam_pos: np.ndarray) -> None:
        if piece.round:
            cv2.fillConvexPoly(out, cv2.convexHull(pts), piece.faces[0][1], cv2.LINE_AA, _SHIFT)
            if len(piece.faces) > len(piece.vertices) // 2:  # a lit cap on top
                f, colour = piece.faces[-1]
                if np.dot(piece.normals[-1], cam_pos - piece.vertices[f[0]]) > 0:
                    cv2.fillConvexPoly(out, pts[f], colour, cv2.LINE_AA, _SHIFT)
            return
        facing = np.einsum("ij,ij->i", piece.normals, cam_pos - piece.anchors) > 0
        for k in np.flatnonzero(facing):
            f, colour = piece.faces[k]
            cv2.fillConvexPoly(out, pts[f], colour, cv2.LINE_AA, _SHIFT)

    # -- the car's own shadow ---------------------------------------------------------------------
    def _draw_own_shadow(self, cam, out: np.ndarray, heading: float) -> None:
        c, s = math.cos(heading), math.sin(heading)
        sun_car = np.array([c * self.sun[0] + s * self.sun[1], -s * self.sun[0] + c * self.sun[1]])
        drop = sun_car / max(self.sun[2], 0.2) * CAR_HEIGHT
        x_from, x_to, half = CAR_BODY
        body = np.array([[x_from, -half], [x_to, -half], [x_to, half], [x_from, half]])
        poly = cv2.convexHull(np.concatenate([body, body - drop]).astype(np.float32)).reshape(-1, 2)
        poly = _clip_ahead(poly.astype(float), cam.forward_m + 0.02)
        if len(poly) < 3:
            return
        uv = cam.ground_to_image(poly)
        if uv is None:
            return
        h, w = out.shape[:2]
        lo = np.maximum(np.floor(uv.min(axis=0)).astype(int), 0)
        hi = np.minimum(np.ceil(uv.max(axis=0)).astype(int) + 1, (w, h))
        if np.any(hi <= lo):
            return
        roi = out[lo[1]:hi[1], lo[0]:hi[0]]
        mask = np.zeros(roi.shape[:2], np.uint8)
        cv2.fillConvexPoly(mask, np.round((uv - lo) * (1 << _SHIFT)).astype(np.int32), 255, cv2.LINE_AA, _SHIFT)
        cv2.blur(mask, (5, 5), dst=mask)  # a soft edge (penumbra)
        gain = cv2.convertScaleAbs(mask, alpha=-self.own_shadow, beta=255.0)  # 255 = lit, less in shadow
        cv2.multiply(roi, cv2.merge((gain, gain, gain)), dst=roi, scale=1.0 / 255.0)


def _clip_ahead(poly: np.ndarray, x_min: float) -> np.ndarray:
    """The part of a convex polygon (K, 2) with x >= x_min (Sutherland-Hodgman, one half-plane)."""
    out = []
    n = len(poly)
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        a_in, b_in = a[0] >= x_min, b[0] >= x_min
        if a_in:
            out.append(a)
        if a_in != b_in:
            t = (x_min - a[0]) / (b[0] - a[0])
            out.append(a + t * (b - a))
    return np.array(out)
