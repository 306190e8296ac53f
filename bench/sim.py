"""Benchmark of the built-in simulator on one core.

Rates are per second of the process's CPU time (time.process_time): everything runs in one thread
(cv2 and torch are set to 1), so they are rates on one core that other processes sharing the
machine do not distort; wall-clock rates on a busy machine are lower by the share of the core the
benchmark got. Measures (median of --repeats runs each):
  * the camera renderer (one cv2.warpPerspective with the precomputed homography) in frames/s,
    against a naive renderer measured in the same run (per-pixel ray casting in numpy + cv2.remap,
    the straightforward way to render a ground plane);
  * the whole frame of every theme as SimCar.render() makes it, without randomisation (the theme's
    plain look) and with it (SIM_RANDOMIZE: backdrop, distractors, the car's shadow and the
    per-frame sensor effects noise, vignetting, motion blur at 2 m/s and JPEG), both with the
    default ranges and with every effect on and 8 distractors (the worst case);
  * a full simulator step (car physics + telemetry + render + expert) in steps/s and as a multiple
    of real time at DRIVE_LOOP_HZ, plain and randomised;
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

from parts.sim.camera import PinholeCamera  # noqa: E402
from parts.sim.expert import Expert  # noqa: E402
from parts.sim.simulator import SimCar  # noqa: E402
from parts.sim.world import load_world  # noqa: E402
from vehicle.app.evaluate import evaluate  # noqa: E402
from vehicle.config import Config  # noqa: E402


def naive_render(cam: PinholeCamera, texture, x: float, y: float, heading: float) -> np.ndarray:
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
    """Calls per second of this process's CPU time: the benchmark runs in one thread, so this is the
    rate on one core, and other processes sharing the core do not count against it."""
    t0 = time.process_time()
    for i in range(n):
        fn(i)
    return n / (time.process_time() - t0)


#: every per-frame effect on, eight distractors: the most a randomised frame costs
WORST_CASE = {"noise": (4.0, 8.0), "vignetting": (0.3, 0.45), "motion_blur": (0.01, 0.015),
              "jpeg_quality": (35, 60), "distractors": (8, 8), "shadows": (6, 6)}


def frame_renderer(cfg: Config, theme: str, seeds: list[int], randomize: int | None,
                   ranges: dict | None = None):
    """A function rendering frame i as SimCar.render() does, cycling over tracks and poses at 2 m/s."""
    c = cfg.replace(SIM_THEME=theme, SIM_RANDOMIZE=randomize, SIM_RANDOMIZE_RANGES=ranges or {})
    sims = [SimCar.from_config(c, seeds=[s]) for s in seeds]
    poses = [[sim.track.pose_at(d) for d in np.linspace(0, sim.track.length, 200, endpoint=False)] for sim in sims]

    def render(i: int) -> None:
        k = (i // 200) % len(sims)  # a few hundred frames on one track, then the next
        sim, (x, y, h) = sims[k], poses[k][i % 200]
        st = sim.car.state
        st.x, st.y, st.heading, st.speed = x, y, h, 2.0
        sim.render()

    return render


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", default="160x120")
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.split("x"))
    cfg = Config.defaults(SIM_CAMERA_W=w, SIM_CAMERA_H=h, SIM_REALTIME=False)
    world = load_world(1)
    track, texture = world.track, world.texture
    cam = PinholeCamera(w, h, cfg.SIM_CAMERA_FOV, cfg.SIM_CAMERA_PITCH, cfg.SIM_CAMERA_HEIGHT, cfg.SIM_CAMERA_FORWARD)
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
    sim_r = SimCar.from_config(cfg.replace(SIM_THEME="indoor", SIM_RANDOMIZE=3), seeds=[1])
    expert_r = Expert.from_config(cfg, sim_r)

    def step(i: int) -> None:
        sim.run(*expert.command())

    def step_randomised(i: int) -> None:
        sim_r.run(*expert_r.command())

    themes = ("road", "indoor", "park")
    seeds = [1, 2, 3, 4]
    renderers = {}
    for theme in themes:
        renderers[f"{theme} plain"] = frame_renderer(cfg, theme, seeds, None)
        renderers[f"{theme} randomised"] = frame_renderer(cfg, theme, seeds, 7)
        renderers[f"{theme} worst case"] = frame_renderer(cfg, theme, seeds, 7, WORST_CASE)
    res: dict[str, list[float]] = {"warp": [], "naive": [], "step": [], "step randomised": [], "eval": []}
    res.update({k: [] for k in renderers})
    for _ in range(args.repeats):
        res["warp"].append(timed(warp, args.frames))
        res["naive"].append(timed(naive, max(200, args.frames // 10)))
        for name, fn in renderers.items():  # the variants in turn, so they see the same load
            res[name].append(timed(fn, args.frames))
        res["step"].append(timed(step, args.frames))
        res["step randomised"].append(timed(step_randomised, args.frames))
        t0 = time.process_time()
        report = evaluate("expert", [1], laps=2, cfg=cfg)
        res["eval"].append(report["overall"]["laps_completed"] / (time.process_time() - t0))
    med = {k: statistics.median(v) for k, v in res.items()}
    hz = cfg.DRIVE_LOOP_HZ
    print(f"simulator benchmark, {w}x{h}, one core (rates per CPU second), median of {args.repeats} runs")
    print(f"  renderer (perspective warp) : {med['warp']:9.0f} frames/s  "
          f"({med['warp'] / hz:.0f}x real time at {hz} Hz)")
    print(f"  naive ray-cast + remap      : {med['naive']:9.0f} frames/s  "
          f"(warp is {med['warp'] / med['naive']:.1f}x faster; {agree * 100:.1f} % of ground pixels within 2/255)")
    print("  whole frame (SimCar.render: ground, backdrop, distractors, shadow, sensor effects):")
    for theme in themes:
        plain = med[f"{theme} plain"]
        print(f"    {theme:7s} plain {plain:7.0f} frames/s | randomised {med[f'{theme} randomised']:7.0f} "
              f"({med[f'{theme} randomised'] / plain:.2f}x plain) | worst case {med[f'{theme} worst case']:7.0f} "
              f"({med[f'{theme} worst case'] / plain:.2f}x plain)")
    print(f"  full step (car+telemetry+render+expert): {med['step']:7.0f} steps/s "
          f"({med['step'] / hz:.0f}x real time); indoor randomised {med['step randomised']:7.0f} steps/s "
          f"({med['step randomised'] / hz:.0f}x real time)")
    print(f"  expert evaluation           : {med['eval']:9.1f} laps per CPU second "
          f"(no images drawn; a lap is ~14 s simulated)")
    print(f"  texture: {texture.image.shape[1]}x{texture.image.shape[0]} px at {texture.res:.3f} m/px")
    return 0


if __name__ == "__main__":
    sys.exit(main())
