"""``vehicle models``: list, show, comment, export and remove the car's trained models.

    vehicle models [list] [--car DIR] [--json]
    vehicle models show NAME [--car DIR]
    vehicle models comment NAME "works on track 3"
    vehicle models rename NAME NEW_NAME
    vehicle models rehash NAME
    vehicle models export NAME|FILE --format onnx|onnx-int8|torchscript [--out FILE]
                          [--int8 static|dynamic] [--calibration TUB ...]
    vehicle models rm NAME [--delete-files]
    vehicle models leaderboard [--tracks 101,102,103] [--laps 2]

The db is ``<car>/<MODELS_PATH>/models.sqlite3`` (training fills it; the trainer console,
``vehicle console``, reads and writes the same file, evaluations included). It keeps each model
file's SHA-256: a registered file whose bytes changed is refused before it drives; ``rehash``
accepts the file as it is now.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path
from typing import Any

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def _out(text: str) -> None:
    print(text)  # noqa: T201 - the command's own output


def _car_options() -> argparse.ArgumentParser:
    # SUPPRESS: `--car` may be given before or after the subcommand without one resetting the other.
    parent = argparse.ArgumentParser(add_help=False)
    add_car_options(parent, suppress=True)
    return parent


def register(subparsers: Any) -> None:
    """Add the ``models`` command and its subcommands."""
    car = _car_options()
    parser = subparsers.add_parser("models", parents=[car], help="list and manage the car's trained models",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                        help="print the list as JSON")
    parser.set_defaults(func=_cmd_list)
    sub = parser.add_subparsers(dest="models_command", metavar="SUBCOMMAND")

    p = sub.add_parser("list", parents=[car], help="list the registered models (the default)")
    p.add_argument("--json", action="store_true", default=argparse.SUPPRESS, help="print as JSON")
    p.set_defaults(func=_cmd_list)

    p = sub.add_parser("show", parents=[car], help="everything the model database knows about one model")
    p.add_argument("name", help="model name (file name without .pt) or path")
    p.set_defaults(func=_cmd_show)

    p = sub.add_parser("comment", parents=[car], help="set the comment of a model ('' clears it)")
    p.add_argument("name")
    p.add_argument("text")
    p.set_defaults(func=_cmd_comment)

    p = sub.add_parser("rename", parents=[car], help="rename a model and its files")
    p.add_argument("name")
    p.add_argument("new_name")
    p.set_defaults(func=_cmd_rename)

    p = sub.add_parser("rehash", parents=[car],
                       help="accept a model file as it is now (it changed since it was registered)")
    p.add_argument("name")
    p.set_defaults(func=_cmd_rehash)

    p = sub.add_parser("leaderboard", parents=[car],
                       help="models ranked by their stored evaluation on the same tracks")
    p.add_argument("--tracks", help="comma-separated track seeds (default SIM_EVAL_TRACK_SEEDS)")
    p.add_argument("--laps", type=int, help="only evaluations of this many laps per track")
    p.set_defaults(func=_cmd_leaderboard)

    p = sub.add_parser("export", parents=[car], help="export a model to ONNX, int8 ONNX or TorchScript")
    p.add_argument("name", help="model name or path of a .pt file")
    p.add_argument("--format", choices=("onnx", "onnx-int8", "torchscript"), default="onnx")
    p.add_argument("--out", metavar="FILE", default=None,
                   help="output file (default: next to the model, .onnx, .int8.onnx or .ts)")
    p.add_argument("--int8", choices=("static", "dynamic"), default="static",
                   help="onnx-int8: static (activation ranges from calibration frames; default) or dynamic")
    p.add_argument("--calibration", nargs="+", metavar="TUB",
                   help="onnx-int8 static: tubs to calibrate on (default: the tubs the model was trained on)")
    p.add_argument("--calibration-frames", type=int, default=None, metavar="N",
                   help="onnx-int8 static: frames to calibrate on (default 300)")
    p.set_defaults(func=_cmd_export)

    p = sub.add_parser("rm", parents=[car], help="remove a model from the model database")
    p.add_argument("name")
    p.add_argument("--delete-files", action="store_true",
                   help="also delete the model file and its exports, loss plot and metrics")
    p.set_defaults(func=_cmd_rm)


def _config(args: argparse.Namespace) -> Any:
    return load_for_command(args)


def _db(args: argparse.Namespace) -> Any:
    from training.model_db import ModelDB

    return ModelDB.for_models_dir(_config(args).path("MODELS_PATH"))


def _short(mapping: dict[str, Any], keys: tuple[str, ...]) -> str:
    parts = []
    for key in keys:
        value = mapping.get(key)
        if isinstance(value, bool) or not isinstance(value, int | float | str):
            continue  # per-epoch lists and the like: `vehicle models show NAME` prints them
        parts.append(f"{key}={value:.4g}" if isinstance(value, float) else f"{key}={value}")
    return " ".join(parts)


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _eval_summary(ev: Any) -> str:
    """The EVALUATION cell: score and the share of the laps driven before autonomy, which alone reads
    100 % for a car that stood still (evaluations stored before the score show autonomy only)."""
    if ev is None:
        return ""
    o = ev.overall
    shown = [f"score {o['score']:.1f}"] if _number(o.get("score")) else []
    if _number(o.get("completion")):
        shown.append(f"driven {100.0 * o['completion']:.0f}%")
    shown.append(f"autonomy {o['autonomy']:.1f}%" if _number(o.get("autonomy")) else "autonomy ?")
    return f"{', '.join(shown)} on {','.join(map(str, ev.tracks))}"


def format_table(entries: list[Any], latest: dict[str, Any] | None = None) -> str:
    """The ``vehicle models`` table: one row per model (``latest``: name -> latest evaluation)."""
    header = ("NAME", "TYPE", "CREATED", "DATASETS", "METRICS", "EVALUATION", "COMMENT")
    rows = [header]
    for e in entries:
        name = e.name if e.exists else f"{e.name} (missing)"
        datasets = ",".join(Path(d).name for d in e.datasets)
        metrics = _short(e.metrics, ("best_val_loss", "val_loss", "best_epoch", "epochs"))
        rows.append((name, e.type, e.created.replace("+00:00", "Z"), datasets, metrics,
                     _eval_summary((latest or {}).get(e.name)), e.comment or ""))
    widths = [max(len(r[i]) for r in rows) for i in range(len(header) - 1)]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r[:-1], widths, strict=True)) + "  " + r[-1]
                     for r in rows).rstrip()


def _cmd_list(args: argparse.Namespace) -> int:
    db = _db(args)
    entries = db.list()
    latest: dict[str, Any] = {}
    for ev in db.evaluations():  # newest first
        latest.setdefault(ev.model, ev)
    if getattr(args, "json", False):
        _out(json.dumps([{**e.as_dict(), "latest_evaluation": latest[e.name].as_dict() if e.name in latest
                          else None} for e in entries], indent=2))
    elif not entries:
        _out(f"no models registered in {db.db_path} (train one: manage.py train)")
    else:
        _out(format_table(entries, latest))
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    db = _db(args)
    entry = db.get(args.name)
    _out(json.dumps({**entry.as_dict(), "evaluations": [ev.as_dict() for ev in db.evaluations(entry.name)]},
                    indent=2))
    return 0


def _cmd_rename(args: argparse.Namespace) -> int:
    entry = _db(args).rename(args.name, args.new_name)
    _out(f"renamed {args.name} to {entry.name} ({entry.path})")
    return 0


def _cmd_rehash(args: argparse.Namespace) -> int:
    entry = _db(args).rehash(args.name)
    _out(f"{entry.name}: the model database now holds the SHA-256 of {entry.path} as it is now")
    return 0


def format_leaderboard(evaluations: list[Any]) -> str:
    """The leaderboard table: rank, model and its overall evaluation figures, the score (what ranks
    them, :func:`parts.sim.metrics.rank_key`) and the share of the laps driven first."""
    rows = [("#", "MODEL", "SCORE", "DRIVEN", "AUTONOMY", "LAPS", "MEAN|CTE|", "SPEED", "OFF-TRACK", "EVALUATED")]
    for i, ev in enumerate(evaluations, 1):
        def f(key: str, fmt: str, o: dict[str, Any] = ev.overall, scale: float = 1.0) -> str:
            v = o.get(key)
            return "-" if not _number(v) else format(v * scale if scale != 1.0 else v, fmt)

        rows.append((str(i), ev.model, f("score", ".1f"), f("completion", ".0f", scale=100.0) + "%",
                     f("autonomy", ".1f") + "%", f("laps_completed", "d"),
                     f("mean_abs_cte", ".3f") + " m", f("mean_speed", ".2f") + " m/s", f("interventions", "d"),
                     ev.created.replace("+00:00", "Z")))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows)


def _cmd_leaderboard(args: argparse.Namespace) -> int:
    cfg = _config(args)
    from training.model_db import ModelDB

    db = ModelDB.for_models_dir(cfg.path("MODELS_PATH"))
    try:
        tracks = [int(t) for t in args.tracks.split(",") if t.strip()] if args.tracks else \
            list(cfg.SIM_EVAL_TRACK_SEEDS)
    except ValueError:
        raise UserError(f"--tracks {args.tracks}: give comma-separated track seeds, e.g. 101,102,103") from None
    board = db.leaderboard(tracks, args.laps)
    if not board:
        sets = db.track_sets()
        hint = ("; evaluated track sets: " + "; ".join(f"--tracks {','.join(map(str, t))} --laps {lp}"
                                                       for t, lp, _n in sets)) if sets else \
            "; evaluate a model first (vehicle console, or vehicle sim eval --pilot MODEL --store)"
        _out(f"no evaluations on tracks {','.join(map(str, tracks))}{hint}")
        return 0
    _out(f"tracks {','.join(map(str, tracks))}" + (f", {args.laps} laps" if args.laps else ""))
    _out(format_leaderboard(board))
    return 0


def _cmd_comment(args: argparse.Namespace) -> int:
    entry = _db(args).set_comment(args.name, args.text)
    _out(f"{entry.name}: comment {'set' if entry.comment else 'cleared'}")
    return 0


def _cmd_rm(args: argparse.Namespace) -> int:
    deleted = _db(args).remove(args.name, delete_files=args.delete_files)
    _out(f"removed {args.name} from the model database" + (f"; deleted {len(deleted)} files" if deleted else ""))
    return 0


def _model_file(args: argparse.Namespace) -> Path:
    path = Path(args.name)
    if path.is_file():
        return path
    from training.model_db import ModelDBError

    try:
        entry = _db(args).get(args.name)
    except ModelDBError as exc:
        raise UserError(f"{args.name}: not a file and {exc}") from exc
    if not entry.exists:
        raise UserError(f"model {entry.name}: its file {entry.path} is missing")
    return entry.path


def _cmd_export(args: argparse.Namespace) -> int:
    from training.export import export_model

    source = _model_file(args)
    try:
        if args.calibration_frames is not None and args.calibration_frames < 1:
            raise UserError(f"--calibration-frames must be >= 1, got {args.calibration_frames}")
        out = export_model(source, args.format, args.out, int8=args.int8, calibration=args.calibration,
                           calibration_frames=args.calibration_frames)
    except (ValueError, FileNotFoundError, ImportError) as exc:
        raise UserError(f"export of {source} failed: {exc}") from exc
    _out(f"wrote {out}")
    return 0
