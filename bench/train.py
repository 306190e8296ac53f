"""Training throughput: the real training path against the fp32 eager baseline, in the same run.

    .venv/bin/python bench/train.py                          # linear and pilotnet, 5 rounds
    .venv/bin/python bench/train.py --types linear --rounds 9 --threads 1,2
    .venv/bin/python bench/train.py --compile                # + torch.compile (compile time too)
    .venv/bin/python bench/train.py --busy torch             # while other OpenMP jobs share the cores

A tub recorded by the simulator expert (``--records``, 4 training tracks) goes through the training
data path (tub reader, decoded-frame cache, augmentations, preprocessing, DataLoader, prefetch
thread) into ``training.fit.fit``, batch 64, the demo's preprocessing (40 rows of sky
cropped: linear sees 3x80x160, pilotnet 3x66x200 YUV). Each round trains one epoch of every
variant in turn, so all variants see the same load of the shared machine; the figures are medians
over the rounds, ratios taken within each round.

- **baseline**: training as it was before the device plan: fp32, contiguous NCHW, torch's own
  ``nn.Dropout``, Adam without the fused kernel.
- **real path**: what ``vehicle train`` runs: the plan of ``training.acceleration`` (printed),
  ``FastDropout``, fused Adam.
- **from memory**: the real path's model and plan fed batches already made (same samples, one
  augmentation draw); real / from memory is what the data path costs the training loop.
- **waiting**: the share of the real path's epoch time its loop waited for the next batch
  (``History.data_seconds``).

``--busy python`` keeps one pure-Python spinning process per core running during the timing;
``--busy torch`` one process per core multiplying matrices with 2 torch threads (OpenMP work
competing for the same cores, as other training jobs on a shared machine).
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

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from parts.pilots.models import create_model  # noqa: E402
from parts.pilots.models.base import FastDropout  # noqa: E402
from parts.pilots.preprocess import preprocess_from_config  # noqa: E402
from training.acceleration import TrainPlan, apply_layout, plan_for  # noqa: E402
from training.fit import FitSettings, fit, make_optimizer, plain_plan  # noqa: E402
from vehicle.config import Config  # noqa: E402

FRAME_SHAPE = (120, 160, 3)
SETTINGS = {"ROI_CROP_TOP": 40, "BATCH_SIZE": 64, "SIM_EXPERT_SPEED": 1.5}


def torch_dropout(model: torch.nn.Module) -> torch.nn.Module:
    """``model`` with every FastDropout replaced by torch's nn.Dropout (the baseline)."""
    for name, child in model.named_children():
        if isinstance(child, FastDropout):
            setattr(model, name, torch.nn.Dropout(child.p))
        else:
            torch_dropout(child)
    return model


def machine_state() -> str:
    """CPU, cores and load average, for the record."""
    from training.acceleration import cpu_caps

    caps = cpu_caps()
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    return (f"{caps.name}, {os.cpu_count()} cores, native bf16: {caps.native_bf16}, load average {load}, "
            f"torch {torch.__version__}")


class Variant:
    """One way of training: a model, its optimiser, its plan and the loader it reads."""

    def __init__(self, name: str, model: torch.nn.Module, plan: TrainPlan, loader: Any,
                 optimizer: torch.optim.Optimizer) -> None:
        self.name, self.model, self.plan, self.loader, self.optimizer = name, model, plan, loader, optimizer
        self.rates: list[float] = []
        self.waiting: list[float] = []

    def epoch(self, pre: Any) -> None:
        settings = FitSettings(epochs=1, patience=None, progress=False)
        h = fit(self.model, self.loader, None, pre, torch.device("cpu"), settings, optimizer=self.optimizer,
                plan=self.plan)
        self.rates.append(h.samples_per_s[-1])
        self.waiting.append(h.data_seconds[-1] / h.seconds[-1])


def variants(mtype: str, cfg: Config, tub: Path, compile_too: bool) -> tuple[list[Variant], Any]:
    """The variants of one model type, all on the same training samples."""
    from torch.utils.data import DataLoader, TensorDataset

    from training.dataset import read_drive_data
    from training.trainer import prepare_data

    data = read_drive_data([tub], modes=cfg.TRAIN_MODES)
    pre = preprocess_from_config(cfg, mtype, FRAME_SHAPE)
    shape = pre.output_shape(FRAME_SHAPE)
    torch.manual_seed(0)
    prep = prepare_data(cfg, data, create_model(mtype, shape), pre)
    batch = cfg.BATCH_SIZE

    def loader(dataset: Any) -> DataLoader:
        return DataLoader(dataset, batch_size=batch, shuffle=True, generator=torch.Generator().manual_seed(0))

    xs, es, ys = zip(*(prep.train[i] for i in range(len(prep.train))), strict=True)
    memory = TensorDataset(torch.stack(xs), torch.stack(es), torch.stack(ys))
    cpu = torch.device("cpu")
    lr = FitSettings().learning_rate

    def model() -> torch.nn.Module:
        torch.manual_seed(0)
        return create_model(mtype, shape)

    base = torch_dropout(model())
    out = [Variant("baseline", base, plain_plan(cpu), loader(prep.train), torch.optim.Adam(base.parameters(), lr))]
    real_plan = plan_for(cpu, "auto")
    for name, ds in (("real path", prep.train), ("from memory", memory)):
        m = apply_layout(model(), real_plan)
        out.append(Variant(name, m, real_plan, loader(ds), make_optimizer(m, FitSettings(), cpu)))
    if compile_too:
        plan = plan_for(cpu, "auto", compile=True)
        m = apply_layout(model(), plan)
        out.append(Variant("real path, compiled", m, plan, loader(prep.train), make_optimizer(m, FitSettings(), cpu)))
    print(f"  {mtype}: {len(prep.train)} training samples of {tuple(shape)}; plan: {real_plan.describe()}",
          flush=True)
    return out, pre


def bench_type(mtype: str, cfg: Config, tub: Path, rounds: int, compile_too: bool) -> dict[str, Any]:
    vs, pre = variants(mtype, cfg, tub, compile_too)
    by = {v.name: v for v in vs}
    if compile_too:  # the first epoch compiles: timed apart, then left out of the rounds
        v = by["real path, compiled"]
        t = time.perf_counter()
        v.epoch(pre)
        print(f"  compiled: first epoch {time.perf_counter() - t:.1f} s (compile included), "
              f"{v.rates[-1]:.0f} samples/s", flush=True)
        v.compile_epoch_s = time.perf_counter() - t  # type: ignore[attr-defined]
        v.rates.clear()
        v.waiting.clear()
    for v in vs:  # warm-up epoch each (allocator, oneDNN kernels), not counted
        v.epoch(pre)
        v.rates.clear()
        v.waiting.clear()
    for r in range(rounds):
        for v in vs:
            v.epoch(pre)
        line = ", ".join(f"{v.name} {v.rates[-1]:.0f}" for v in vs)
        print(f"  round {r + 1}/{rounds}: {line} samples/s; real path waited {by['real path'].waiting[-1]:.0%}",
              flush=True)
    base = by["baseline"].rates
    row: dict[str, Any] = {"type": mtype, "plan": by["real path"].plan.describe()}
    for v in vs:
        row[v.name] = statistics.median(v.rates)
        row[f"{v.name} x"] = statistics.median(a / b for a, b in zip(v.rates, base, strict=True))
    row["data share"] = 1.0 - statistics.median(
        a / b for a, b in zip(by["real path"].rates, by["from memory"].rates, strict=True))
    row["waiting"] = statistics.median(by["real path"].waiting)
    if compile_too:
        row["compile epoch s"] = by["real path, compiled"].compile_epoch_s  # type: ignore[attr-defined]
    return row


def _spin(kind: str, stop: Any) -> None:
    """A competing job until ``stop`` is set: pure Python, or torch matrix products on 2 threads."""
    if kind == "torch":
        torch.set_num_threads(2)
        a = torch.randn(256, 256)
        while not stop.is_set():
            for _ in range(20):
                a = torch.tanh(a @ a)
    else:
        x = 0
        while not stop.is_set():
            for _ in range(100_000):
                x += 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--types", default="linear,pilotnet", help="comma-separated model types")
    parser.add_argument("--records", type=int, default=3000, help="expert records to record")
    parser.add_argument("--rounds", type=int, default=5, help="timed epochs per variant")
    parser.add_argument("--threads", default=str(os.cpu_count() or 1),
                        help="comma-separated torch thread counts (default: all cores)")
    parser.add_argument("--compile", action="store_true", help="also time torch.compile (and its compile)")
    parser.add_argument("--busy", choices=("python", "torch"), help="competing jobs during the timing, one per core")
    args = parser.parse_args(argv)
    from vehicle.app.record import record_expert

    print(f"machine: {machine_state()}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        cfg = Config.defaults(CAR_PATH=tmp, **SETTINGS)
        t = time.perf_counter()
        tub = record_expert(cfg, [1, 2, 3, 4], args.records, Path(tmp) / "data" / "bench_tub", noise=0.4)
        print(f"recorded {args.records} expert records in {time.perf_counter() - t:.1f} s")
        busy = []
        if args.busy:
            import multiprocessing

            ctx = multiprocessing.get_context("spawn")
            stop = ctx.Event()
            busy = [ctx.Process(target=_spin, args=(args.busy, stop), daemon=True) for _ in range(os.cpu_count() or 1)]
            for proc in busy:
                proc.start()
            print(f"{len(busy)} competing {args.busy} processes running")
        for threads in (int(v) for v in args.threads.split(",")):
            torch.set_num_threads(threads)
            print(f"\n{threads} torch thread(s)")
            for mtype in args.types.split(","):
                rows.append({"threads": threads, **bench_type(mtype, cfg, tub, args.rounds, args.compile)})
        if busy:
            stop.set()
            for proc in busy:
                proc.join(timeout=10)
    print(f"\nmachine after: {machine_state()}")
    extra = " compiled samples/s (x) | first epoch with compile s |" if args.compile else ""
    print("\n| threads | type | plan | baseline samples/s | real path samples/s | real / baseline | "
          f"from memory samples/s | data path cost (1 - real / memory) | loop waiting for data |{extra}")
    print("|---|---|---|---|---|---|---|---|---|" + ("---|---|" if args.compile else ""))
    for r in rows:
        tail = (f" {r['real path, compiled']:.0f} ({r['real path, compiled x']:.2f}x) | {r['compile epoch s']:.1f} |"
                if args.compile else "")
        print(f"| {r['threads']} | {r['type']} | {r['plan'].split(' (')[0]} | {r['baseline']:.0f} | "
              f"{r['real path']:.0f} | {r['real path x']:.2f}x | {r['from memory']:.0f} | "
              f"{r['data share']:.0%} | {r['waiting']:.0%} |{tail}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
