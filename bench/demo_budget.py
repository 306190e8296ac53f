"""The demo's pilot on a training budget: closed-loop result against sample-steps, over seeds.

    .venv/bin/python bench/demo_budget.py --out /tmp/budget --records 12000 \
        --variant 'base:{"epochs": 10}' --variant 'oc4:{"epochs": 4, "TRAIN_LR_SCHEDULE": "one_cycle"}' \
        --seeds 1 2 3

Records the demo's tub once per record count (the demo's settings, tracks 1-64, steering noise
0.4; kept in ``--out`` and reused), then for every variant and training seed trains the demo's
model and drives it ``--laps`` laps on each unseen track of ``--eval-tracks`` in the road, indoor
and park themes (the demo's evaluation, pilot only). A variant is ``name:{json}``: ``epochs``,
``records`` (which tub) and any setting (``BATCH_SIZE``, ``LEARNING_RATE``, ``TRAIN_LR_SCHEDULE``,
``TRAIN_BALANCE``, ...) on top of the demo's. Cost is counted in sample-steps (training samples
the optimiser stepped on, and validation samples, which cost about a third of one), not seconds:
the machine is shared. One JSON line per run goes to ``--out``/runs.jsonl and stdout; a summary
table closes the run.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def tub_for(out: Path, records: int, cfg: Any, tracks: list[int], noise: float) -> Path:
    """The demo's tub of ``records`` records, recorded once."""
    from vehicle.app.record import record_expert

    tub = out / f"tub_{records}"
    if not (tub / "done").exists():
        t = time.perf_counter()
        record_expert(cfg, tracks, records, tub, noise=noise)
        (tub / "done").write_text(f"{time.perf_counter() - t:.1f}\n")
    return tub


def run(out: Path, name: str, variant: dict[str, Any], seed: int, args: argparse.Namespace) -> dict[str, Any]:
    from training.trainer import train
    from vehicle.app.demo import DEFAULTS, DEMO_SETTINGS
    from vehicle.app.evaluate import evaluate
    from vehicle.config import Config

    variant = dict(variant)
    epochs = int(variant.pop("epochs", DEFAULTS["epochs"]))
    records = int(variant.pop("records", args.records))
    settings = {**DEMO_SETTINGS, "SHOW_PLOT": False, **variant, "TRAIN_SEED": seed}
    cfg = Config.defaults(CAR_PATH=str(out), **settings)
    tub = tub_for(out, records, Config.defaults(CAR_PATH=str(out), **DEMO_SETTINGS), DEFAULTS["train_tracks"],
                  DEFAULTS["noise"])
    model = out / "models" / f"{name}_s{seed}.pt"
    t, load = time.perf_counter(), os.getloadavg()[0]
    m = train(cfg, [tub], model, epochs=epochs, register=False, progress=False)
    train_s = time.perf_counter() - t
    row: dict[str, Any] = {"variant": name, "seed": seed, "records": records, "epochs": m["epochs"],
                           "train_samples": m["train_samples"], "val_samples": m["val_samples"],
                           "sample_steps": sum(m["epoch_samples"]),
                           "val_sample_passes": m["val_samples"] * m["epochs"],
                           "best_val_loss": m["best_val_loss"], "best_epoch": m["best_epoch"],
                           "train_s": round(train_s, 1), "samples_per_s": round(sum(m["epoch_samples"]) /
                                                                               sum(m["epoch_seconds"]), 1),
                           "load": round(load, 1), "settings": variant}
    for theme in ("road", "indoor", "park"):
        r = evaluate(model, args.eval_tracks, args.laps, cfg=cfg.replace(SIM_THEME=theme, SIM_RANDOMIZE=None),
                     workers=1)
        o = r["overall"]
        row[theme] = {"autonomy": round(o["autonomy"], 1), "laps": o["laps_completed"],
                      "interventions": o["interventions"], "cte": round(o["mean_abs_cte"], 4)}
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--records", type=int, default=12000)
    parser.add_argument("--variant", action="append", required=True, help="name:{json settings}")
    parser.add_argument("--seeds", type=int, nargs="+", default=[42])
    parser.add_argument("--eval-tracks", type=int, nargs="+", default=[101, 102, 103, 104, 105])
    parser.add_argument("--laps", type=int, default=2)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)
    import torch

    logging.basicConfig(level=logging.WARNING)
    torch.set_num_threads(args.threads)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for spec in args.variant:
        name, _, body = spec.partition(":")
        for seed in args.seeds:
            row = run(args.out, name, json.loads(body or "{}"), seed, args)
            rows.append(row)
            line = json.dumps(row)
            print(line, flush=True)
            with open(args.out / "runs.jsonl", "a") as f:
                f.write(line + "\n")
    print("\n| variant | seed | records | epochs | sample-steps | best val loss | road / indoor / park autonomy "
          "(laps) | load |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        res = " / ".join(f"{r[t]['autonomy']:.0f} ({r[t]['laps']})" for t in ("road", "indoor", "park"))
        print(f"| {r['variant']} | {r['seed']} | {r['records']} | {r['epochs']} | {r['sample_steps']} | "
              f"{r['best_val_loss']:.4f} | {res} | {r['load']} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
