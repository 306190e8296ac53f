"""Closed-loop evaluation wall time: tracks one after another against parallel worker processes.

    .venv/bin/python bench/eval.py                          # 8 tracks, expert and a linear pilot, 3 repeats
    .venv/bin/python bench/eval.py --model demo/models/demo_linear.pt --laps 2 --repeats 5

``vehicle.app.evaluate.evaluate`` with ``workers=1`` and with ``workers=0`` (one per core), run in
turn ``--repeats`` times on the same tracks, so both see the same load; medians, and the median of
the per-repeat ratios. Without ``--model`` the pilot is an untrained linear model exported to ONNX
(what it costs per step does not depend on its weights); each episode then runs its full
``--max-time``. Track textures are drawn afresh for every run (as in a new process). The reports
of the two runs are checked to be identical.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from parts.sim import simulator  # noqa: E402
from vehicle.app.evaluate import evaluate  # noqa: E402
from vehicle.config import Config  # noqa: E402

TRACKS = [101, 102, 103, 104, 105, 106, 107, 108]


def untrained_pilot(folder: Path) -> Path:
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess
    from training.export import export_model

    torch.manual_seed(0)
    pre = Preprocess(crop=(40, 0, 0, 0), normalize="symmetric", image_shape=(120, 160, 3))
    path = save_model(folder / "linear.pt", create_model("linear", pre.output_shape((120, 160, 3))),
                      {"preprocess": pre.to_dict()})
    export_model(path, "onnx")
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", help="a trained model file (default: an untrained linear model, ONNX)")
    parser.add_argument("--tracks", default=",".join(map(str, TRACKS)), help="comma-separated track seeds")
    parser.add_argument("--laps", type=int, default=1)
    parser.add_argument("--max-time", type=float, default=30.0, help="simulated seconds per track at most")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    seeds = [int(s) for s in args.tracks.split(",")]
    cfg = Config.defaults(ROI_CROP_TOP=40, SIM_EXPERT_SPEED=1.5)
    print(f"{os.cpu_count()} cores, load average {', '.join(f'{v:.1f}' for v in os.getloadavg())}; "
          f"{len(seeds)} tracks x {args.laps} lap(s), at most {args.max_time:.0f} simulated s each")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        model = Path(args.model) if args.model else untrained_pilot(Path(tmp))
        for pilot in ("expert", str(model)):
            times: dict[str, list[float]] = {"serial": [], "parallel": []}
            reports = {}
            for _ in range(args.repeats):
                for name, workers in (("serial", 1), ("parallel", 0)):
                    # as a fresh `vehicle sim eval` process: no track textures cached from the last run
                    # (the workers always start without)
                    simulator._WORLDS.clear()
                    t = time.perf_counter()
                    reports[name] = evaluate(pilot, seeds, args.laps, cfg=cfg, max_time=args.max_time,
                                             workers=workers)
                    times[name].append(time.perf_counter() - t)
                print(f"  {Path(pilot).name}: serial {times['serial'][-1]:.1f} s, parallel "
                      f"{times['parallel'][-1]:.1f} s", flush=True)
            a, b = (dict(reports[k]) for k in ("serial", "parallel"))
            a.pop("wall_time_s"), b.pop("wall_time_s")
            if a != b:
                raise SystemExit("the parallel report differs from the serial one")
            frames = reports["serial"]["overall"]["frames"]
            rows.append((Path(pilot).name, frames, statistics.median(times["serial"]),
                         statistics.median(times["parallel"]),
                         statistics.median(s / p for s, p in zip(times["serial"], times["parallel"], strict=True))))
    print(f"load average after: {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    print("\n| pilot | simulated frames | serial s | parallel s (one worker per core) | speed-up | reports |")
    print("|---|---|---|---|---|---|")
    for name, frames, serial, parallel, ratio in rows:
        print(f"| {name} | {frames} | {serial:.1f} | {parallel:.1f} | {ratio:.2f}x | identical |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
