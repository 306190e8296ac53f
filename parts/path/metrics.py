"""How far a car drives from its recorded path (its true position against the path in the world)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np


def distance_to_polyline(xy: np.ndarray, x: float, y: float, closed: bool = False) -> float:
    """Shortest distance (m) from (x, y) to the polyline through ``xy`` (N, 2)."""
    a = np.asarray(xy, np.float64)
    b = np.roll(a, -1, axis=0) if closed else a[1:]
    a = a if closed else a[:-1]
    if len(a) == 0:
        return float(np.hypot(xy[0][0] - x, xy[0][1] - y))
    d = b - a
    seg2 = np.maximum((d * d).sum(axis=1), 1e-12)
    t = np.clip(((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / seg2, 0.0, 1.0)
    px, py = a[:, 0] + t * d[:, 0] - x, a[:, 1] + t * d[:, 1] - y
    return float(np.sqrt((px * px + py * py).min()))


class PathDistance:
    """Part: the true distance from the car (``sim/pos``, world metres) to a path given in world
    coordinates, every loop the pilot drives (``run_pilot``); ``result()`` summarises it.

    Args:
        world_xy: the recorded path carried into the simulator's world frame (N, 2).
        closed: the path is a lap (the last point joins the first).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("sim/pos", "run_pilot")
    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, world_xy: np.ndarray, closed: bool = False) -> None:
        self.xy = np.asarray(world_xy, np.float64)
        self.closed = closed
        self.distances: list[float] = []

    def run(self, pos: Any, run_pilot: Any) -> None:
        if pos is not None and run_pilot:
            self.distances.append(distance_to_polyline(self.xy, float(pos[0]), float(pos[1]), self.closed))

    def result(self) -> dict[str, float | None]:
        """``mean_path_distance``, ``p95_path_distance``, ``max_path_distance`` in metres."""
        if not self.distances:
            return {"mean_path_distance": None, "p95_path_distance": None, "max_path_distance": None}
        d = np.asarray(self.distances)
        return {"mean_path_distance": round(float(d.mean()), 4),
                "p95_path_distance": round(float(np.percentile(d, 95)), 4),
                "max_path_distance": round(float(d.max()), 4)}
