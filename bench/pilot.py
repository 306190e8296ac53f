"""Pilot benchmarks: inference latency per model type and runtime, and the pilot part's overhead.

    .venv/bin/python bench/pilot.py                 # every type (about 1 minute on 2 cores)
    .venv/bin/python bench/pilot.py --types linear --iters 300 --repeats 5

Training throughput is bench/train.py; int8 exports are bench/int8.py.

Inference: batch 1, 1 CPU thread (torch.set_num_threads(1); ONNX Runtime intra_op_num_threads=1),
120x160 camera frames with the car's default preprocessing for each type (pilotnet: 66x200 YUV).
The runtimes are timed call by call in turn (``--repeats`` x ``--iters`` calls each), so all of
them see the same load of the shared, noisy machine; median and p99 are over all calls. "bare" is
the model alone on an already preprocessed tensor; "part" is ``Pilot.run(frame)``, preprocessing
included; the overhead compares the part with the same runtime's preprocessing + bare forward,
the least work that turns a frame into a command.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from parts.pilots import load_pilot  # noqa: E402
from parts.pilots.modelfile import load_model, save_model  # noqa: E402
from parts.pilots.models import create_model, model_type_names  # noqa: E402
from parts.pilots.preprocess import preprocess_from_config  # noqa: E402
from training.export import export_model  # noqa: E402
from vehicle.config import Config  # noqa: E402

FRAME_SHAPE = (120, 160, 3)


def macs(model: torch.nn.Module, inputs: tuple[torch.Tensor, ...]) -> int:
    """Multiply-accumulates of one forward (conv, linear and LSTM layers)."""
    total = 0

    def conv(mod: torch.nn.Module, _inp: tuple, out: torch.Tensor) -> None:
        nonlocal total
        k = int(np.prod(mod.kernel_size)) * mod.in_channels // mod.groups
        total += out.numel() * k

    def linear(mod: torch.nn.Module, _inp: tuple, out: torch.Tensor) -> None:
        nonlocal total
        total += out.numel() * mod.in_features

    def lstm(mod: torch.nn.Module, inp: tuple, _out: tuple) -> None:
        nonlocal total
        steps = inp[0].shape[0] * inp[0].shape[1]
        total += steps * 4 * mod.hidden_size * (mod.input_size + mod.hidden_size)

    hooks = []
    for m in model.modules():
        if isinstance(m, torch.nn.Conv2d | torch.nn.Conv3d):
            hooks.append(m.register_forward_hook(conv))
        elif isinstance(m, torch.nn.Linear):
            hooks.append(m.register_forward_hook(linear))
        elif isinstance(m, torch.nn.LSTM):
            hooks.append(m.register_forward_hook(lstm))
    with torch.no_grad():
        model(*inputs)
    for h in hooks:
        h.remove()
    return total


def time_calls(fn: Callable[[], object], n: int) -> list[float]:
    """Wall time of ``n`` calls of ``fn``, seconds each."""
    out = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def summary(samples: list[float]) -> tuple[float, float]:
    """(median, p99) in milliseconds."""
    a = np.asarray(samples) * 1e3
    return float(np.median(a)), float(np.percentile(a, 99))


def inference(types: list[str], iters: int, repeats: int, folder: Path) -> list[dict]:
    """Latency rows, one per model type."""
    cfg = Config.defaults()
    frame = np.random.default_rng(0).integers(0, 256, FRAME_SHAPE, dtype=np.uint8)
    rows = []
    for mtype in types:
        row = bench_type(mtype, cfg, frame, iters, repeats, folder)
        rows.append(row)
        print(f"  {mtype}: eager {row['eager'][0]:.3f} ms, torchscript {row['torchscript'][0]:.3f} ms, "
              f"onnx {row['onnx'][0]:.3f} ms, part(torch) {row['part_torch'][0]:.3f} ms", flush=True)
    return rows


def bench_type(mtype: str, cfg: Config, frame: np.ndarray, iters: int, repeats: int, folder: Path) -> dict:
    """Time one model type in every runtime, bare and as the Pilot part."""
    pre = preprocess_from_config(cfg, mtype, FRAME_SHAPE)
    options = {"seq_length": 3} if mtype in ("rnn", "3d") else {}
    model = create_model(mtype, pre.output_shape(FRAME_SHAPE), **options)
    path = save_model(folder / f"{mtype}.pt", model, {"preprocess": pre.to_dict()})
    export_model(path, "onnx")
    export_model(path, "torchscript")
    model, meta = load_model(path)
    desc = meta["model"]
    x = pre(frame)
    images = x.expand(desc["frames"], *x.shape)[None].contiguous() if desc["frames"] > 1 else x[None]
    extra = torch.zeros(1, desc["extra_size"]) if desc["extra_size"] else None
    extra_values = [[1.0] + [0.0] * (desc["extra_size"] - 1)] * len(desc["extra_inputs"])
    pilots = {b: load_pilot(path, backend=b) for b in ("torch", "torchscript", "onnx")}
    ts_module = pilots["torchscript"].runner.module
    session = pilots["onnx"].runner.session
    names = pilots["onnx"].runner.input_names
    feed = {names[0]: images.numpy()}
    if extra is not None:
        feed[names[1]] = extra.numpy()
    ts_args = (images,) if extra is None else (images, extra)

    def eager() -> None:
        with torch.inference_mode():
            model.controls(model(images, extra))

    def script() -> None:
        with torch.inference_mode():
            ts_module(*ts_args)

    def onnx() -> None:
        session.run(None, feed)

    def preprocess() -> None:
        pre(frame)

    calls: dict[str, Callable[[], object]] = {
        "eager": eager, "torchscript": script, "onnx": onnx, "preprocess": preprocess,
        **{f"part_{b}": (lambda p=p: p.run(frame, *extra_values)) for b, p in pilots.items()},
    }
    for fn in calls.values():  # warm up (allocator, ORT graph optimisations)
        time_calls(fn, 20)
    # Round robin, call by call: every runtime samples the same moments of the shared machine's
    # load, so the ratios hold even when the absolute times drift.
    samples: dict[str, list[float]] = {k: [] for k in calls}
    clock = time.perf_counter
    for _ in range(repeats * iters):
        for k, fn in calls.items():
            t = clock()
            fn()
            samples[k].append(clock() - t)
    row: dict = {"type": mtype, "input": "x".join(map(str, images.shape[1:])),
                 "mmacs": macs(model, (images, extra)) / 1e6}
    for k, v in samples.items():
        row[k] = summary(v)
    pre_ms = row["preprocess"][0]
    for b, bare in (("torch", "eager"), ("torchscript", "torchscript"), ("onnx", "onnx")):
        row[f"overhead_{b}"] = row[f"part_{b}"][0] / (pre_ms + row[bare][0]) - 1.0
    return row


def _ms(row: dict, key: str) -> str:
    return f"{row[key][0]:.3f} / {row[key][1]:.3f}"


def print_inference(rows: list[dict]) -> None:
    print("\n| type | input (CxHxW) | MMACs | eager median / p99 ms | TorchScript | ONNX Runtime | "
          "ONNX speed-up | preprocess ms | Pilot.run (torch) | part vs preprocess + forward, torch / onnx | "
          "part vs forward alone (torch) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['type']} | {r['input']} | {r['mmacs']:.1f} | {_ms(r, 'eager')} | {_ms(r, 'torchscript')} | "
              f"{_ms(r, 'onnx')} | {r['eager'][0] / r['onnx'][0]:.2f}x | {r['preprocess'][0]:.3f} | "
              f"{_ms(r, 'part_torch')} | {r['overhead_torch'] * 100:+.1f} % / {r['overhead_onnx'] * 100:+.1f} % | "
              f"{(r['part_torch'][0] / r['eager'][0] - 1) * 100:+.1f} % |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--types", default="all", help="comma-separated model types (default: all)")
    parser.add_argument("--iters", type=int, default=200, help="calls per timing run")
    parser.add_argument("--repeats", type=int, default=3, help="timing rounds (x iters calls per runtime)")
    args = parser.parse_args(argv)
    types = model_type_names() if args.types == "all" else args.types.split(",")
    torch.set_num_threads(1)
    print(f"torch {torch.__version__}, 1 thread, frames {FRAME_SHAPE}")
    with tempfile.TemporaryDirectory() as tmp:
        rows = inference(types, args.iters, args.repeats, Path(tmp))
        print_inference(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
