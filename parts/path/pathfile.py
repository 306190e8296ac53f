"""A recorded path and its file: a CSV a person can read, one point per line.

::

    x,y,speed
    0.000,0.000,0.00
    0.200,0.004,0.85

``x``, ``y`` in metres in the localiser's frame, ``speed`` in m/s measured when the point was
recorded. Lines starting with ``#`` are comments. DonkeyCar's files (x, y, throttle; no header) load
too: the third column is then taken as it is.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field
from pathlib import Path as FilePath

import numpy as np

from vehicle.errors import VehicleError

HEADER = ("x", "y", "speed")
#: a path file's limits: loading must stay short even off the loop thread, and a larger file is a
#: mistake (200 000 points are 40 km at the default 0.2 m spacing; a line is about 25 bytes)
MAX_POINTS = 200_000
MAX_BYTES = 16 * 1024 * 1024
#: metres from the localiser's origin a point may lie (1000 km; float32 keeps ~6 cm there)
MAX_COORD_M = 1e6


class PathFileError(VehicleError):
    """A path file is missing or malformed (the message names the file and line)."""


@dataclass(frozen=True)
class Path:
    """Points of a path: ``xy`` (N, 2) metres and ``speed`` (N,) m/s, float32 (never mutated)."""

    xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.float32))
    speed: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy, np.float32).reshape(-1, 2)
        speed = np.asarray(self.speed, np.float32).reshape(-1)
        if len(speed) != len(xy):
            raise ValueError(f"a path needs one speed per point, got {len(xy)} points and {len(speed)} speeds")
        xy.setflags(write=False)
        speed.setflags(write=False)
        object.__setattr__(self, "xy", xy)
        object.__setattr__(self, "speed", speed)

    def __len__(self) -> int:
        return len(self.xy)

    @property
    def length(self) -> float:
        """Metres along the points, first to last."""
        return float(np.linalg.norm(np.diff(self.xy, axis=0), axis=1).sum()) if len(self) > 1 else 0.0

    def is_closed(self, close_dist: float) -> bool:
        """Whether the last point lies within ``close_dist`` metres of the first (a lap)."""
        return len(self) > 2 and float(np.linalg.norm(self.xy[-1] - self.xy[0])) <= close_dist

    def transformed(self, x0: float, y0: float, heading: float) -> Path:
        """The path in a frame whose origin is at (x0, y0) with its x axis at ``heading`` (rad) of
        this one (the points as seen from that pose)."""
        c, s = math.cos(heading), math.sin(heading)
        d = self.xy.astype(np.float64) - (x0, y0)
        return Path(np.stack([d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c], axis=1), self.speed)


def save_path(path: Path, filename: str | os.PathLike[str]) -> FilePath:
    """Write ``path`` as CSV (atomically: a crash leaves the old file whole). Returns the file."""
    target = FilePath(filename).expanduser()
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(target.name + ".tmp")
    with open(tmp, "w", newline="", encoding="ascii") as f:
        w = csv.writer(f)
        w.writerow(HEADER)
        for (x, y), v in zip(path.xy.tolist(), path.speed.tolist(), strict=True):
            w.writerow((f"{x:.4f}", f"{y:.4f}", f"{v:.3f}"))
    os.replace(tmp, target)
    return target


def load_path(filename: str | os.PathLike[str]) -> Path:
    """Read a path CSV (see the module docstring).

    Raises:
        PathFileError: the file is missing, empty, over :data:`MAX_BYTES` or :data:`MAX_POINTS`,
            or a line is not two or three numbers within :data:`MAX_COORD_M` (the message names
            the file and the line).
    """
    source = FilePath(filename).expanduser()
    try:
        size = source.stat().st_size
        if size > MAX_BYTES:
            raise PathFileError(f"path file {source}: {size / 2**20:.1f} MiB, larger than a path file may be "
                                f"({MAX_BYTES // 2**20} MiB, {MAX_POINTS} points); record a shorter path or thin "
                                "it out")
        text = source.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise PathFileError(f"path file {source}: cannot read it ({exc.strerror or exc}); record and save a path "
                            "first (PATH_FILENAME)") from exc
    xy: list[tuple[float, float]] = []
    speed: list[float] = []
    rows = csv.reader(text.splitlines())
    number = 0
    while True:
        number += 1
        try:
            row = next(rows)
        except StopIteration:
            break
        except csv.Error as exc:  # a field over csv's limit (128 KiB), a NUL byte ...
            raise PathFileError(f"{source}, line {number}: not a CSV line ({exc}); expected x,y,speed") from None
        cells = [c.strip() for c in row]
        if not cells or not any(cells) or cells[0].startswith("#"):
            continue
        if not xy and tuple(c.lower() for c in cells[:3]) == HEADER[:len(cells[:3])]:
            continue  # the header
        if len(cells) not in (2, 3):
            raise PathFileError(f"{source}, line {number}: expected x,y,speed (2 or 3 numbers), got {len(cells)} "
                                f"values: {','.join(cells)[:60]!r}")
        try:
            values = [float(c) for c in cells]
        except ValueError:
            raise PathFileError(f"{source}, line {number}: not a number in {','.join(cells)[:60]!r} (expected "
                                "x,y,speed in metres and m/s)") from None
        if not all(math.isfinite(v) for v in values):
            raise PathFileError(f"{source}, line {number}: {','.join(cells)[:60]!r} is not finite")
        if not all(abs(v) <= MAX_COORD_M for v in values):
            raise PathFileError(f"{source}, line {number}: {','.join(cells)[:60]!r} is out of range: every value "
                                f"within ±{MAX_COORD_M:g} (x, y in metres from the origin, speed in m/s)")
        if len(xy) >= MAX_POINTS:
            raise PathFileError(f"{source}, line {number}: more than {MAX_POINTS} points, more than a path file "
                                "may hold; record a shorter path or thin it out")
        xy.append((values[0], values[1]))
        speed.append(values[2] if len(values) == 3 else 0.0)
    if not xy:
        raise PathFileError(f"{source}: no points (expected a header x,y,speed and one line per point)")
    return Path(np.array(xy), np.array(speed))
