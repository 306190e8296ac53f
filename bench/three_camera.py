"""The three-camera model beside a single-camera DAVE-2 on the same three-camera data, closed loop
in the built-in simulator.

    .venv/bin/python bench/three_camera.py --out /tmp/bench_three --records 2000 --epochs 4

The expert records with side cameras (SIM_SIDE_CAMERAS_OFFSET) on the demo's training tracks and
conditions (road and indoor themes, randomised, steering noise). Two pilots train on that one tub
with the same preprocessing, augmentations and epochs: ``three_camera`` (the three frames as one
input) and ``pilotnet`` with ELU (Track Driver AI's DAVE-2), which learns from the side frames as
extra samples with a steering offset of ±0.15 (the document's ``side_cam_offset``) and drives on
the centre frame. Both drive the same unseen tracks in the road, indoor and (never trained) park
themes, with the side cameras on. Prints one table and writes ``results.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from vehicle.app.demo import DEFAULTS, DEMO_SETTINGS  # noqa: E402
from vehicle.config import Config  # noqa: E402

THEMES = ("road", "indoor", "park")
PILOTS: dict[str, dict[str, Any]] = {
    "three_camera": {"DEFAULT_MODEL_TYPE": "three_camera", "TRAIN_SIDE_CAMERAS": {}},
    "pilotnet+side": {"DEFAULT_MODEL_TYPE": "pilotnet", "MODEL_OPTIONS": {"activation": "elu", "dropout": 0.0},
                      "TRAIN_SIDE_CAMERAS": {"cam/image_array_left": 0.15, "cam/image_array_right": -0.15}},
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("/tmp/bench_three"))
    parser.add_argument("--records", type=int, default=2000)
    parser.add_argument("--epochs", type=int, default=4)
    parser.add_argument("--offset", type=float, default=0.1, help="SIM_SIDE_CAMERAS_OFFSET, metres")
    parser.add_argument("--train-tracks", type=int, default=16, help="tracks 1..N")
    parser.add_argument("--eval-tracks", type=int, nargs="+", default=DEFAULTS["eval_tracks"])
    parser.add_argument("--laps", type=int, default=2)
    parser.add_argument("--themes", nargs="+", default=list(THEMES), help="themes to drive in (park: never trained)")
    parser.add_argument("--reuse", action="store_true", help="drive the models of an earlier run (no training)")
    args = parser.parse_args()

    import logging

    import torch

    from parts.pilots.modelfile import read_meta
    from training.trainer import train
    from vehicle.app.evaluate import evaluate
    from vehicle.app.record import record_expert

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    torch.set_num_threads(1)
    out = args.out.resolve()
    base = Config.defaults(CAR_PATH=str(out), **{**DEMO_SETTINGS, "SHOW_PLOT": False},
                           SIM_SIDE_CAMERAS_OFFSET=args.offset, PREPROCESS_RESIZE=[66, 100])
    tub = out / "data" / "tub_three"
    if not tub.exists():
        t = time.perf_counter()
        record_expert(base, list(range(1, args.train_tracks + 1)), args.records, tub, noise=DEFAULTS["noise"])
        print(f"recorded {args.records} three-camera records in {time.perf_counter() - t:.0f} s", flush=True)
    results: dict[str, Any] = {}
    for name, settings in PILOTS.items():
        model = out / "models" / f"{name}.pt"
        t = time.perf_counter()
        if args.reuse and model.exists():
            metrics = read_meta(model)["metrics"]
        else:
            metrics = train(base.replace(**settings), [tub], model, epochs=args.epochs, register=False, workers=0)
        row: dict[str, Any] = {"train_s": round(time.perf_counter() - t, 1), "epochs": metrics["epochs"],
                               "train_samples": metrics["train_samples"], "best_val_loss": metrics["best_val_loss"],
                               "themes": {}}
        for theme in args.themes:
            report = evaluate(model, args.eval_tracks, args.laps, cfg=base.replace(SIM_THEME=theme, SIM_RANDOMIZE=None))
            o = report["overall"]
            row["themes"][theme] = {k: o.get(k) for k in ("autonomy", "laps_completed", "interventions",
                                                           "mean_abs_cte", "mean_speed")}
        results[name] = row
        (out / "results.json").write_text(json.dumps(results, indent=2))
        print(json.dumps({name: row}), flush=True)
    print(f"\n{'pilot':14} {'theme':7} {'autonomy':>9} {'laps':>5} {'interv.':>7} {'|cte| m':>8}")
    for name, r in results.items():
        for theme, v in r["themes"].items():
            print(f"{name:14} {theme:7} {v['autonomy']:8.1f}% {v['laps_completed']:5d} {v['interventions']:7d} "
                  f"{v['mean_abs_cte']:8.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
