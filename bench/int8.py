"""int8 ONNX against float ONNX: steering difference on a held-out tub and 1-thread latency, same run.

    .venv/bin/python bench/int8.py                      # linear and pilotnet (about 4 minutes on 2 cores)
    .venv/bin/python bench/int8.py --types linear --epochs 6 --iters 2000 --drive

The simulator expert records a training tub on tracks 1-4 and a held-out tub on tracks 101-102
(the demo's settings: 40 rows of sky cropped, 1.5 m/s). Each model type is trained on the training
tub (``training.trainer.train``, the real training path), exported to float ONNX and to int8
ONNX, static (calibrated on 300 frames of the training tub) and dynamic.

- **Accuracy**: every held-out frame through each export (the pilot's own preprocessing, batch 1);
  mean and p95 of |steering int8 - steering float|, and each one's mean |error| against the
  expert's recorded steering for scale.
- **Speed**: ONNX Runtime with 1 intra-op thread (the pilot's default), the exports called in turn,
  call by call, on the same preprocessed frames, so all see the same load; median and p99.
- ``--drive``: closed-loop evaluation of the float and int8 pilots on tracks 101-102, 2 laps.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from vehicle.config import Config  # noqa: E402

SETTINGS = {"ROI_CROP_TOP": 40, "BATCH_SIZE": 64, "SIM_EXPERT_SPEED": 1.5, "SHOW_PLOT": False}
EXPORTS = ("float", "int8 static", "int8 dynamic")


def machine_state() -> str:
    import onnxruntime

    from training.acceleration import cpu_caps

    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    return (f"{cpu_caps().name}, {os.cpu_count()} cores, load average {load}, onnxruntime "
            f"{onnxruntime.__version__}")


def held_out_inputs(runner: Any, tub: Path) -> tuple[list[np.ndarray], np.ndarray]:
    """Preprocessed frames (batch 1) of every record of ``tub`` and the recorded steering."""
    from parts.tub.reader import load_records

    frames, angles = [], []
    for rec in load_records([str(tub)]):
        frames.append(runner.preprocess(rec.image("cam/image_array"))[None])
        angles.append(float(rec.data["user/angle"]))
    return frames, np.asarray(angles)


def bench_type(mtype: str, cfg: Config, train_tub: Path, held_out: Path, folder: Path, epochs: int,
               iters: int, drive: bool) -> dict[str, Any]:
    from parts.pilots import load_pilot
    from training.export import export_model
    from training.trainer import train

    model = folder / "models" / f"{mtype}.pt"
    t = time.perf_counter()
    metrics = train(cfg, [train_tub], model, model_type_name=mtype, epochs=epochs, register=False)
    print(f"  {mtype}: trained {metrics['epochs']} epochs in {time.perf_counter() - t:.0f} s, "
          f"best val_loss {metrics['best_val_loss']:.4f}", flush=True)
    paths = {"float": export_model(model, "onnx")}
    for method in ("static", "dynamic"):
        t = time.perf_counter()
        paths[f"int8 {method}"] = export_model(model, "onnx-int8", folder / "models" / f"{mtype}.{method}.int8.onnx",
                                               int8=method, calibration=[train_tub])
        print(f"  {mtype}: int8 {method} export in {time.perf_counter() - t:.1f} s, "
              f"{paths[f'int8 {method}'].stat().st_size / 1e3:.0f} kB (float "
              f"{paths['float'].stat().st_size / 1e3:.0f} kB)", flush=True)
    runners = {k: load_pilot(p, onnx_threads=1).runner for k, p in paths.items()}
    frames, labels = held_out_inputs(runners["float"], held_out)
    steer = {k: np.array([r.predict(x, None)[0] for x in frames]) for k, r in runners.items()}
    row: dict[str, Any] = {"type": mtype, "frames": len(frames), "val_loss": metrics["best_val_loss"]}
    for k in EXPORTS:
        diff = np.abs(steer[k] - steer["float"])
        row[k] = {"mean_diff": float(diff.mean()), "p95_diff": float(np.percentile(diff, 95)),
                  "max_diff": float(diff.max()), "mae_label": float(np.abs(steer[k] - labels).mean())}
    # speed: round robin call by call over the same frames
    times: dict[str, list[float]] = {k: [] for k in runners}
    for r in runners.values():
        for x in frames[:50]:
            r.predict(x, None)
    clock = time.perf_counter
    for i in range(iters):
        x = frames[i % len(frames)]
        for k, r in runners.items():
            t = clock()
            r.predict(x, None)
            times[k].append(clock() - t)
    for k in EXPORTS:
        a = np.asarray(times[k]) * 1e3
        row[k].update(median_ms=float(np.median(a)), p99_ms=float(np.percentile(a, 99)))
        row[k]["speedup"] = statistics.median(times["float"]) / statistics.median(times[k])
    if drive:
        from vehicle.app.evaluate import evaluate

        for k, p in paths.items():
            report = evaluate(load_pilot(p, onnx_threads=1), [101, 102], 2, cfg=cfg)["overall"]
            row[k]["drive"] = {"autonomy": report["autonomy"], "laps": report["laps_completed"],
                               "mean_abs_cte": report["mean_abs_cte"]}
    for k in EXPORTS:
        r = row[k]
        print(f"  {mtype} {k}: |diff| mean {r['mean_diff']:.4f} p95 {r['p95_diff']:.4f}, |error| "
              f"{r['mae_label']:.4f}, {r['median_ms']:.3f} ms ({r['speedup']:.2f}x)", flush=True)
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--types", default="linear,pilotnet", help="comma-separated model types")
    parser.add_argument("--records", type=int, default=3000, help="training records")
    parser.add_argument("--held-out", type=int, default=600, help="held-out records (tracks 101, 102)")
    parser.add_argument("--epochs", type=int, default=4, help="training epochs per type")
    parser.add_argument("--iters", type=int, default=1500, help="timed calls per export")
    parser.add_argument("--drive", action="store_true", help="also evaluate each export closed-loop")
    args = parser.parse_args(argv)
    import torch

    from vehicle.app.record import record_expert

    print(f"machine: {machine_state()}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        cfg = Config.defaults(CAR_PATH=tmp, **SETTINGS)
        train_tub = record_expert(cfg, [1, 2, 3, 4], args.records, folder / "data" / "train", noise=0.4)
        held_out = record_expert(cfg, [101, 102], args.held_out, folder / "data" / "held_out", noise=0.0)
        for mtype in args.types.split(","):
            torch.set_num_threads(os.cpu_count() or 1)  # training uses the machine
            rows.append(bench_type(mtype, cfg, train_tub, held_out, folder, args.epochs, args.iters, args.drive))
    print(f"machine after: {machine_state()}")
    print("\n| type | export | mean / p95 / max abs steering diff vs float | mean abs error vs expert | "
          "median / p99 ms, 1 thread | speed vs float |" + (" closed loop: autonomy, laps, mean abs CTE |"
                                                             if args.drive else ""))
    print("|---|---|---|---|---|---|" + ("---|" if args.drive else ""))
    for row in rows:
        for k in EXPORTS:
            r = row[k]
            drive = ""
            if args.drive:
                d = r["drive"]
                drive = f" {d['autonomy']:.1f} %, {d['laps']}, {d['mean_abs_cte']} m |"
            print(f"| {row['type']} | {k} | {r['mean_diff']:.4f} / {r['p95_diff']:.4f} / {r['max_diff']:.4f} | "
                  f"{r['mae_label']:.4f} | {r['median_ms']:.3f} / {r['p99_ms']:.3f} | {r['speedup']:.2f}x |{drive}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
