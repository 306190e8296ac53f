"""Procedural ground materials for the top-down track texture: asphalt, grass, concrete, wood ...

Each material is a small drawing function ``draw(rng, h, w, base, res) -> float32 HxWx3`` that
paints an ``h x w`` patch of ground at ``res`` metres per pixel around the RGB colour ``base``.
Patterns that have a real size (planks, tiles, joints, pavers) are laid out in metres, so they
look the same at any texture resolution; they are aligned with the texture's axes (the walls of
a room are too). Everything is vectorised numpy/OpenCV: a 15 x 15 m patch at 1 cm per pixel takes
a few tenths of a second.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

#: a material's drawing function: (rng, height px, width px, base RGB, metres per pixel) -> image
Draw = Callable[[np.random.Generator, int, int, np.ndarray, float], np.ndarray]


def smooth_noise(rng: np.random.Generator, h: int, w: int, cells: int) -> np.ndarray:
    """Zero-mean noise in about [-1, 1] with ``cells`` blobs across the larger side (float32 HxW)."""
    ch = max(2, int(round(cells * h / max(h, w))) + 1)
    cw = max(2, int(round(cells * w / max(h, w))) + 1)
    small = rng.uniform(-1.0, 1.0, (ch, cw)).astype(np.float32)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


def _cells(h: int, w: int, res: float, size_m: float) -> int:
    """Number of noise blobs across the larger side for blobs of about ``size_m`` metres."""
    return max(2, int(max(h, w) * res / size_m))


def _grain(rng: np.random.Generator, h: int, w: int, sigma: float, blur: float = 0.8) -> np.ndarray:
    """Per-pixel grain (float32 HxW, standard deviation about ``sigma``), lightly blurred."""
    fine = rng.standard_normal((h, w), dtype=np.float32)
    fine *= sigma
    if blur > 0:
        cv2.GaussianBlur(fine, (3, 3), blur, dst=fine)
    return fine


def _base(h: int, w: int, base: np.ndarray) -> np.ndarray:
    layer = np.empty((h, w, 3), np.float32)
    layer[:] = np.asarray(base, np.float32)
    return layer


def _add(layer: np.ndarray, field: np.ndarray, tint: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> None:
    """Add a grey-level field to every channel (scaled per channel by ``tint``), in place."""
    for k in range(3):
        if tint[k] == 1.0:
            layer[..., k] += field
        else:
            layer[..., k] += field * np.float32(tint[k])


def asphalt(rng: np.random.Generator, h: int, w: int, base: np.ndarray, res: float) -> np.ndarray:
    """Asphalt: blotches of about 40 cm, grain and sparse light grit."""
    layer = _base(h, w, base)
    _add(layer, 10.0 * smooth_noise(rng, h, w, _cells(h, w, res, 0.4)))
    grain = _grain(rng, h, w, 12.0)
    grit = rng.random((h, w), dtype=np.float32) < 0.01
    grain[grit] += 30.0
    _add(layer, grain, (1.0, 0.97, 0.94))
    return layer


def grass(rng: np.random.Generator, h: int, w: int, base: np.ndarray, res: float) -> np.ndarray:
    """Lawn: yellower and darker patches of a metre or two, tufts of ~5 cm and coarse grain."""
    layer = _base(h, w, base)
    patches = smooth_noise(rng, h, w, _cells(h, w, res, 1.5))
    _add(layer, 22.0 * patches, (0.9, 1.0, 0.4))  # drier patches are lighter and yellower
    tufts = smooth_noise(rng, h, w, _cells(h, w, res, 0.05))
    _add(layer, 14.0 * tufts, (0.6, 1.0, 0.5))
    _add(layer, _grain(rng, h, w, 20.0, 0.6), (0.7, 1.0, 0.6))
    return layer


def dirt(rng: np.random.Generator, h: int, w: int, base: np.ndarray, res: float) -> np.ndarray:
    """Bare earth or sand: large blotches and fine grain."""
    layer = _base(h, w, base)
    _add(layer, 25.0 * smooth_noise(rng, h, w, _cells(h, w, res, 0.4)))
    _add(layer, _grain(rng, h, w, 16.0), (1.0, 0.95, 0.9))
    return layer


def concrete(rng: np.random.Generator, h: int, w: int, base: np.ndarray, res: float) -> np.ndarray:
    """Polished concrete floor: soft stains, fine grain and saw-cut joints every 2-4 m."""
    layer = _base(h, w, base)
    _add(layer, 9.0 * smooth_noise(rng, h, w, _cells(h, w, res, 0.8)))
    stains = np.clip(smooth_noise(rng, h, w, _cells(h, w, res, 1.2)) - 0.4, 0.0, None)
    _add(layer, -40.0 * stains)
    _add(layer, _grain(rng, h, w, 7.0))
    pitch = rng.uniform(2.0, 4.0) / res
    line = max(1, int(round(0.006 / res)))
    for axis, n in ((0, h), (1, w)):
        offset = rng.uniform(0, pitch)
        for pos in np.arange(offset, n, pitch).astype(int):
            sl = (slice(pos, pos + line), slice(None)) if axis == 0 else (slice(None), slice(pos, pos + line))
            layer[sl] *= 0.72
    return layer


def wood(rng: np.random.Generator, h: int, w: int, base: np.ndarray, res: float) -> np.ndarray:
    """Wooden floor: boards 9-20 cm wide with staggered ends, a tone per board, grain and seams."""
    along_x = bool(rng.integers(2))
    n_across, n_along = (h, w) if along_x else (w, h)
    board = rng.uniform(0.09, 0.2) / res  # board width, px
    length = rng.uniform(0.8, 2.0) / res  # board length, px
    rows = np.arange(n_across, dtype=np.float32)
    idx = (rows // board).astype(np.int32)
    n_boards = int(idx.max()) + 1
    stagger = rng.uniform(0, length, n_boards).astype(np.float32)
    cols = np.arange(n_along, dtype=np.float32)
    pos = cols[None, :] + stagger[idx][:, None]  # position along each board's row
    seg = (pos // length).astype(np.int32)
    tones = rng.uniform(0.8, 1.15, (n_boards, int(seg.max()) + 2)).astype(np.float32)
    tone = tones[idx[:, None], seg]
    # grain: noise stretched ~40x along the boards
    streak = rng.standard_normal((n_across, max(2, n_along // 40)), dtype=np.float32)
    streak = cv2.resize(streak, (n_along, n_across), interpolation=cv2.INTER_LINEAR)
    shade = tone * (1.0 + 0.06 * streak)
    seam = max(1, int(round(0.003 / res)))
    shade[(rows % board) < seam] *= 0.6
    shade[(pos % length) < seam] *= 0.6
    if not along_x:
        shade = np.ascontiguousarray(shade.T)
    layer = _base(h, w, base)
    layer *= shade[..., None]
    _add(layer, _grain(rng, h, w, 5.0))
    return layer


def carpet(rng: np.random.Generator, h: int, w: int, base: np.ndarray, res: float) -> np.ndarray:
    """Carpet tiles of 50 cm: a slight tone per tile, strong per-pixel fibre noise."""
    tile = 0.5 / res
    ty = (np.arange(h) // tile).astype(np.int32)
    tx = (np.arange(w) // tile).astype(np.int32)
    tones = rng.uniform(0.93, 1.07, (int(ty.max()) + 1, int(tx.max()) + 1)).astype(np.float32)
    layer = _base(h, w, base)
    layer *= tones[ty[:, None], tx[None, :]][..., None]
    _add(layer, 6.0 * smooth_noise(rng, h, w, _cells(h, w, res, 0.6)))
    _add(layer, _grain(rng, h, w, 14.0, 0.0))
    return layer


def gravel(rng: np.random.Generator, h: int, w: int, base: np.ndarray, res: float) -> np.ndarray:
    """Gravel path: pebbles of 1-3 cm in light and dark tones over fine grain."""
    layer = _base(h, w, base)
    pebbles = smooth_noise(rng, h, w, _cells(h, w, res, 0.02))
    _add(layer, 30.0 * pebbles)
    _add(layer, 12.0 * smooth_noise(rng, h, w, _cells(h, w, res, 0.5)))
    _add(layer, _grain(rng, h, w, 14.0, 0.5))
    return layer


def pavers(rng: np.random.Generator, h: int, w: int, base: np.ndarray, res: float) -> np.ndarray:
    """Concrete pavers (14 x 7 cm) in running bond: a tone per paver, darker joints."""
    bw, bh = 0.14 / res, 0.07 / res
    ys = np.arange(h, dtype=np.float32)
    xs = np.arange(w, dtype=np.float32)
    row = (ys // bh).astype(np.int32)
    shift = (row % 2).astype(np.float32) * (bw / 2)
    xpos = xs[None, :] + shift[:, None]
    col = (xpos // bw).astype(np.int32)
    tones = rng.uniform(0.85, 1.12, (int(row.max()) + 1, int(col.max()) + 2)).astype(np.float32)
    shade = tones[row[:, None], col]
    joint = max(1, int(round(0.006 / res)))
    shade[(ys % bh) < joint] *= 0.65
    shade[(xpos % bw) < joint] *= 0.65
    layer = _base(h, w, base)
    layer *= shade[..., None]
    _add(layer, _grain(rng, h, w, 8.0))
    return layer


#: every material by name (the themes pick from these)
SURFACES: dict[str, Draw] = {
    "asphalt": asphalt, "grass": grass, "dirt": dirt, "concrete": concrete, "wood": wood, "carpet": carpet,
    "gravel": gravel, "pavers": pavers,
}
