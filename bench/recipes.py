"""Each source document's recipe, closed loop in the built-in simulator, beside our default pilot.

    .venv/bin/python bench/recipes.py --out /tmp/recipes            # all recipes + the default
    .venv/bin/python bench/recipes.py --recipes udacity-bc default --records 3000

The expert records once per frame size the recipes need (320x160 for the two Udacity-simulator
documents, DonkeyCar's 160x120 for the thesis and our default), on the demo's training tracks and
conditions (road and indoor themes, randomised, steering noise). Each recipe then trains exactly as
its document says (``vehicle train --recipe``), and every pilot drives the same unseen tracks in
the road, indoor and (never trained) park themes. Each recipe drives as its document's driver does
(drive_settings), with the document's speed set to the expert's speed in our simulator (a 1:10 car,
not the Udacity simulator's full-size one). Prints one table and writes ``results.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from training.recipes import RECIPES  # noqa: E402
from vehicle.app.demo import DEFAULTS, DEMO_SETTINGS  # noqa: E402
from vehicle.config import Config  # noqa: E402

THEMES = ("road", "indoor", "park")


def recording_settings(frame_shape: tuple[int, int]) -> dict[str, Any]:
    h, w = frame_shape
    return {**DEMO_SETTINGS, "SIM_CAMERA_W": w, "SIM_CAMERA_H": h, "IMAGE_W": w, "IMAGE_H": h}


def drive_settings(name: str, expert_speed: float) -> dict[str, Any]:
    if name == "default":
        return {}
    settings = dict(RECIPES[name].drive_settings)
    if settings.get("PILOT_SPEED_CONTROL", "off") != "off":
        settings["PILOT_SPEED_LIMIT"] = expert_speed
    return settings


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("/tmp/bench_recipes"))
    parser.add_argument("--recipes", nargs="+", default=[*sorted(RECIPES), "default"])
    parser.add_argument("--records", type=int, default=6000)
    parser.add_argument("--train-tracks", type=int, default=32, help="tracks 1..N")
    parser.add_argument("--eval-tracks", type=int, nargs="+", default=DEFAULTS["eval_tracks"])
    parser.add_argument("--laps", type=int, default=2)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()

    import logging

    import torch

    from training.trainer import train
    from vehicle.app.evaluate import evaluate
    from vehicle.app.record import record_expert

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    torch.set_num_threads(1)
    out = args.out.resolve()
    tubs: dict[tuple[int, int], Path] = {}
    results: dict[str, Any] = {}
    for name in args.recipes:
        r = RECIPES.get(name)
        shape = r.frame_shape if r else (120, 160)
        base = Config.defaults(CAR_PATH=str(out), **recording_settings(shape))
        if shape not in tubs:
            tub = out / "data" / f"tub_{shape[1]}x{shape[0]}"
            if not tub.exists():
                t = time.perf_counter()
                record_expert(base, list(range(1, args.train_tracks + 1)), args.records, tub, noise=DEFAULTS["noise"])
                print(f"recorded {args.records} {shape[1]}x{shape[0]} records in {time.perf_counter() - t:.0f} s",
                      flush=True)
            tubs[shape] = tub
        model = out / "models" / f"{name}.pt"
        cfg = base.replace(**r.settings) if r else base.replace(AUGMENTATIONS=DEMO_SETTINGS["AUGMENTATIONS"])
        t = time.perf_counter()
        metrics = train(cfg, [tubs[shape]], model, recipe=r, register=False,
                        epochs=None if r else DEFAULTS["epochs"])
        train_s = time.perf_counter() - t
        row: dict[str, Any] = {"train_s": round(train_s, 1), "epochs": metrics["epochs"],
                               "best_val_loss": metrics["best_val_loss"], "themes": {}}
        for theme in THEMES:
            c = base.replace(SIM_THEME=theme, SIM_RANDOMIZE=None,
                             **drive_settings(name, DEMO_SETTINGS["SIM_EXPERT_SPEED"]))
            report = evaluate(model, args.eval_tracks, args.laps, cfg=c, workers=args.workers)
            o = report["overall"]
            row["themes"][theme] = {k: o.get(k) for k in ("autonomy", "laps_completed", "interventions",
                                                           "mean_abs_cte", "mean_speed")}
        results[name] = row
        (out / "results.json").write_text(json.dumps(results, indent=2))
        print(json.dumps({name: row}), flush=True)
    print(f"\n{'recipe':16} {'train s':>8} {'epochs':>6}  " + "  ".join(f"{t:>24}" for t in THEMES))
    for name, row in results.items():
        cells = "  ".join(f"{v['autonomy']:6.1f} % {v['laps_completed']:3d} laps {v['mean_abs_cte']:.3f} m"
                          for v in row["themes"].values())
        print(f"{name:16} {row['train_s']:8.0f} {row['epochs']:6d}  {cells}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
