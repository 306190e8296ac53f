"""Robustness ablation: which training augmentations and recording ranges close the gap to hidden
randomisation draws and a theme never trained on.

    .venv/bin/python bench/robust.py --tub /tmp/robust/tub_demo --out /tmp/robust \
        --variant demo --variant light:+light --variant all:+light,colour,noise,cutout

Each variant trains the demo's ``linear`` pilot (DEMO_SETTINGS, the demo's epochs) on the given
tub with the demo's augmentations plus (``+a,b``) or instead of (``=a,b``) the listed ones, then
drives the unseen tracks in road, indoor and (never trained) park under each hidden randomisation
draw (seeds never used in training), beside the expert. ``NAME:SPEC@TUB`` trains on another tub
(e.g. one recorded with wider ranges; ``@A,B`` trains on both). Writes ``OUT/ablation.json`` and
prints one row per variant: mean and worst autonomy per theme, interventions, pilot speed / expert
speed, training seconds.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from vehicle.app.demo import DEFAULTS, DEMO_SETTINGS  # noqa: E402

THEMES = ("road", "indoor", "park")


def parse_variant(text: str, default_tub: Path) -> tuple[str, list[str], list[Path], dict[str, Any]]:
    """``NAME[:+a,b|=a,b][@TUB[,TUB...]][#SETTING=VALUE;...]`` -> (name, augmentations, tubs, settings)."""
    settings: dict[str, Any] = {}
    if "#" in text:
        text, extra = text.split("#", 1)
        for item in extra.split(";"):
            key, value = item.split("=", 1)
            settings[key] = eval(value, {})  # noqa: S307 - a benchmark's own command line
    tubs = [default_tub]
    if "@" in text:
        text, tub_text = text.split("@", 1)
        tubs = [Path(t) for t in tub_text.split(",")]
    name, _, spec = text.partition(":")
    augs = list(DEMO_SETTINGS["AUGMENTATIONS"])
    if spec.startswith("+"):
        augs += [a for a in spec[1:].split(",") if a]
    elif spec.startswith("="):
        augs = [a for a in spec[1:].split(",") if a]
    return name, augs, tubs, settings


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tub", type=Path, required=True, help="tub the demo's expert recorded")
    parser.add_argument("--out", type=Path, default=Path("/tmp/robust"))
    parser.add_argument("--variant", action="append", default=[])
    parser.add_argument("--cost", action="store_true", help="only measure each augmentation's ms per batch")
    parser.add_argument("--draws", type=int, nargs="+", default=[2, 3, 777], help="hidden randomisation seeds")
    parser.add_argument("--eval-tracks", type=int, nargs="+", default=DEFAULTS["eval_tracks"])
    parser.add_argument("--laps", type=int, default=2)
    parser.add_argument("--epochs", type=int, default=DEFAULTS["epochs"])
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()

    import logging
    import os

    import torch

    from training.trainer import train
    from vehicle.app.evaluate import evaluate
    from vehicle.config import Config

    logging.basicConfig(level=logging.WARNING)
    if args.cost:
        print(json.dumps({"ms_per_batch": augmentation_cost(args.tub), "load": os.getloadavg()}))
        return 0
    torch.set_num_threads(1)
    out = args.out.resolve()
    path = out / "ablation.json"
    results: dict[str, Any] = json.loads(path.read_text()) if path.exists() else {}
    base = Config.defaults(CAR_PATH=str(out), **DEMO_SETTINGS)
    if DEMO_SETTINGS["SIM_RANDOMIZE"] in args.draws:
        raise SystemExit(f"draw {DEMO_SETTINGS['SIM_RANDOMIZE']} is the training draw")
    expert: dict[str, Any] = results.get("_expert", {})
    for text in args.variant:
        name, augs, tubs, settings = parse_variant(text, args.tub)
        model = out / "models" / f"{name}.pt"
        cfg = base.replace(AUGMENTATIONS=augs, **settings)
        t = time.perf_counter()
        metrics = train(cfg, tubs, model, register=False, epochs=args.epochs)
        row: dict[str, Any] = {"augmentations": augs, "tubs": [str(p) for p in tubs],
                               "settings": {k: repr(v) for k, v in settings.items()},
                               "train_s": round(time.perf_counter() - t, 1), "epochs": metrics["epochs"],
                               "best_val_loss": metrics["best_val_loss"], "load": os.getloadavg()[0], "runs": {}}
        for theme in THEMES:
            for draw in args.draws:
                c = cfg.replace(SIM_THEME=theme, SIM_RANDOMIZE=draw)
                key = f"{theme}/{draw}"
                o = evaluate(model, args.eval_tracks, args.laps, cfg=c, workers=args.workers)["overall"]
                if key not in expert:
                    e = evaluate("expert", args.eval_tracks, args.laps, cfg=c, workers=args.workers)["overall"]
                    expert[key] = {k: e.get(k) for k in ("autonomy", "interventions", "mean_speed")}
                row["runs"][key] = {k: o.get(k) for k in ("autonomy", "interventions", "mean_abs_cte", "mean_speed")}
                print(name, key, row["runs"][key], "expert", expert[key], flush=True)
        results[name] = row
        results["_expert"] = expert
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(results, indent=1))
        print(json.dumps({name: summary(row, expert)}), flush=True)
    print(table(results))
    return 0


def _per_frame(aug: Any, frames: list[Any], rng: Any) -> list[Any]:
    return [aug.apply(f, aug.draw(rng)) for f in frames]


def augmentation_cost(tub: Path, repeats: int = 20) -> dict[str, float]:
    """Milliseconds per batch of BATCH_SIZE demo frames: each per-frame augmentation (OpenCV, in
    the data loader) and each batch augmentation (torch, on the cropped batch), always applied."""
    import numpy as np
    import torch

    from parts.pilots.preprocess import Preprocess
    from parts.tub.reader import load_records
    from training.augment import BATCH_AUGMENTATIONS, SAMPLE_AUGMENTATIONS, Augmenter, AugmentSettings
    from training.batch_augment import BatchAugmenter

    torch.set_num_threads(1)
    n = DEMO_SETTINGS["BATCH_SIZE"]
    frames = [r.image() for r in list(load_records([str(tub)]))[:n]]
    pre = Preprocess(crop=(DEMO_SETTINGS["ROI_CROP_TOP"], 0, 0, 0), image_shape=frames[0].shape)
    batch = torch.stack([Preprocess.to_chw(pre.frame(f)) for f in frames])
    rng = np.random.default_rng(0)
    out: dict[str, float] = {}
    for name in (*SAMPLE_AUGMENTATIONS, *BATCH_AUGMENTATIONS):
        settings = AugmentSettings(names=(name,), **{f"{name}_p": 1.0})
        run = functools.partial(BatchAugmenter(settings), batch) if name in BATCH_AUGMENTATIONS else \
            functools.partial(_per_frame, Augmenter(settings), frames, rng)
        run()
        t = time.perf_counter()
        for _ in range(repeats):
            run()
        out[name] = round((time.perf_counter() - t) / repeats * 1000, 2)
    return out


def summary(row: dict[str, Any], expert: dict[str, Any]) -> dict[str, Any]:
    """Per theme: mean and worst autonomy over the draws, interventions; the speed ratio."""
    out: dict[str, Any] = {"train_s": row["train_s"]}
    ratios = []
    for theme in THEMES:
        runs = {k: v for k, v in row["runs"].items() if k.startswith(theme + "/")}
        autos = [v["autonomy"] for v in runs.values()]
        out[theme] = {"mean": round(sum(autos) / len(autos), 1), "worst": round(min(autos), 1),
                      "interventions": sum(v["interventions"] for v in runs.values())}
        ratios += [v["mean_speed"] / expert[k]["mean_speed"] for k, v in runs.items() if expert[k]["mean_speed"]]
    out["speed_ratio"] = round(sum(ratios) / len(ratios), 3) if ratios else None
    return out


def table(results: dict[str, Any]) -> str:
    expert = results.get("_expert", {})
    lines = [f"{'variant':18} {'train s':>7}  " + "  ".join(f"{t + ' mean/worst/int':>24}" for t in THEMES)
             + "  speed"]
    for name, row in results.items():
        if name.startswith("_"):
            continue
        s = summary(row, expert)
        cells = "  ".join(f"{s[t]['mean']:8.1f} {s[t]['worst']:6.1f} {s[t]['interventions']:5d}    " for t in THEMES)
        lines.append(f"{name:18} {s['train_s']:7.0f}  {cells}  {s['speed_ratio']}")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
