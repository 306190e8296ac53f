"""Benchmark of the vision parts per camera frame, on one core.

Measures (median over --repeats runs of --frames frames each), on simulator frames:
  * lane extraction (the thesis's warp + min-max stretch + HLS + S threshold, plus the white mask)
    against a plain cv2.resize of the same frame to the same size, measured in the same run: the
    ratio says what the lane stream costs on top of the cheapest preprocessing there is;
  * the whole preprocessing of the two-stream ``lanes`` model (crop, lane image, scale to float)
    against that of the single-stream ``behavior`` model;
  * the Undistort part (one precomputed remap) against the thesis's per-frame ``cv2.undistort``.

Usage: .venv/bin/python bench/vision.py [--frames 2000] [--repeats 5] [--size 160x120]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

cv2.setNumThreads(1)
import torch  # noqa: E402

torch.set_num_threads(1)

from parts.pilots.preprocess import preprocess_from_config  # noqa: E402
from parts.sim.camera import PinholeCamera, lane_region_points  # noqa: E402
from parts.sim.simulator import SimCar  # noqa: E402
from parts.vision.calibration import CameraCalibration  # noqa: E402
from parts.vision.lanes import LaneExtractor, LaneSettings  # noqa: E402
from parts.vision.undistort import Undistort  # noqa: E402
from vehicle.config import Config  # noqa: E402

LENS = np.array([-0.25, 0.07, 0.001, -0.0015, 0.0])


def frames_of(width: int, height: int, n: int) -> list[np.ndarray]:
    """``n`` simulator frames of a two-lane track (64 distinct views, repeated)."""
    sim = SimCar([1], camera=PinholeCamera(width, height), world={"lanes": 2, "res": 0.02})
    out = []
    for i in range(64):
        x, y, h = sim.track.pose_at(i * sim.track.length / 64, -0.2)
        sim.car.place(x, y, h)
        out.append(sim.render())
    return [out[i % 64] for i in range(n)]


def per_frame_us(fn, frames: list[np.ndarray], repeats: int) -> float:
    """Median over ``repeats`` runs of the mean time per frame, microseconds."""
    runs = []
    for _ in range(repeats):
        t = time.perf_counter()
        for f in frames:
            fn(f)
        runs.append((time.perf_counter() - t) / len(frames) * 1e6)
    return statistics.median(runs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", default="160x120", help="camera frame WxH")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    frames = frames_of(w, h, args.frames)
    points = lane_region_points(PinholeCamera(w, h))
    settings = LaneSettings(source=points["LANE_SOURCE_POINTS"], destination=points["LANE_DESTINATION_POINTS"],
                            points_size=points["LANE_POINTS_SIZE"], color_mask="white")
    lanes = LaneExtractor(settings)
    out_size = (w, h - h // 3)  # the demo's crop of the top third

    def resize(f: np.ndarray) -> np.ndarray:
        return cv2.resize(f, out_size, interpolation=cv2.INTER_AREA)

    rows = []
    base = per_frame_us(resize, frames, args.repeats)
    ext = per_frame_us(lambda f: lanes.extract(f, out_size), frames, args.repeats)
    rows.append(("cv2.resize to the model size (baseline)", base, 1.0))
    rows.append(("lane extraction (warp + HLS + S threshold + white)", ext, ext / base))

    cfg = Config.defaults(ROI_CROP_TOP=h // 3, LANE_COLOR_MASK="white",
                          **{k: [tuple(p) for p in v] if k != "LANE_POINTS_SIZE" else tuple(v)
                             for k, v in points.items()})
    single = preprocess_from_config(cfg, "behavior", (h, w, 3))
    two = preprocess_from_config(cfg, "lanes", (h, w, 3))
    p1 = per_frame_us(single, frames, args.repeats)
    p2 = per_frame_us(two, frames, args.repeats)
    rows.append(("preprocessing of the behavior model (crop, scale)", p1, p1 / base))
    rows.append(("preprocessing of the lanes model (+ lane image)", p2, p2 / base))

    cam = PinholeCamera(w, h)
    cal = CameraCalibration((w, h), cam.intrinsics, LENS, 0.1)
    und = Undistort(cal)
    und.run(frames[0])  # the maps are made once, outside the timing
    k_new = und.new_camera_matrix
    remap = per_frame_us(und.run, frames, args.repeats)
    thesis = per_frame_us(lambda f: cv2.undistort(f, cal.camera_matrix, LENS, None, k_new), frames, args.repeats)
    rows.append(("Undistort part (precomputed remap)", remap, remap / base))
    rows.append(("cv2.undistort per frame (the thesis's Appendix 1.3)", thesis, thesis / base))

    print(f"vision per frame, {w}x{h} frames, one core, median of {args.repeats} x {args.frames} frames")
    print(f"{'':55s} {'us/frame':>9s} {'x resize':>9s}")
    for name, us, ratio in rows:
        print(f"{name:55s} {us:9.1f} {ratio:9.2f}")
    print(f"remap is {thesis / remap:.1f}x faster than cv2.undistort; the lane image adds "
          f"{p2 - p1:.0f} us to the preprocessing ({(p2 - p1) / 1000 / (1000 / 20) * 100:.2f} % of a 20 Hz loop)")


if __name__ == "__main__":
    main()
