"""``vehicle demo``: record → train → evaluate on unseen tracks on a CPU (see :mod:`vehicle.app.demo`)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from vehicle.app.demo import DEFAULTS, RECIPES
from vehicle.app.demo_lanes import DEFAULTS as LANE_DEFAULTS
from vehicle.errors import UserError


def _seeds(text: str) -> list[int]:
    try:
        seeds = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected track seeds like 1,2,3, got {text!r}") from None
    if not seeds:
        raise argparse.ArgumentTypeError("give at least one track seed")
    return seeds


def _seed_or_off(text: str) -> int | None:
    if text.strip().lower() in ("off", "none"):
        return None
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer seed or 'off', got {text!r}") from None


def _span(seeds: list[int]) -> str:
    """``1-64`` for a run of consecutive seeds, else ``1,5,9``."""
    if seeds == list(range(seeds[0], seeds[0] + len(seeds))) and len(seeds) > 2:
        return f"{seeds[0]}-{seeds[-1]}"
    return ",".join(map(str, seeds))


def register(subparsers: Any) -> None:
    """Add the ``demo`` command."""
    p = subparsers.add_parser("demo", help="record, train and evaluate a pilot in the simulator (CPU, minutes)",
                              description=_demo_doc(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="demo", metavar="DIR", help="working folder (a car folder; default ./demo)")
    # None = the chosen demo's own default (the plain and the --lanes demo differ)
    p.add_argument("--records", type=int, help=f"expert records to train on (default {DEFAULTS['records']}, "
                                                f"--lanes {LANE_DEFAULTS['records']})")
    p.add_argument("--epochs", type=int, help=f"most training epochs (default {DEFAULTS['epochs']})")
    p.add_argument("--noise", type=float,
                   help=f"steering noise injected while the expert drives (0 = off; default {DEFAULTS['noise']})")
    p.add_argument("--train-tracks", type=_seeds, metavar="SEEDS",
                   help=f"track seeds to record on, e.g. 1,2,3 (default {_span(DEFAULTS['train_tracks'])}, "
                        f"--lanes {_span(LANE_DEFAULTS['train_tracks'])})")
    p.add_argument("--eval-tracks", type=_seeds, metavar="SEEDS",
                   help=f"track seeds to evaluate on, never trained on (default {_span(DEFAULTS['eval_tracks'])})")
    p.add_argument("--laps", type=int, help=f"laps per evaluation track (default {DEFAULTS['laps']})")
    p.add_argument("--eval-randomize", type=_seed_or_off, default=DEFAULTS["eval_randomize"], metavar="SEED|off",
                   help="evaluate under this randomisation draw (the training draw is 1); default off: each "
                        "theme's plain look")
    p.add_argument("--unseen-theme", default=DEFAULTS["unseen_theme"], metavar="THEME",
                   help="a theme the pilot is not trained on, evaluated as well")
    p.add_argument("--draws", type=int, default=0, metavar="N",
                   help="also drive under N hidden randomisation draws per theme and report the mean and the worst "
                        "draw (vehicle sim eval --draws; costs about N times the evaluation step); with --lanes "
                        "in the trained theme, with lane changes, failed ones in failure galleries")
    p.add_argument("--type", dest="model_type", default="linear", help="model type to train")
    p.add_argument("--recipe", choices=sorted(RECIPES), default="plain",
                   help="what the demo records and trains: " + "; ".join(f"{k}: {r.what}" for k, r in RECIPES.items())
                   + " (docs/pilot.md)")
    p.add_argument("--robust", dest="recipe", action="store_const", const="robust",
                   help="the same as --recipe robust: steadier under light, colours and themes never seen, about "
                        "three times the recording and training time")
    p.add_argument("--seed", type=int, default=1, metavar="N",
                   help="recording and training seed: the training recordings' randomisation draws, their effects "
                        "and steering-noise seed (--lanes: also its lane changes), and TRAIN_SEED (1: the demo "
                        "as it always ran; vehicle sim robustness trains several)")
    p.add_argument("--precision", choices=["auto", "fp32", "bf16"], default="auto",
                   help="training precision (TRAIN_PRECISION; auto: bf16 on a CPU with native bf16, else fp32)")
    p.add_argument("--threads", type=int, default=None,
                   help="torch threads (default: one per core, or 1 when the machine is already busy)")
    p.add_argument("--lanes", action="store_true",
                   help="the thesis's lane change on demand: record with lane changes on two-lane tracks, train the "
                        "two-stream lanes model and the single-stream behavior model, evaluate both with commanded "
                        "lane changes (default folder ./demo_lanes)")
    p.add_argument("--lane-changes", type=int, default=LANE_DEFAULTS["lane_changes"], metavar="N",
                   help="--lanes: lane changes commanded while recording")
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args: argparse.Namespace) -> int:
    import torch

    from training.acceleration import cpu_caps
    from vehicle.app.demo import expected_time, run_demo, torch_threads, write_summary
    from vehicle.app.demo import say as _say
    from vehicle.app.demo_estimate import demo_expectation

    if args.threads is not None and args.threads < 1:
        raise UserError(f"--threads must be >= 1, got {args.threads}")
    threads, why = torch_threads(args.threads)
    torch.set_num_threads(threads)
    _say(f"torch threads: {threads} ({why})")
    for name, value in (LANE_DEFAULTS if args.lanes else DEFAULTS).items():
        if getattr(args, name, "") is None:
            setattr(args, name, value)
    if args.draws < 0:
        raise UserError(f"--draws {args.draws}: give 0 (off) or more hidden randomisation draws")
    check_precision(args.precision)
    if args.lanes:
        if args.recipe != "plain":
            raise UserError("--recipe chooses the plain demo's recipe: leave it out with --lanes")
        caps = cpu_caps()
        _say(expected_time("lanes", caps.native_bf16, caps.name))
        return _cmd_lanes(args)
    # the plain demo measures this host (about 2 s) instead of looking its CPU kind up
    recorded = args.records * (1 + len(RECIPES[args.recipe].recordings))  # --recipe robust records again
    _say(demo_expectation(recorded, args.epochs, len(args.eval_tracks), args.laps, threads,
                          precision=args.precision, recipe=args.recipe))
    started = time.perf_counter()
    summary_path = Path(args.out) / "eval" / "result.json"
    summary_path.unlink(missing_ok=True)  # exists only once this run has finished
    try:
        result = run_demo(Path(args.out), records=args.records, epochs=args.epochs, noise=args.noise,
                          train_tracks=args.train_tracks, eval_tracks=args.eval_tracks, laps=args.laps,
                          model_type=args.model_type, eval_randomize=args.eval_randomize,
                          unseen_theme=args.unseen_theme, recipe=args.recipe, draws=args.draws, seed=args.seed,
                          precision=args.precision)
    except ValueError as exc:
        raise UserError(f"demo: {exc}") from exc
    total = time.perf_counter() - started
    laps_needed = args.laps * len(args.eval_tracks)
    steps = ", ".join(f"{k} {v:.0f} s" for k, v in result["seconds"].items())
    cpu = sum(result["cpu_seconds"].values())
    _say(f"\ndemo finished in {total:.0f} s ({steps}; CPU time {cpu:.0f} s); torch threads: "
         f"{torch.get_num_threads()}")
    for theme, pair in result["reports"].items():
        overall = pair["pilot"]["overall"]
        # a lap only counts as driven by the pilot when nobody had to put the car back on the road
        done = overall["laps_completed"] >= laps_needed and overall["interventions"] == 0
        verdict = "completed" if done else "did NOT complete"
        kind = "trained theme" if theme in result["trained_themes"] else "theme never seen in training"
        _say(f"{theme} ({kind}): the trained pilot {verdict} its {laps_needed} laps on unseen tracks on its own "
             f"({overall['laps_completed']} laps, {overall['interventions']} interventions, "
             f"autonomy {overall['autonomy']:.1f} %)")
    for theme, s in result.get("draws", {}).get("by_theme", {}).items():
        _say(f"{theme} under {len(s['draws'])} hidden draws: autonomy mean {s['mean']['autonomy']:.1f} %, worst "
             f"{s['worst']['autonomy']:.1f} % (draw {s['worst']['randomize']}), speed "
             f"{s['speed_vs_expert_pct'] if s.get('speed_vs_expert_pct') is not None else '-'} % of the expert's")
    out = Path(args.out)
    write_summary(result, summary_path, total)
    _say(f"next: vehicle models --car {out}  |  vehicle sim eval --pilot {result['model']} --theme "
         f"{args.unseen_theme} --randomize {'off' if args.eval_randomize is None else args.eval_randomize}  |  "
         f"reports in {out / 'eval'}")
    sys.stdout.flush()
    return 0


def check_precision(precision: str, option: str = "--precision") -> None:
    """UserError for bf16 forced on a CPU without native bf16 (emulated: slower than fp32, and not
    the arithmetic a measurement of the bf16 path means)."""
    if precision != "bf16":
        return
    from training.acceleration import cpu_caps

    caps = cpu_caps()
    if not caps.native_bf16:
        raise UserError(f"{option} bf16: this CPU ({caps.name}) has no native bf16 (AVX512-BF16 or AMX); "
                        "use fp32 or auto")


def _cmd_lanes(args: argparse.Namespace) -> int:
    import torch

    from vehicle.app.demo import say
    from vehicle.app.demo_lanes import run_lanes_demo, thesis_claim_met
    from vehicle.app.lanes_robustness import write_lanes_summary

    out = Path("demo_lanes" if args.out == "demo" else args.out)
    started = time.perf_counter()
    summary_path = out / "eval" / "result.json"
    summary_path.unlink(missing_ok=True)  # exists only once this run has finished
    try:
        result = run_lanes_demo(out, records=args.records, lane_changes=args.lane_changes, epochs=args.epochs,
                                noise=args.noise, train_tracks=args.train_tracks, eval_tracks=args.eval_tracks,
                                laps=args.laps, seed=args.seed, precision=args.precision, draws=args.draws)
    except ValueError as exc:
        raise UserError(f"demo --lanes: {exc}") from exc
    total = time.perf_counter() - started
    write_lanes_summary(result, summary_path, total)
    steps = ", ".join(f"{k} {v:.0f} s" for k, v in result["seconds"].items())
    say(f"\ndemo finished in {total:.0f} s ({steps}); torch threads: {torch.get_num_threads()}")
    for name, report in result["reports"].items():
        lanes = report["overall"]["lanes"]
        verdict = "meets" if thesis_claim_met(report) else "does NOT meet"
        say(f"{name} {verdict} the thesis's claim: {lanes['lane_changes_ok']} of {lanes['lane_changes']} commanded "
            f"lane changes done, {report['overall']['interventions']} times off the road")
    say(f"next: vehicle sim eval --car {out} --pilot {out / 'models' / 'demo_lanes.pt'}  |  "
        f"reports and trajectory maps in {out / 'eval'}")
    sys.stdout.flush()
    return 0


def _demo_doc() -> str:
    import vehicle.app.demo
    import vehicle.app.demo_lanes

    return (vehicle.app.demo.__doc__ or "") + "\n" + (vehicle.app.demo_lanes.__doc__ or "")
