"""Our trainer beside DonkeyCar 5.3's Keras trainer on the same tub, in alternating rounds of one run.

    .venv/bin/python bench/donkey_train.py --tub TUB --heldout TUB2 --rounds 4 \
        --donkey-python .bench/donkey-venv/bin/python [--emulate-avx2] [--out /tmp/donkey_train]

Two worker processes train side by side, each paused between epochs: DonkeyCar's
(bench/donkey_keras_worker.py, in DonkeyCar's venv made by ``WITH_TENSORFLOW=1
bench/setup_donkey_venv.sh``: TubDataset, its 80/20 split, BatchSequence tf.data, KerasLinear, Adam
1e-3, MSE) and ours (``training.trainer.train``, the demo's settings with no augmentation, as
DonkeyCar's default has none). Both see 80x160 frames (the demo's 40 rows of sky cropped), batch
64, the same torch/TF thread count. Round k: DonkeyCar trains epoch k; then ours trains epochs until
its wall time has caught up with DonkeyCar's. Alternating makes both see the same machine load.

Reported: training samples/s of each (steady rounds: round 1 decodes the JPEGs), and, at the wall
time DonkeyCar took for ``--rounds`` epochs, the model each trainer hands over (its best by its
own validation loss so far): MSE on a held-out tub recorded on other tracks (the same records and
the same evaluation code for both; DonkeyCar's weights are copied into our identical linear model
with its [0, 1] pixel scaling), and the closed-loop result on unseen tracks in three themes.
``--emulate-avx2`` runs both as on a CPU without AVX-512 (and so without bf16): oneDNN and MKL
held to AVX2, torch's kernels to avx2 (ATEN_CPU_CAPABILITY), our training in fp32.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

AVX2_ENV = {"ONEDNN_MAX_CPU_ISA": "AVX2", "MKL_ENABLE_INSTRUCTIONS": "AVX2", "ATEN_CPU_CAPABILITY": "avx2"}
CROP_TOP, BATCH = 40, 64


def ours_worker(tub: str, out: str, threads: int, precision: str) -> int:
    """Our trainer, paused after every epoch until the parent says ``epoch`` (go on) or ``stop``."""
    import logging

    import torch

    from training.trainer import train
    from vehicle.app.demo import DEMO_SETTINGS
    from vehicle.config import Config

    logging.basicConfig(level=logging.WARNING)
    torch.set_num_threads(threads)
    cfg = Config.defaults(CAR_PATH=out, **{**DEMO_SETTINGS, "AUGMENTATIONS": [], "BATCH_SIZE": BATCH,
                                           "ROI_CROP_TOP": CROP_TOP, "USE_EARLY_STOP": False, "SHOW_PLOT": False,
                                           "TRAIN_PRECISION": precision, "LEARNING_RATE": 0.001})
    model = Path(out) / "ours.pt"
    stop = threading.Event()
    clock = {"start": time.perf_counter(), "cpu": time.process_time()}

    def on_event(event: dict[str, Any]) -> None:
        if event["event"] != "epoch":
            return
        seconds, cpu = time.perf_counter() - clock["start"], time.process_time() - clock["cpu"]
        shutil.copy(model, Path(out) / f"ours_e{event['epoch']}.pt")  # the best so far, as handed over now
        print(json.dumps({"epoch": event["epoch"], "seconds": seconds, "cpu_seconds": cpu,
                          "train_seconds": event["seconds"],
                          "samples": round(event["samples_per_s"] * event["seconds"]),
                          "train_loss": event["train_loss"], "val_loss": event["val_loss"],
                          "best": event["best"]}), flush=True)
        command = sys.stdin.readline().strip()
        if command != "epoch":
            stop.set()
        clock["start"], clock["cpu"] = time.perf_counter(), time.process_time()

    print(json.dumps({"ready": True, "precision": precision}), flush=True)
    sys.stdin.readline()  # the first "epoch"
    clock["start"], clock["cpu"] = time.perf_counter(), time.process_time()
    train(cfg, [tub], model, epochs=1000, register=False, progress=False, on_event=on_event, should_stop=stop.is_set)
    return 0


class Worker:
    """A paused trainer process spoken to in lines of text, answered in JSON lines."""

    def __init__(self, cmd: list[str], env: dict[str, str]) -> None:
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
                                     cwd=ROOT)
        self.info = self._reply()

    def _reply(self) -> dict[str, Any]:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if line.startswith("{"):
                return json.loads(line)
        raise RuntimeError(f"{self.proc.args[:2]} ended (exit {self.proc.wait()})")

    def ask(self, command: str) -> dict[str, Any]:
        assert self.proc.stdin is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()
        return self._reply()

    def close(self, command: str) -> None:
        try:
            assert self.proc.stdin is not None
            self.proc.stdin.write(command + "\n")
            self.proc.stdin.close()
        except BrokenPipeError:
            pass
        self.proc.wait(timeout=600)


def keras_to_model_file(npz: Path, path: Path) -> Path:
    """DonkeyCar's KerasLinear weights as our linear model file (the same layers; its [0, 1] pixels)."""
    import numpy as np
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import preprocess_from_config
    from vehicle.config import Config

    cfg = Config.defaults(ROI_CROP_TOP=CROP_TOP, PREPROCESS_NORMALIZE="unit")
    pre = preprocess_from_config(cfg, "linear", (120, 160, 3))
    model = create_model("linear", pre.output_shape((120, 160, 3)))
    data = np.load(npz)
    w = [data[k] for k in sorted(data.files)]  # conv1..5, dense_1, dense_2, n_outputs0, n_outputs1 (kernel, bias)
    convs = [m for m in model.features if isinstance(m, torch.nn.Conv2d)]
    dense = [m for m in model.head if isinstance(m, torch.nn.Linear)]
    with torch.no_grad():
        for i, conv in enumerate(convs):  # Keras (kh, kw, in, out) -> torch (out, in, kh, kw)
            conv.weight.copy_(torch.from_numpy(w[2 * i].transpose(3, 2, 0, 1)))
            conv.bias.copy_(torch.from_numpy(w[2 * i + 1]))
        fmap = model.features[:-1](torch.zeros(1, *model.input_shape)).shape  # (1, C, H, W) before Flatten
        flat = w[10].shape[0]
        assert flat == fmap[1] * fmap[2] * fmap[3], (flat, fmap)
        # Keras flattens (H, W, C), torch (C, H, W): reorder the first dense layer's input rows
        k = w[10].reshape(fmap[2], fmap[3], fmap[1], -1).transpose(2, 0, 1, 3).reshape(flat, -1)
        dense[0].weight.copy_(torch.from_numpy(k.T))
        dense[0].bias.copy_(torch.from_numpy(w[11]))
        dense[1].weight.copy_(torch.from_numpy(w[12].T))
        dense[1].bias.copy_(torch.from_numpy(w[13]))
        dense[2].weight.copy_(torch.from_numpy(np.concatenate([w[14], w[16]], axis=1).T))
        dense[2].bias.copy_(torch.from_numpy(np.concatenate([w[15], w[17]])))
    save_model(path, model, {"type": "linear", "preprocess": pre.to_dict(), "training": {"trainer": "DonkeyCar 5.3"},
                             "comment": "DonkeyCar 5.3 KerasLinear weights"})
    return path


def heldout_mse(model_path: Path, tub: str) -> float:
    """Mean squared error of (angle, throttle) over the held-out tub's records, through the pilot part."""
    import numpy as np

    from parts.pilots import load_pilot
    from training.dataset import read_drive_data

    pilot = load_pilot(model_path, backend="torch")
    data = read_drive_data([tub])
    err = []
    for r in data.records:
        angle, throttle = pilot.run(r.image("cam/image_array"))
        err.append(((angle - r.angle) ** 2 + (throttle - r.throttle) ** 2) / 2)
    return float(np.mean(err))


def closed_loop(model_path: Path, tracks: list[int], laps: int) -> dict[str, Any]:
    from vehicle.app.demo import DEMO_SETTINGS
    from vehicle.app.evaluate import evaluate
    from vehicle.config import Config

    cfg = Config.defaults(**DEMO_SETTINGS)
    out = {}
    for theme in ("road", "indoor", "park"):
        o = evaluate(model_path, tracks, laps, cfg=cfg.replace(SIM_THEME=theme, SIM_RANDOMIZE=None))["overall"]
        out[theme] = {"autonomy": round(o["autonomy"], 1), "laps": o["laps_completed"],
                      "interventions": o["interventions"]}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tub", help="the tub both train on")
    parser.add_argument("--heldout", help="a tub recorded on other tracks: the common validation")
    parser.add_argument("--rounds", type=int, default=4, help="DonkeyCar epochs (rounds)")
    parser.add_argument("--donkey-python", default=str(ROOT / ".bench" / "donkey-venv" / "bin" / "python"))
    parser.add_argument("--threads", type=int, default=1, help="torch and TensorFlow threads of each trainer")
    parser.add_argument("--emulate-avx2", action="store_true", help="as on a CPU without AVX-512 and bf16")
    parser.add_argument("--out", type=Path, default=Path("/tmp/donkey_train"))
    parser.add_argument("--eval-tracks", type=int, nargs="+", default=[101, 102, 103, 104, 105])
    parser.add_argument("--laps", type=int, default=2, help="laps per evaluation track (0: no closed loop)")
    parser.add_argument("--ours-worker", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.ours_worker:
        tub, out, threads, precision = args.ours_worker
        return ours_worker(tub, out, int(threads), precision)
    if not (args.tub and args.heldout):
        parser.error("--tub and --heldout are required")
    out = args.out.resolve()
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TF_CPP_MIN_LOG_LEVEL": "2",
           "OMP_NUM_THREADS": str(args.threads), "TF_NUM_INTRAOP_THREADS": str(args.threads),
           "TF_NUM_INTEROP_THREADS": "1"}
    if args.emulate_avx2:
        env.update(AVX2_ENV)
    precision = "fp32" if args.emulate_avx2 else "auto"
    load = [os.getloadavg()[0]]
    donkey = Worker([args.donkey_python, str(ROOT / "bench" / "donkey_keras_worker.py"), args.tub, str(CROP_TOP),
                     str(BATCH), str(args.threads)], env)
    ours = Worker([sys.executable, __file__, "--ours-worker", args.tub, str(out), str(args.threads), precision], env)
    d_rows: list[dict[str, Any]] = []
    o_rows: list[dict[str, Any]] = []
    d_time = o_time = 0.0
    for _ in range(args.rounds):
        r = donkey.ask("epoch")
        d_time += r["seconds"]
        d_rows.append({**r, "cumulative": d_time})
        print(f"DonkeyCar epoch {r['epoch']}: {r['seconds']:.1f} s, val_loss {r['val_loss']:.4f} "
              f"(cumulative {d_time:.0f} s)", flush=True)
        while o_time < d_time:
            r = ours.ask("epoch")
            o_time += r["seconds"]
            o_rows.append({**r, "cumulative": o_time})
            print(f"  ours epoch {r['epoch']}: {r['seconds']:.1f} s, val_loss {r['val_loss']:.4f} "
                  f"(cumulative {o_time:.0f} s)", flush=True)
        load.append(os.getloadavg()[0])
    donkey.ask(f"save {out / 'donkey.npz'}")
    donkey.close("quit")
    ours.close("stop")
    budget = d_time
    at_budget = [r for r in o_rows if r["cumulative"] <= budget * 1.02] or o_rows[:1]
    ours_model = out / f"ours_e{at_budget[-1]['epoch']}.pt"
    donkey_model = keras_to_model_file(out / "donkey.npz", out / "donkey.pt")

    def rate(rows: list[dict[str, Any]]) -> float:
        steady = rows[1:] or rows
        return sum(r["samples"] for r in steady) / sum(r["train_seconds"] for r in steady)

    def per_cpu(rows: list[dict[str, Any]]) -> float:
        """Samples per CPU second of the whole process (validation included): on a shared machine
        the wall-clock rates say as much about the scheduler as about the trainer."""
        steady = rows[1:] or rows
        return sum(r["samples"] for r in steady) / sum(r["cpu_seconds"] for r in steady)

    result = {"cpu": _cpu(), "emulate_avx2": args.emulate_avx2, "threads": args.threads, "load": load,
              "budget_s": budget, "donkey": {"epochs": d_rows, "samples_per_s": rate(d_rows),
                                             "samples_per_cpu_s": per_cpu(d_rows),
                                             "heldout_mse": heldout_mse(donkey_model, args.heldout)},
              "ours": {"epochs": o_rows, "samples_per_s": rate(o_rows), "samples_per_cpu_s": per_cpu(o_rows),
                       "epochs_in_budget": len(at_budget),
                       "precision": precision, "heldout_mse": heldout_mse(ours_model, args.heldout)}}
    result["ratio_samples_per_s"] = result["ours"]["samples_per_s"] / result["donkey"]["samples_per_s"]
    result["ratio_samples_per_cpu_s"] = result["ours"]["samples_per_cpu_s"] / result["donkey"]["samples_per_cpu_s"]
    for who, path in (("donkey", donkey_model), ("ours", ours_model)):
        result[who]["closed_loop"] = closed_loop(path, args.eval_tracks, args.laps) if args.laps else {}
    (out / "result.json").write_text(json.dumps(result, indent=1))
    d, o = result["donkey"], result["ours"]
    print(f"\nsamples/s (steady rounds): DonkeyCar {d['samples_per_s']:.0f}, ours {o['samples_per_s']:.0f} "
          f"({o['precision']}): {result['ratio_samples_per_s']:.2f}x; per CPU second (validation included) "
          f"{d['samples_per_cpu_s']:.0f} and {o['samples_per_cpu_s']:.0f}: {result['ratio_samples_per_cpu_s']:.2f}x; "
          f"load average {load[0]:.1f} -> {load[-1]:.1f}")
    for who, r in (("DonkeyCar", d), ("ours", o)):
        loop = r["closed_loop"]
        cl = " / ".join(f"{loop[t]['autonomy']:.0f} % ({loop[t]['laps']} laps)" for t in ("road", "indoor", "park")) \
            if loop else "not driven"
        print(f"{who} after {budget:.0f} s: held-out MSE {r['heldout_mse']:.4f}; road / indoor / park {cl}")
    return 0


def _cpu() -> str:
    from training.acceleration import cpu_caps

    return cpu_caps().name


if __name__ == "__main__":
    raise SystemExit(main())
