"""``vehicle demo``: record → train → evaluate on unseen tracks, with nothing but a CPU.

    vehicle demo                      # works in ./demo (regenerated each run)
    vehicle demo --out /tmp/mydemo --records 6000 --epochs 12

1. The simulator's expert drives the training tracks (with noise injection, so the data shows
   recoveries) and its clean commands are recorded in a tub.
2. The default ``linear`` model trains on that tub (the same training code as ``manage.py train``).
3. The model is exported to ONNX when onnx and onnxruntime are installed (the pilot then runs it).
4. The trained pilot and the expert both drive tracks the pilot never saw; the table compares them.

The demo folder is an ordinary car folder: ``vehicle models --car demo`` lists the model,
``vehicle sim eval --pilot demo/models/demo_linear.pt`` evaluates it again.
"""

from __future__ import annotations

import argparse
import logging
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from vehicle.errors import UserError

logger = logging.getLogger(__name__)

#: settings the demo runs with (tuned so the pilot completes its laps within the time budget);
#: each is a normal setting of vehicle/config_defaults.py
DEMO_SETTINGS: dict[str, Any] = {
    "ROI_CROP_TOP": 40,  # the top third of the frame is sky: less to learn and 1/3 less compute
    "BATCH_SIZE": 64,
    # the expert (and so the pilot it teaches) drives at 1.5 m/s instead of 2: at 2 m/s one sharp
    # curve per unseen track was too much for a model trained in 2 minutes
    "SIM_EXPERT_SPEED": 1.5,
    "SHOW_PLOT": True,
}
DEFAULTS = {"records": 6000, "epochs": 10, "noise": 0.4, "train_tracks": [1, 2, 3, 4, 5, 6, 7, 8],
            "eval_tracks": [101, 102, 103, 104, 105], "laps": 2}


def _seeds(text: str) -> list[int]:
    try:
        seeds = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected track seeds like 1,2,3, got {text!r}") from None
    if not seeds:
        raise argparse.ArgumentTypeError("give at least one track seed")
    return seeds


def register(subparsers: Any) -> None:
    """Add the ``demo`` command."""
    p = subparsers.add_parser("demo", help="record, train and evaluate a pilot in the simulator (CPU, minutes)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="demo", metavar="DIR", help="working folder (a car folder; default ./demo)")
    p.add_argument("--records", type=int, default=DEFAULTS["records"], help="expert records to train on")
    p.add_argument("--epochs", type=int, default=DEFAULTS["epochs"], help="most training epochs")
    p.add_argument("--noise", type=float, default=DEFAULTS["noise"],
                   help="steering noise injected while the expert drives (0 = off)")
    p.add_argument("--train-tracks", type=_seeds, default=DEFAULTS["train_tracks"], metavar="SEEDS",
                   help="track seeds to record on, e.g. 1,2,3,4,5,6,7,8")
    p.add_argument("--eval-tracks", type=_seeds, default=DEFAULTS["eval_tracks"], metavar="SEEDS",
                   help="track seeds to evaluate on (never trained on)")
    p.add_argument("--laps", type=int, default=DEFAULTS["laps"], help="laps per evaluation track")
    p.add_argument("--type", dest="model_type", default="linear", help="model type to train")
    p.add_argument("--threads", type=int, default=None, help="torch threads (default: all cores)")
    p.set_defaults(func=_cmd_demo)


def _say(text: str) -> None:
    print(text, flush=True)  # noqa: T201 - the command's own output


def run_demo(out: Path, *, records: int, epochs: int, noise: float, train_tracks: list[int],
             eval_tracks: list[int], laps: int, model_type: str = "linear") -> dict[str, Any]:
    """Run the four steps in ``out``; returns ``{"pilot": report, "expert": report, "model": path,
    "seconds": {step: s}}``. Raises ValueError on bad arguments."""
    from parts.sim.evaluate import evaluate
    from parts.sim.record import record_expert
    from parts.sim.report import format_table, write_json
    from vehicle.config import Config

    if set(train_tracks) & set(eval_tracks):
        raise ValueError(f"evaluation tracks {sorted(set(train_tracks) & set(eval_tracks))} are also training "
                         "tracks: evaluate on tracks the pilot never saw")
    if records < 100 or epochs < 1 or laps < 1:
        raise ValueError(f"need records >= 100, epochs >= 1 and laps >= 1 (got {records}, {epochs}, {laps})")
    out = out.resolve()
    cfg = Config.defaults(CAR_PATH=str(out), **DEMO_SETTINGS)
    _write_myconfig(out)
    tub = out / "data" / "demo_tub"
    if tub.exists():
        shutil.rmtree(tub)  # the demo records afresh each run; it never touches other folders
    model_path = out / "models" / f"demo_{model_type}.pt"
    seconds: dict[str, float] = {}

    t = time.perf_counter()
    _say(f"[1/4] the expert drives training tracks {train_tracks}: recording {records} records "
         f"(steering noise {noise}) ...")
    record_expert(cfg, train_tracks, records, tub, noise=noise)
    seconds["record"] = time.perf_counter() - t

    t = time.perf_counter()
    _say(f"[2/4] training a {model_type} model for up to {epochs} epochs ...")
    from parts.pilots.train import train

    metrics = train(cfg, [tub], model_path, model_type_name=model_type, epochs=epochs,
                    comment="vehicle demo")
    seconds["train"] = time.perf_counter() - t
    _say(f"      best val_loss {metrics['best_val_loss']:.5f} at epoch {metrics['best_epoch']} of "
         f"{metrics['epochs']} ({seconds['train']:.0f} s)")

    t = time.perf_counter()
    from parts.pilots.runners import onnxruntime_available

    try:
        import onnx  # noqa: F401
        have_onnx = onnxruntime_available()
    except ImportError:
        have_onnx = False
    if have_onnx:
        from parts.pilots.export import export_model

        _say(f"[3/4] exporting to ONNX: {export_model(model_path, 'onnx')}")
    else:
        _say("[3/4] onnx/onnxruntime not installed: the pilot runs in PyTorch")
    seconds["export"] = time.perf_counter() - t

    t = time.perf_counter()
    _say(f"[4/4] driving {laps} laps on each of the unseen tracks {eval_tracks} ...")
    pilot_report = evaluate(model_path, eval_tracks, laps, cfg=cfg)
    expert_report = evaluate("expert", eval_tracks, laps, cfg=cfg)
    seconds["evaluate"] = time.perf_counter() - t
    write_json(pilot_report, out / "eval" / "pilot.json")
    write_json(expert_report, out / "eval" / "expert.json")
    _say("\ntrained pilot on unseen tracks:")
    _say(format_table(pilot_report))
    _say("\nthe expert on the same tracks, for comparison:")
    _say(format_table(expert_report))
    return {"pilot": pilot_report, "expert": expert_report, "model": model_path, "seconds": seconds,
            "metrics": metrics}


def _write_myconfig(out: Path) -> None:
    """Make ``out`` a car folder with the demo's settings (kept if it already has a myconfig.py),
    so ``vehicle models --car``, ``vehicle sim eval`` and ``manage.py`` there use them too."""
    path = out / "myconfig.py"
    if path.exists():
        return
    out.mkdir(parents=True, exist_ok=True)
    lines = ['"""Settings of the `vehicle demo` car (written by the demo)."""', ""]
    lines += [f"{name} = {value!r}" for name, value in DEMO_SETTINGS.items()]
    path.write_text("\n".join(lines) + "\n")


def _cmd_demo(args: argparse.Namespace) -> int:
    import torch

    if args.threads is not None:
        if args.threads < 1:
            raise UserError(f"--threads must be >= 1, got {args.threads}")
        torch.set_num_threads(args.threads)
    started = time.perf_counter()
    try:
        result = run_demo(Path(args.out), records=args.records, epochs=args.epochs, noise=args.noise,
                          train_tracks=args.train_tracks, eval_tracks=args.eval_tracks, laps=args.laps,
                          model_type=args.model_type)
    except ValueError as exc:
        raise UserError(f"demo: {exc}") from exc
    total = time.perf_counter() - started
    overall = result["pilot"]["overall"]
    laps_needed = args.laps * len(args.eval_tracks)
    steps = ", ".join(f"{k} {v:.0f} s" for k, v in result["seconds"].items())
    _say(f"\ndemo finished in {total:.0f} s ({steps}); torch threads: {torch.get_num_threads()}")
    # a lap only counts as driven by the pilot when nobody had to put the car back on the road
    done = overall["laps_completed"] >= laps_needed and overall["interventions"] == 0
    verdict = "completed" if done else "did NOT complete"
    _say(f"the trained pilot {verdict} its {laps_needed} laps on unseen tracks on its own "
         f"({overall['laps_completed']} laps, {overall['interventions']} interventions, "
         f"autonomy {overall['autonomy']:.1f} %)")
    out = Path(args.out)
    _say(f"next: vehicle models --car {out}  |  vehicle sim eval --pilot {result['model']}  |  "
         f"reports in {out / 'eval'}")
    sys.stdout.flush()
    return 0
