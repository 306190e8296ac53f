"""LeRobot export/import throughput against reading the same tub, in the same run.

    .venv/bin/python bench/lerobot.py [--records 5000] [--runs 3] [--workdir DIR]

Builds a tub of --records 160x120 frames (bench/tub.py's camera-like frames, each marked with its
number so that no two are alike, two sessions), then
times, --runs times each: reading it as training does (``iter_images(iter_records(...))``, the
baseline), ``export_lerobot`` with video (AV1, LeRobot's settings) and with images (the tub's
JPEGs in the parquet files), and ``import_lerobot`` of the video dataset into a new tub. Prints
medians in records/s, each as a ratio to the read, and the sizes on disk.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from tub import dir_bytes, make_frames, settle  # noqa: E402  (bench/tub.py)


def build(path: Path, n: int) -> None:
    from parts.tub.tub import Tub

    frames = make_frames(200)
    t = 1_700_000_000_000
    for session in range(2):
        with Tub(path, ["cam/image_array", "user/angle", "user/throttle", "user/mode"],
                 ["image_array", "float", "float", "str"], fsync=False) as tub:
            for i in range(session * n // 2, (session + 1) * n // 2):
                t += 50
                frame = frames[i % len(frames)].copy()
                frame[:4, :16] = ((i >> (np.arange(16) % 16)) & 1)[None, :, None] * 255  # no two frames alike
                tub.write_record({"cam/image_array": frame, "user/angle": (i % 41) / 20 - 1,
                                  "user/throttle": 0.3, "user/mode": "user"}, timestamp_ms=t)


def read(path: Path) -> int:
    from parts.tub.reader import iter_images, iter_records

    return sum(1 for _ in iter_images(iter_records(path, check_images=False)))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--records", type=int, default=5000)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--workdir", default=None)
    args = parser.parse_args()
    from parts.tub.lerobot import export_lerobot, import_lerobot

    work = Path(tempfile.mkdtemp(prefix="bench-lerobot-", dir=args.workdir))
    try:
        tub = work / "tub"
        build(tub, args.records)
        times: dict[str, list[float]] = {"read": [], "export video": [], "export images": [], "import video": []}
        for run in range(args.runs):
            v, i, b = work / f"v{run}", work / f"i{run}", work / f"b{run}"
            for name, job in (("read", lambda: read(tub)),
                              ("export video", lambda v=v: export_lerobot(tub, v)),
                              ("export images", lambda i=i: export_lerobot(tub, i, video=False)),
                              ("import video", lambda v=v, b=b: import_lerobot(v, b))):
                settle()
                t0 = time.perf_counter()
                job()
                times[name].append(time.perf_counter() - t0)
        base = args.records / statistics.median(times["read"])
        print(f"{args.records} records, {args.runs} runs, medians:")
        for name, values in times.items():
            rate = args.records / statistics.median(values)
            print(f"  {name:14s} {rate:8.0f} records/s   {rate / base:5.2f} x read")
        print(f"sizes: tub {dir_bytes(tub) / 1e6:.1f} MB, video dataset {dir_bytes(work / 'v0') / 1e6:.1f} MB, "
              f"images dataset {dir_bytes(work / 'i0') / 1e6:.1f} MB")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
