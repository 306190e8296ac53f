"""Behaviour cloning against RL with throttle control and BC + RL fine-tuning, end to end.

Runs, in a car folder (created if missing, with the 64x128 crop of docs/rl.md), each stage only
when its output is missing (so a run can go on, or reuse pilots trained by hand):

1. ``vehicle sim record``: expert demonstrations on the training tracks (the expert drives ~2 m/s);
2. ``vehicle train --type linear``: the behaviour-cloned pilot (BC);
3. ``vehicle rl train --throttle-range``: PPO from pixels with throttle control, from scratch;
4. ``vehicle rl train --init BC``: PPO fine-tuning of the BC pilot, throttle control on, with the
   stabilisers of docs/rl.md (value-function warm-up, small learning rate and std, KL stop, clip);

then drives each pilot closed loop in the Vehicle loop on the held-out tracks
(:func:`vehicle.app.evaluate.evaluate`) and prints the table (autonomy, laps, mean lap time, speed,
|CTE|, lap time against BC's), writes it as JSON, and plots both RL learning curves to one PNG.

An RL stage gets ``--minutes`` of wall time and is then stopped with SIGTERM, which (as Ctrl-C) keeps
its best pilot (``vehicle rl train`` exits 143); ``--steps`` caps it otherwise.

Usage: python bench/rl_finetune.py [--car .bench/rlcar] [--minutes 25] [--steps 60000]
       [--tracks 1,2,3,4,5,6] [--eval-tracks 101,102,103,104,105] [--laps 2] [--stages all]
       [--json out.json] [--plot docs/img/rl_finetune.png]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
ENV = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
       "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy"}
CLI = [sys.executable, "-m", "vehicle.app.cli"]
MYCONFIG = "ROI_CROP_TOP = 40\nPREPROCESS_RESIZE = (64, 128)\nSIM_REALTIME = False\n"

#: PPO with throttle control from scratch: the throttle action spans 0.2..0.6 (~0.7-2.5 m/s), so
#: early exploration neither stops nor flies off the road; the speed reward pays for speed
SCRATCH = ["--throttle-range", "0.2,0.6", "--reward", "speed", "--n-steps", "128", "--epochs", "3",
           "--eval-every", "4000"]
#: fine-tuning the cloned pilot (it drives ~0.475 throttle, ~2 m/s): a range that reaches higher,
#: the speed reward, and what keeps the cloned behaviour while the critic is still wrong
FINETUNE = ["--throttle-range", "0.3,0.9", "--reward", "speed", "--n-steps", "128", "--epochs", "3",
            "--lr", "5e-5", "--clip-range", "0.1", "--target-kl", "0.02", "--log-std-init", "-1.6",
            "--vf-warmup", "2048", "--eval-every", "2000"]


#: per-track figures kept in the JSON
PER_TRACK = ("autonomy", "interventions", "mean_lap_s", "mean_speed")


def run(cmd: list[str], log: Path, minutes: float | None = None) -> int:
    """Run a CLI command with its output in ``log``; after ``minutes`` stop it with SIGINT."""
    print("$", " ".join(cmd[2:]), flush=True)  # noqa: T201
    with log.open("w") as out:
        p = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=ENV, cwd=ROOT)
        try:
            p.wait(timeout=None if minutes is None else minutes * 60)
        except subprocess.TimeoutExpired:
            # SIGTERM, not SIGINT: a shell starts background jobs ignoring SIGINT, and rl train stops
            # on SIGTERM as on Ctrl-C (the best pilot and the state kept)
            p.send_signal(signal.SIGTERM)
            p.wait()
    return p.returncode


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--car", default=str(ROOT / ".bench" / "rlcar"))
    ap.add_argument("--records", type=int, default=6000)
    ap.add_argument("--bc-epochs", type=int, default=8)
    ap.add_argument("--minutes", type=float, default=25.0, help="wall time per RL stage")
    ap.add_argument("--steps", type=int, default=60_000, help="environment steps per RL stage at most")
    ap.add_argument("--tracks", default="1,2,3,4,5,6")
    ap.add_argument("--eval-tracks", default="101,102,103,104,105")
    ap.add_argument("--laps", type=int, default=2, help="laps per held-out track in the final comparison")
    ap.add_argument("--stages", default="all", help="comma-separated: record,bc,scratch,finetune,eval (or all)")
    ap.add_argument("--json", default=None, help="write the table here (default <car>/rl_finetune.json)")
    ap.add_argument("--plot", default=None, help="learning curves PNG (default <car>/rl_finetune.png)")
    args = ap.parse_args()
    stages = {"record", "bc", "scratch", "finetune", "eval"} if args.stages == "all" else set(args.stages.split(","))

    car = Path(args.car).resolve()
    (car / "models").mkdir(parents=True, exist_ok=True)
    (car / "logs").mkdir(exist_ok=True)
    if not (car / "myconfig.py").is_file():
        (car / "myconfig.py").write_text(MYCONFIG)
    tub, models, logs = car / "data" / "tub_expert", car / "models", car / "logs"
    pilots = {"BC (behaviour cloning)": models / "bc.pt", "PPO, throttle, from scratch": models / "ppo_throttle.pt",
              "BC + PPO fine-tuning": models / "bc_ppo.pt"}
    common = ["--car", str(car), "--envs", "2", "--tracks", args.tracks, "--eval-tracks", args.eval_tracks,
              "--steps", str(args.steps), "--no-progress"]
    if "record" in stages and not tub.is_dir():
        run([*CLI, "sim", "record", "--car", str(car), "--records", str(args.records), "--tracks", args.tracks,
             "--tub", str(tub)], logs / "record.log")
    if "bc" in stages and not pilots["BC (behaviour cloning)"].is_file():
        run([*CLI, "train", "--car", str(car), "--tubs", str(tub), "--model", str(models / "bc.pt"),
             "--type", "linear", "--epochs", str(args.bc_epochs), "--no-register"], logs / "bc_train.log")
    if "scratch" in stages and not pilots["PPO, throttle, from scratch"].is_file():
        run([*CLI, "rl", "train", *common, "--model", str(models / "ppo_throttle.pt"), *SCRATCH],
            logs / "ppo_throttle.log", args.minutes)
    if "finetune" in stages and not pilots["BC + PPO fine-tuning"].is_file():
        run([*CLI, "rl", "train", *common, "--model", str(models / "bc_ppo.pt"), "--init", str(models / "bc.pt"),
             *FINETUNE], logs / "bc_ppo.log", args.minutes)
    if "eval" not in stages:
        return
    table = evaluate_all(car, pilots, [int(v) for v in args.eval_tracks.split(",")], args.laps)
    print_table(table, args.eval_tracks, args.laps)
    out = Path(args.json) if args.json else car / "rl_finetune.json"
    out.write_text(json.dumps({"eval_tracks": args.eval_tracks, "laps": args.laps, "rows": table}, indent=1))
    plot_curves({name: path for name, path in pilots.items() if "PPO" in name}, Path(args.plot) if args.plot
                else car / "rl_finetune.png")


def evaluate_all(car: Path, pilots: dict[str, Path], tracks: list[int], laps: int) -> list[dict]:
    import torch

    from parts.pilots.modelfile import read_meta
    from vehicle.app.evaluate import evaluate
    from vehicle.config import load_config

    # one frame per step: on a busy machine a thread pool waits for every thread at every operation
    # (a 2-thread forward pass measured 25x slower than 1 thread at load ~25; docs/benchmarks.md#rl)
    torch.set_num_threads(1)
    cfg = load_config(str(car / "myconfig.py"))
    rows = []
    for name, path in pilots.items():
        if not path.is_file():
            continue
        t0 = time.perf_counter()
        report = evaluate(str(path), tracks, laps, cfg=cfg, workers=2)  # a process per core, 1 thread each
        o = report["overall"]
        m = read_meta(path).get("metrics", {})
        rows.append({"pilot": name, "file": path.name, "autonomy": o["autonomy"], "laps": o["laps_completed"],
                     "mean_lap_s": o["mean_lap_s"], "mean_speed": o["mean_speed"], "mean_abs_cte": o["mean_abs_cte"],
                     "interventions": o["interventions"], "rl_steps": m.get("rl_timesteps"),
                     "eval_s": round(time.perf_counter() - t0, 1),
                     "tracks": {t["seed"]: {k: t.get(k) for k in PER_TRACK} for t in report["tracks"]}})
    bc = next((r["mean_lap_s"] for r in rows if r["pilot"].startswith("BC (")), None)
    for r in rows:
        r["lap_vs_bc"] = None if not (bc and r["mean_lap_s"]) else round(100.0 * (bc / r["mean_lap_s"] - 1.0), 1)
    return rows


def print_table(rows: list[dict], tracks: str, laps: int) -> None:
    print(f"\nheld-out tracks {tracks}, {laps} lap(s) each, Vehicle loop:")  # noqa: T201
    print(f"{'pilot':<30} {'RL steps':>8} {'autonomy':>9} {'laps':>5} {'lap s':>7} {'m/s':>5} "  # noqa: T201
          f"{'|cte| m':>8} {'faster than BC':>15}")
    for r in rows:
        faster = "-" if r["lap_vs_bc"] is None else f"{r['lap_vs_bc']:+.1f} %"
        lap = "-" if r["mean_lap_s"] is None else f"{r['mean_lap_s']:.2f}"
        speed = "-" if r["mean_speed"] is None else f"{r['mean_speed']:.2f}"
        print(f"{r['pilot']:<30} {r['rl_steps'] or '-':>8} {r['autonomy']:>8.1f}% {r['laps']:>5} {lap:>7} "  # noqa: T201
              f"{speed:>5} {r['mean_abs_cte']:>8.3f} {faster:>15}")


def plot_curves(runs: dict[str, Path], path: Path) -> None:
    """Training reward and held-out autonomy / lap time of each RL run, against environment steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(13, 3.8))
    for (name, pilot), colour in zip(runs.items(), ("tab:blue", "tab:red"), strict=False):
        curve_file = pilot.with_name(pilot.stem + ".rl.json")
        if not curve_file.is_file():
            continue
        curve = json.loads(curve_file.read_text())
        ro = [r for r in curve["rollouts"] if r["mean_reward"] is not None]
        ax1.plot([r["timesteps"] for r in ro], [r["mean_reward"] for r in ro], color=colour, label=name)
        ev = curve["evaluations"]
        ax2.plot([r["timesteps"] for r in ev], [r["autonomy"] for r in ev], "o-", color=colour, label=name)
        lap = [r for r in ev if r["mean_lap_s"]]
        ax3.plot([r["timesteps"] for r in lap], [r["mean_lap_s"] for r in lap], "o-", color=colour, label=name)
    ax1.set_title("mean episode reward (training)")
    ax2.set_title("autonomy on held-out tracks, %")
    ax2.set_ylim(0, 105)
    ax3.set_title("mean lap on held-out tracks, s")
    for ax in (ax1, ax2, ax3):
        ax.set_xlabel("environment steps")
    ax1.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    main()
