"""Cost of seeing what the pilot sees: ms per saliency map per method, and what --gallery adds.

    .venv/bin/python bench/saliency.py                 # linear and lanes models, 5 repeats
    .venv/bin/python bench/saliency.py --repeats 9 --tracks 101,102

Part 1: one torch thread (one core), a 120x160 frame of the built-in simulator (40 rows of sky
cropped), :meth:`parts.pilots.saliency.Explainer.explain` of the steering with each method (16
samples: integrated gradients' steps, SmoothGrad's noisy copies; occlusion: 1/8-side patches moved
by half a patch); median ms per map over ``--repeats`` rounds of 10 maps, beside one plain forward.

Part 2: ``vehicle.app.evaluate.evaluate`` of an untrained linear model at a fixed throttle 0.4 (it
leaves the road: the gallery has interventions to show) on ``--tracks``, one worker, with and
without ``gallery=`` (defaults: 2 s, 6 frames per moment, 3 worst-|CTE| moments), in turn, so both
see the same load; medians and the median ratio. Weights do not change the cost.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def model_file(folder: Path, model_type: str) -> Path:
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess
    from parts.vision.lanes import LaneSettings

    torch.manual_seed(0)
    lanes = LaneSettings().to_dict() if model_type == "lanes" else None
    pre = Preprocess(crop=(40, 0, 0, 0), image_shape=(120, 160, 3), lanes=lanes)
    model = create_model(model_type, pre.output_shape((120, 160, 3)))
    return save_model(folder / f"{model_type}.pt", model, {"preprocess": pre.to_dict()})


def maps(folder: Path, repeats: int) -> None:
    from parts.pilots.saliency import METHODS, Explainer

    frame = np.random.default_rng(0).integers(0, 256, (120, 160, 3), dtype=np.uint8)
    print("| model | input | forward ms | " + " | ".join(f"{m} ms" for m in METHODS) + " |")
    print("|---" * (3 + len(METHODS)) + "|")
    for model_type in ("linear", "lanes"):
        ex = Explainer.from_file(model_file(folder, model_type))
        ex.explain([frame])  # warm-up
        times: dict[str, list[float]] = {m: [] for m in ("forward", *METHODS)}
        for _ in range(repeats):
            for method in ("forward", *METHODS):
                t = time.perf_counter()
                for _ in range(10):
                    ex.predict([frame]) if method == "forward" else ex.explain([frame], method=method)
                times[method].append((time.perf_counter() - t) * 100.0)  # ms per map
        c, h, w = ex.model.input_shape
        cells = " | ".join(f"{statistics.median(times[m]):.1f}" for m in ("forward", *METHODS))
        print(f"| {model_type} | {c}x{h}x{w} | {cells} |")


def gallery_cost(folder: Path, tracks: list[int], repeats: int) -> None:
    from vehicle.app.evaluate import evaluate
    from vehicle.app.failure_moments import GallerySpec
    from vehicle.config import Config

    model = model_file(folder, "linear")
    cfg = Config.defaults(SIM_REALTIME=False)
    plain, with_gallery, ratios, moments = [], [], [], 0
    for k in range(repeats):
        t = time.perf_counter()
        evaluate(str(model), tracks, 1, cfg=cfg, max_time=30.0, fixed_throttle=0.4)
        a = time.perf_counter() - t
        out = folder / f"gallery{k}"
        t = time.perf_counter()
        report = evaluate(str(model), tracks, 1, cfg=cfg, max_time=30.0, fixed_throttle=0.4,
                          gallery=GallerySpec(str(out), str(model)))
        b = time.perf_counter() - t
        moments = sum(len(t["moments"]) for t in __import__("json").loads((out / "gallery.json").read_text())["tracks"])
        interventions = report["overall"]["interventions"]
        shutil.rmtree(out)
        plain.append(a)
        with_gallery.append(b)
        ratios.append(b / a)
    print(f"evaluation of {len(tracks)} track(s) x 30 s: {statistics.median(plain):.2f} s without, "
          f"{statistics.median(with_gallery):.2f} s with --gallery ({moments} moments, {interventions} "
          f"interventions); median ratio {statistics.median(ratios):.2f}, "
          f"+{(statistics.median(with_gallery) - statistics.median(plain)) / max(1, moments):.2f} s per moment")


def main() -> None:
    import torch

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--tracks", default="101,102")
    args = parser.parse_args()
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        maps(Path(tmp), args.repeats)
        gallery_cost(Path(tmp), [int(t) for t in args.tracks.split(",")], args.repeats)


if __name__ == "__main__":
    main()
