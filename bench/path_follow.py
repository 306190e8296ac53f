"""Path follow in the built-in simulator: each localiser against the expert and a learned pilot.

For every track seed the expert drives one lap while the car records its path from the simulated
sensors (SIM_SEED + 1000: other noise than the runs that follow it), then the path follower drives
``--laps`` laps from odometry alone, GPS alone (a consumer receiver, SIM_GPS_NOISE = 1 m, and an RTK
one, 5 cm) and both fused; ``--pilot`` adds trained models on the same tracks. One row per driver:
the metrics of ``vehicle sim eval`` plus the true distance to the recorded path. ``--png`` draws
recorded vs driven path of the first track.

Usage: .venv/bin/python bench/path_follow.py [--tracks 1,2,3] [--laps 3] [--pilot models/x.pt ...]
       [--png docs/img/path_follow.png]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from parts.sim.eval_report import format_comparison
from parts.sim.metrics import overall
from vehicle.app.evaluate import _path_overall, evaluate
from vehicle.app.path_sim import PathDriver, record_path
from vehicle.config import Config

#: (row name, localiser, settings)
RUNS = (
    ("odometry", "odometry", {}),
    ("gps 1 m (consumer)", "gps", {}),
    ("gps 5 cm (RTK)", "gps", {"SIM_GPS_NOISE": 0.05}),
    ("fused, gps 1 m", "fused", {"LOC_ODOM_DRIFT": 0.005}),
    ("fused, gps 1 m, drift 2 %", "fused", {}),
)


def plot(paths: list[tuple[str, object, dict]], seed: int, out: str, laps: int) -> None:
    """Recorded path (world frame) and driven trajectory per localiser, over the track's centre line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from parts.sim.simulator import load_world

    track = load_world(seed).track
    fig, axes = plt.subplots(1, len(paths), figsize=(4.2 * len(paths), 4.8))
    for ax, (name, driver, report) in zip(np.atleast_1d(axes), paths, strict=True):
        centre = np.asarray(track.points)
        ax.plot(centre[:, 0], centre[:, 1], color="0.8", lw=6, label="road centre")
        rec = driver.distance.xy
        ax.plot(rec[:, 0], rec[:, 1], "o", ms=2.5, color="tab:blue", label="recorded path")
        traj = np.asarray(report["tracks"][0]["trajectory"])
        ax.plot(traj[:, 0], traj[:, 1], lw=0.8, color="tab:red", label=f"driven ({laps} laps)")
        o = report["overall"]
        ax.set_title(f"{name}\nmean |d| {o['mean_path_distance']:.3f} m, {o['interventions']} off-track", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    np.atleast_1d(axes)[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"track {seed}: recorded path (expert lap) and the follower's {laps} laps", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    fig.savefig(out, dpi=90)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tracks", default="1,2,3")
    ap.add_argument("--laps", type=int, default=3)
    ap.add_argument("--pilot", nargs="*", default=[], help="trained model files to compare")
    ap.add_argument("--png", help="draw recorded vs driven path of the first track here")
    args = ap.parse_args()
    seeds = [int(s) for s in args.tracks.split(",")]
    reports = []
    drawn = []
    for name, localizer, settings in RUNS:
        cfg = Config.defaults(**settings)
        tracks = []
        for seed in seeds:
            start = time.perf_counter()
            driver = PathDriver(record_path(cfg, seed, localizer), localizer, cfg, name=name)
            report = evaluate(driver, [seed], args.laps, cfg=cfg)
            tracks.append(report)
            if seed == seeds[0] and name in ("odometry", "gps 1 m (consumer)", "fused, gps 1 m"):
                drawn.append((name, driver, report))
            print(f"{name} track {seed}: {time.perf_counter() - start:.1f} s")  # noqa: T201
        merged = {**tracks[0], "tracks": [t["tracks"][0] for t in tracks], "seeds": seeds}
        merged["overall"] = {**overall(merged["tracks"], cfg.SIM_INTERVENTION_PENALTY, np.zeros(0)),
                             **_path_overall(merged["tracks"])}
        reports.append(merged)
    cfg = Config.defaults()
    reports.insert(0, evaluate("expert", seeds, args.laps, cfg=cfg))
    for i, model in enumerate(args.pilot):
        reports.insert(1 + i, evaluate(model, seeds, args.laps, cfg=cfg))
    print(format_comparison(reports))  # noqa: T201
    if args.png:
        plot(drawn, seeds[0], args.png, args.laps)
        print(f"wrote {args.png}")  # noqa: T201


if __name__ == "__main__":
    main()
