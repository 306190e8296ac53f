"""``vehicle sim ...``: draw tracks, evaluate pilots, record expert demonstrations."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def register(subparsers: Any) -> None:
    """Add the ``sim`` command and its subcommands."""
    sim = subparsers.add_parser("sim", help="built-in simulator: tracks, evaluation, expert recording",
                                description=__doc__)
    sub = sim.add_subparsers(dest="sim_command", metavar="SUBCOMMAND", required=True)
    fmt = argparse.ArgumentDefaultsHelpFormatter

    track = sub.add_parser("track", help="draw a generated track (top view) as PNG", formatter_class=fmt)
    track.add_argument("--seed", type=int, required=True, help="track seed")
    track.add_argument("--png", required=True, help="output PNG file")
    track.add_argument("--camera", metavar="PNG", help="also write the camera's view from the start line")
    track.add_argument("--size", type=int, default=800, help="image size in pixels")
    add_car_options(track)
    track.set_defaults(func=cmd_track)

    ev = sub.add_parser("eval", help="closed-loop evaluation of a pilot on simulated tracks", formatter_class=fmt)
    ev.add_argument("--pilot", required=True, help="'expert' or a trained model file")
    ev.add_argument("--tracks", type=_seeds, help="comma-separated track seeds (default SIM_EVAL_TRACK_SEEDS)")
    ev.add_argument("--laps", type=int, help="laps per track (default SIM_EVAL_LAPS)")
    ev.add_argument("--max-time", type=float, help="simulated seconds per track at most")
    ev.add_argument("--throttle", type=float, help="fixed throttle: use only the pilot's steering")
    ev.add_argument("--workers", type=int, metavar="N",
                    help="tracks evaluated in parallel processes (default SIM_EVAL_WORKERS: 0 = one per core)")
    ev.add_argument("--json", help="write the full report (metrics and trajectories) here")
    ev.add_argument("--png", help="write the driven trajectories over the track maps here")
    add_car_options(ev)
    ev.set_defaults(func=cmd_eval)

    rec = sub.add_parser("record", help="record expert demonstrations into a tub", formatter_class=fmt)
    rec.add_argument("--records", type=int, required=True, help="number of records")
    rec.add_argument("--tracks", type=_seeds, help="comma-separated track seeds (default SIM_TRACK_SEEDS)")
    rec.add_argument("--tub", help="tub folder (default: a new tub in the car's data folder)")
    rec.add_argument("--noise", type=float, help="steering noise injection amplitude (default SIM_EXPERT_NOISE)")
    add_car_options(rec)
    rec.set_defaults(func=cmd_record)


def _seeds(text: str) -> list[int]:
    try:
        seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"track seeds must be comma-separated integers, e.g. 11,12 (got {text!r})") from None
    if not seeds:
        raise argparse.ArgumentTypeError("give at least one track seed, e.g. --tracks 11,12")
    return seeds


def cmd_track(args: argparse.Namespace) -> int:
    """Draw one track (and optionally the camera view from its start)."""
    import cv2

    from parts.sim.eval_report import track_image, write_panels
    from parts.sim.track import TrackError

    cfg = load_for_command(args)
    if args.size < 64:
        raise UserError(f"--size {args.size} is too small: use at least 64 pixels")
    try:
        img = track_image(args.seed, cfg, args.size)
    except TrackError as exc:
        raise UserError(str(exc)) from exc
    out = write_panels([img], args.png)
    print(f"track {args.seed}: wrote {out}")  # noqa: T201 - CLI output
    if args.camera:
        from parts.sim.simulator import SimCar

        frame = SimCar.from_config(cfg, seeds=[args.seed]).render()
        path = Path(args.camera)
        path.parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(path), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)):
            raise UserError(f"could not write {path}: use a .png file name in a writable folder")
        print(f"camera view: wrote {path}")  # noqa: T201
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    """Evaluate a pilot and print the table; write JSON / PNG on request."""
    from parts.sim.eval_report import format_table, write_json, write_png
    from vehicle.app.evaluate import evaluate

    cfg = load_for_command(args)
    seeds = args.tracks or list(cfg.SIM_EVAL_TRACK_SEEDS)
    laps = args.laps if args.laps is not None else cfg.SIM_EVAL_LAPS
    if laps < 1:
        raise UserError(f"--laps {laps}: give at least 1 lap")
    workers = args.workers if args.workers is not None else cfg.SIM_EVAL_WORKERS
    if workers < 0:
        raise UserError(f"--workers {workers}: give 1 or more processes, or 0 for one per core")
    if args.pilot != "expert" and not Path(args.pilot).exists():
        raise UserError(f"--pilot {args.pilot}: no such model file; pass 'expert' or a trained model "
                        "(e.g. models/mypilot.pt)")
    try:
        report = evaluate(args.pilot, seeds, laps, cfg=cfg, max_time=args.max_time,
                          fixed_throttle=args.throttle, workers=workers)
    except (ValueError, FileNotFoundError) as exc:
        raise UserError(str(exc)) from exc
    print(format_table(report))  # noqa: T201 - CLI output
    if args.json:
        print(f"wrote {write_json(report, args.json)}")  # noqa: T201
    if args.png:
        print(f"wrote {write_png(report, args.png, cfg)}")  # noqa: T201
    return 0


def cmd_record(args: argparse.Namespace) -> int:
    """Record expert demonstrations."""
    from vehicle.app.record import record_expert

    cfg = load_for_command(args)
    if args.records < 1:
        raise UserError(f"--records {args.records}: give at least 1 record")
    try:
        path = record_expert(cfg, args.tracks, args.records, args.tub, noise=args.noise)
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    print(f"recorded {args.records} records into {path}")  # noqa: T201
    return 0
