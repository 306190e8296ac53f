"""Benchmark of the built-in simulator on one core.

Measures (median of --repeats runs each):
  * the camera renderer (one cv2.warpPerspective with the precomputed homography) in frames/s,
    against a naive renderer measured in the same run (per-pixel ray casting in numpy + cv2.remap,
    the straightforward way to render a ground plane);
  * a full simulator step (car physics + telemetry + render) in steps/s and as a multiple of real
    time at DRIVE_LOOP_HZ;
  * closed-loop evaluation of the expert (simulated laps per wall second).

Usage: .venv/bin/python bench/sim.py [--frames 3000] [--repeats 5] [--size 160x120]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

cv2.setNumThreads(1)
try:  # torch is not needed here; if it is installed keep it to one thread too
    import torch  # noqa: E402

    torch.set_num_threads(1)
except ImportError:
    pass

from parts.sim.camera import Camera  # noqa: E402
from parts.sim.expert import Expert  # noqa: E402
from parts.sim.simulator import SimCar, load_world  # noqa: E402
from vehicle.app.evaluate import evaluate  # noqa: E402
from vehicle.config import Config  # noqa: E402


def naive_render(cam: Camera, texture, x: float, y: float, heading: float) -> np.ndarray:
    """Per-pixel ray casting: each frame, intersect every pixel's ray with the ground in numpy."""
    w, h = cam.width, cam.height
    f = (w / 2) / math.tan(math.radians(cam.fov_deg) / 2)
    u, v = np.meshgrid(np.arange(w) - (w / 2 - 0.5), np.arange(h) - (h / 2 - 0.5))
    p = math.radians(cam.pitch_deg)
    xc, yc = u / f, v / f  # camera ray (xc, yc, 1): right, down, forward
    rx = -yc * math.sin(p) + math.cos(p)
    ry = -xc
    rz = -yc * math.cos(p) - math.sin(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(rz < 0, cam.height_m / -rz, np.nan)
    gx, gy = cam.forward_m + t * rx, t * ry
    c, s = math.cos(heading), math.sin(heading)
    wx, wy = x + c * gx - s * gy, y + s * gx + c * gy
    mx = ((wx - texture.x0) / texture.res - 0.5).astype(np.float32)
    my = ((texture.y1 - wy) / texture.res - 0.5).astype(np.float32)
    img = cv2.remap(texture.image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=texture.ground_color)
    img[~np.isfinite(t)] = texture.sky_bottom
    return img


def timed(fn, n: int) -> float:
    t0 = time.perf_counter()
    for i in range(n):
        fn(i)
    return n / (time.perf_counter() - t0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", default="160x120")
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.split("x"))
    cfg = Config.defaults(SIM_CAMERA_W=w, SIM_CAMERA_H=h, SIM_REALTIME=False)
    track, texture = load_world(1)
    cam = Camera(w, h, cfg.SIM_CAMERA_FOV, cfg.SIM_CAMERA_PITCH, cfg.SIM_CAMERA_HEIGHT, cfg.SIM_CAMERA_FORWARD)
    poses = [track.pose_at(s) for s in np.linspace(0, track.length, 500)]
    out = np.empty((h, w, 3), np.uint8)

    def warp(i: int) -> None:
        cam.render(texture, *poses[i % 500], out=out)

    def naive(i: int) -> None:
        naive_render(cam, texture, *poses[i % 500])

    # the two renderers agree (apart from interpolation at the horizon rows)
    diff = np.abs(cam.render(texture, *poses[7]).astype(int) - naive_render(cam, texture, *poses[7]).astype(int))
    agree = float(np.mean(diff[cam.ground_row + 2:] <= 2))

    sim = SimCar.from_config(cfg, seeds=[1])
    expert = Expert.from_config(cfg, sim)

    def step(i: int) -> None:
        sim.run(*expert.command())

    res: dict[str, list[float]] = {"warp": [], "naive": [], "step": [], "eval": []}
    for _ in range(args.repeats):
        res["warp"].append(timed(warp, args.frames))
        res["naive"].append(timed(naive, max(200, args.frames // 10)))
        res["step"].append(timed(step, args.frames))
        t0 = time.perf_counter()
        report = evaluate("expert", [1], laps=2, cfg=cfg)
        res["eval"].append(report["overall"]["laps_completed"] / (time.perf_counter() - t0))
    med = {k: statistics.median(v) for k, v in res.items()}
    hz = cfg.DRIVE_LOOP_HZ
    print(f"simulator benchmark, {w}x{h}, one core, median of {args.repeats} runs")
    print(f"  renderer (perspective warp) : {med['warp']:9.0f} frames/s  "
          f"({med['warp'] / hz:.0f}x real time at {hz} Hz)")
    print(f"  naive ray-cast + remap      : {med['naive']:9.0f} frames/s  "
          f"(warp is {med['warp'] / med['naive']:.1f}x faster; {agree * 100:.1f} % of ground pixels within 2/255)")
    print(f"  full step (car+telemetry+render+expert): {med['step']:7.0f} steps/s "
          f"({med['step'] / hz:.0f}x real time)")
    print(f"  expert evaluation           : {med['eval']:9.1f} laps per wall second "
          f"(track cached; a lap is ~14 s simulated)")
    print(f"  texture: {texture.image.shape[1]}x{texture.image.shape[0]} px at {texture.res:.3f} m/px")
    return 0


if __name__ == "__main__":
    sys.exit(main())
