"""The path view's ``path`` message (parts/web/pathview.py): its size in JSON and the time to
encode it, for paths of several lengths, against the naive message (every point, full float
precision, ``[[x, y], ...]``). Encoding runs in the web thread, once per path version.

    .venv/bin/python bench/web_path.py
"""

from __future__ import annotations

import json
import statistics
import timeit

import numpy as np

from parts.web.pathview import encode_path


def oval(n: int) -> np.ndarray:
    """A 60 m by 30 m oval of ``n`` points, float32 metres (a GPS lap)."""
    t = np.linspace(0, 2 * np.pi, n)
    return np.stack([30 - 30 * np.cos(t), 15 * np.sin(t)], axis=1).astype(np.float32)


def main() -> None:
    print("| points | kept | message (kB) | naive (kB) | encode p50 (ms) |")
    print("|---|---|---|---|---|")
    for n in (200, 2000, 20000):
        xy = oval(n)
        msg = encode_path(xy, 1)
        naive = json.dumps({"version": 1, "xy": xy.astype(float).tolist()})
        runs = [min(timeit.repeat(lambda xy=xy: encode_path(xy, 1), number=20, repeat=3)) / 20 * 1e3
                for _ in range(5)]
        print(f"| {n} | {len(msg['xy']) // 2} | {len(json.dumps(msg)) / 1e3:.1f} | {len(naive) / 1e3:.1f} "
              f"| {statistics.median(runs):.2f} |")


if __name__ == "__main__":
    main()
