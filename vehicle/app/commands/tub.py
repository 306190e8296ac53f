"""``vehicle tub ...``: inspect, clean, check/repair, plot, film, import and export tubs (docs/tub.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from vehicle.errors import UserError


def _out(text: str) -> None:
    """The command's own output (results), on stdout."""
    print(text)  # noqa: T201 - CLI output


def _tty() -> bool:
    return sys.stderr.isatty()


def register(subparsers: Any) -> None:
    """Add the ``tub`` command and its subcommands."""
    tub = subparsers.add_parser("tub", help="inspect, clean, check, plot, import and export tubs",
                                description=__doc__)
    sub = tub.add_subparsers(dest="tub_command", metavar="SUBCOMMAND", required=True)

    p = sub.add_parser("info", help="records, sessions, time span, fields, size, deleted count")
    p.add_argument("tubs", nargs="+", help="tub folders or folders of tubs")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("ls", help="list records")
    p.add_argument("tub")
    p.add_argument("--range", default=None, help="indexes to list, e.g. 0:50 (default: all)")
    p.add_argument("--deleted", action="store_true", help="include deleted records (marked D)")
    p.add_argument("--fields", default=None,
                   help="comma-separated fields (default: every non-image field)")
    p.set_defaults(func=cmd_ls)

    for name, verb in (("delete", "soft-delete"), ("restore", "restore deleted")):
        p = sub.add_parser(name, help=f"{verb} records by index ranges")
        p.add_argument("tub")
        p.add_argument("ranges", help="e.g. 3,10:20,95: (A:B means A..B-1, as in Python)")
        p.set_defaults(func=cmd_delete if name == "delete" else cmd_restore)

    for name, repair in (("check", False), ("repair", True)):
        p = sub.add_parser(name, help="fix what check finds (same as check --repair)" if repair else
                           "report problems (every image is decoded); --repair fixes them")
        p.add_argument("tubs", nargs="+")
        if not repair:
            p.add_argument("--repair", action="store_true",
                           help="rewrite the manifest and catalog manifests, cut torn lines, drop empty "
                                "trailing catalogs, soft-delete records with bad images")
        p.add_argument("--quick", "--no-decode", dest="quick", action="store_true",
                       help="do not decode the images, only look at their markers (faster; misses "
                            "images damaged in their middle)")
        p.set_defaults(func=cmd_check, repair=repair)

    p = sub.add_parser("hist", help="PNG histograms of steering/throttle")
    p.add_argument("tubs", nargs="+")
    p.add_argument("--out", default=None, help="PNG file (default: <first tub>_hist.png)")
    p.add_argument("--fields", default="user/angle,user/throttle", help="comma-separated fields")
    p.add_argument("--bins", type=int, default=50)
    p.set_defaults(func=cmd_hist)

    _movie_and_udacity_parsers(sub)
    _lerobot_parsers(sub)


def _movie_and_udacity_parsers(sub: Any) -> None:
    """``tub movie`` and the Udacity recording's import and export."""
    p = sub.add_parser("movie", help="MP4 of the images with steering/throttle overlay")
    p.add_argument("tub")
    p.add_argument("--out", default=None, help="MP4 file (default: <tub>.mp4)")
    p.add_argument("--start", type=int, default=0)
    p.add_argument("--end", type=int, default=None)
    p.add_argument("--fps", type=float, default=20.0)
    p.add_argument("--scale", type=int, default=2, help="integer upscale of the frames")
    p.add_argument("--model", default=None, metavar="MODEL",
                   help="a pilot model file: its steering is drawn as an orange bar above the recorded (green) one")
    p.add_argument("--salient", nargs="?", const="integrated", default=None, metavar="METHOD",
                   choices=("integrated", "smoothgrad", "occlusion"),
                   help="with --model: overlay where the model looks for its steering (default method: integrated; "
                        "smoothgrad or occlusion; docs/insight.md)")
    p.set_defaults(func=cmd_movie)

    p = sub.add_parser("import-udacity", help="import a Udacity simulator recording (driving_log.csv)")
    p.add_argument("source", help="driving_log.csv or the folder holding it (with IMG/)")
    p.add_argument("tub", help="tub folder to create (or append to)")
    p.add_argument("--max-catalog-len", type=int, default=1000)
    p.set_defaults(func=cmd_import_udacity)

    p = sub.add_parser("export-udacity", help="write tubs as a Udacity recording (driving_log.csv + IMG/)")
    p.add_argument("tubs", nargs="+", help="tub folders or folders of tubs")
    p.add_argument("--out", required=True, help="new folder for driving_log.csv and IMG/")
    p.add_argument("--style", choices=("simulator", "sample", "semicolon"), default="simulator",
                   help="simulator: no header, ',' and absolute paths; sample: header, ', ' and IMG/ paths "
                        "(Udacity's data.zip); semicolon: header and ';'")
    p.set_defaults(func=cmd_export_udacity)


def _lerobot_parsers(sub: Any) -> None:
    """``tub export-lerobot`` and ``tub import-lerobot``."""
    p = sub.add_parser("export-lerobot", help="write tubs as a LeRobot v3.0 dataset (needs the datasets extra)")
    p.add_argument("tubs", nargs="+", help="tub folders or folders of tubs")
    p.add_argument("--out", required=True, help="new folder for the dataset")
    p.add_argument("--fps", type=int, default=None,
                   help="nominal frame rate (default: measured from the capture times)")
    frames = p.add_mutually_exclusive_group()
    frames.add_argument("--video", dest="video", action="store_true", default=True,
                        help="camera frames as MP4 videos (default, as LeRobot)")
    frames.add_argument("--images", dest="video", action="store_false",
                        help="camera frames as the tub's JPEGs inside the parquet files")
    p.add_argument("--vcodec", choices=("libsvtav1", "h264", "hevc"), default="libsvtav1",
                   help="video codec (libsvtav1 = AV1, LeRobot's default)")
    p.add_argument("--crf", type=int, default=30, help="video quality, 0-63, lower is better (LeRobot: 30)")
    p.add_argument("--task", default=None,
                   help="task text of frames without behaviour label or simulator track "
                        "(default: 'drive along the track')")
    p.add_argument("--max-gap", type=float, default=1.0, metavar="SECONDS",
                   help="a longer gap between capture times starts a new episode (0: never)")
    p.add_argument("--max-episode-s", type=float, default=None, metavar="SECONDS",
                   help="longer sessions are split into episodes of at most this length (default: 1800, "
                        "30 min; at most 2048: LeRobot's float32 timestamps lose its 1e-4 s tolerance beyond)")
    p.set_defaults(func=cmd_export_lerobot)

    p = sub.add_parser("import-lerobot", help="read a LeRobot v3.0 dataset into a new tub (needs the datasets extra)")
    p.add_argument("dataset", help="the dataset folder (holding meta/info.json)")
    p.add_argument("--out", required=True, help="new tub folder")
    p.add_argument("--jpeg-quality", type=int, default=95,
                   help="JPEG quality of frames decoded from videos (1-100)")
    p.set_defaults(func=cmd_import_lerobot)


def _errors() -> tuple[type[BaseException], ...]:
    from parts.tub.errors import TubError

    return (TubError, ValueError, OSError)


def _user_error(exc: BaseException) -> UserError:
    return UserError(str(exc))


def _tubs(paths: list[str]) -> list[Path]:
    from parts.tub.reader import find_tubs

    try:
        return find_tubs(paths)
    except _errors() as exc:
        raise _user_error(exc) from exc


def cmd_info(args: argparse.Namespace) -> int:
    from parts.tub.tools import tub_info

    for i, path in enumerate(_tubs(args.tubs)):
        try:
            info = tub_info(path)
        except _errors() as exc:
            raise _user_error(exc) from exc
        _out(("\n" if i else "") + "\n".join(info.lines()))
    return 0


def cmd_ls(args: argparse.Namespace) -> int:
    from parts.tub.format import IMAGE_TYPES
    from parts.tub.tools import check_fields, format_header, format_record, parse_ranges
    from parts.tub.tub import Tub

    try:
        tub = Tub(args.tub, read_only=True)
        wanted = set(parse_ranges(args.range, tub.current_index)) if args.range else None
        fields = [f for f in args.fields.split(",") if f] if args.fields else \
            [k for k, t in zip(tub.inputs, tub.types, strict=True) if t not in IMAGE_TYPES]
        check_fields(fields, tub.inputs, args.tub)
    except _errors() as exc:
        raise _user_error(exc) from exc
    _out(format_header(fields))
    deleted = tub.manifest.deleted_indexes
    for index, rec in tub.records(include_deleted=args.deleted):
        if wanted is None or index in wanted:
            _out(format_record(index, rec, index in deleted, fields))
    return 0


def _edit(args: argparse.Namespace, delete: bool) -> int:
    from parts.tub.tools import format_ranges, parse_ranges
    from parts.tub.tub import Tub

    if not Path(args.tub).is_dir():
        raise UserError(f"{args.tub}: no such tub folder")
    try:
        with Tub(args.tub) as tub:
            idx = parse_ranges(args.ranges, tub.current_index)
            before = len(tub)
            kept: list[int] = []  # restore: indexes that stay deleted
            if delete:
                tub.delete_records(idx)
            else:
                kept = tub.restore_records(idx)
            after = len(tub)
    except _errors() as exc:
        raise _user_error(exc) from exc
    verb = "deleted" if delete else "restored"
    _out(f"{args.tub}: {verb} {abs(before - after)} records ({len(idx)} indexes given); {after} records now")
    if kept:
        _out(f"{len(kept)} kept deleted: they have no input value (mostly indexes kept for records "
             f"that could not be written): {format_ranges(kept)}")
    return 0


def cmd_delete(args: argparse.Namespace) -> int:
    return _edit(args, True)


def cmd_restore(args: argparse.Namespace) -> int:
    return _edit(args, False)


def cmd_check(args: argparse.Namespace) -> int:
    from parts.tub.check import check_tub

    bad = 0
    for path in _check_paths(args.tubs):
        try:
            report = check_tub(path, repair=args.repair, decode=not args.quick, progress=_tty())
        except _errors() as exc:
            raise _user_error(exc) from exc
        _out("\n".join(report.lines()))
        bad += 0 if report.settled else 1
    return 1 if bad else 0


def _check_paths(paths: list[str]) -> list[Path]:
    """The tubs ``tub check`` looks at: those :func:`_tubs` finds, and the folders (given, or in a
    given folder) that an older version was killed while creating as a tub (parts.tub.births)."""
    from parts.tub.births import stillborn

    found: list[Path] = []
    rest = []
    for text in paths:
        path = Path(text)
        if path.is_dir() and stillborn(path):
            found.append(path)
            continue
        rest.append(text)
        if path.is_dir():
            found += [c for c in sorted(path.iterdir()) if c.is_dir() and not c.name.startswith(".")
                      and any(c.iterdir()) and stillborn(c)]
    if rest:
        try:
            tubs = _tubs(rest)
        except UserError:
            if not found:
                raise
            tubs = []
        found += [t for t in tubs if t not in found]
    return found


def cmd_hist(args: argparse.Namespace) -> int:
    from parts.tub.visualize import write_histograms

    tubs = _tubs(args.tubs)
    out = Path(args.out) if args.out else tubs[0].with_name(f"{tubs[0].name}_hist.png")
    try:
        path = write_histograms(tubs, out, [f for f in args.fields.split(",") if f], bins=args.bins)
    except _errors() as exc:
        raise _user_error(exc) from exc
    _out(f"wrote {path}")
    return 0


def cmd_movie(args: argparse.Namespace) -> int:
    from parts.tub.visualize import write_movie

    tub = Path(args.tub)
    out = Path(args.out) if args.out else tub.with_name(f"{tub.name}.mp4")
    if args.salient and not args.model:
        raise UserError("--salient shows where a model looks: give the model with --model MODEL")
    try:
        view = _salient_view(args.model, args.salient) if args.model else None
        path, frames = write_movie(tub, out, start=args.start, end=args.end, fps=args.fps,
                                   scale=args.scale, progress=_tty(), view=view)
    except _errors() as exc:
        raise _user_error(exc) from exc
    _out(f"wrote {path} ({frames} frames)")
    return 0


def _salient_view(model: str, method: str | None) -> Any:
    """The movie's view of ``model`` (ValueError, one line, for a file that is no model)."""
    from parts.pilots.errors import ModelFileError
    from parts.pilots.saliency import Explainer
    from parts.pilots.salient_view import SalientView

    try:
        return SalientView(Explainer.from_file(model), method)
    except ModelFileError as exc:
        raise ValueError(f"--model: {exc}") from exc


def cmd_import_udacity(args: argparse.Namespace) -> int:
    from parts.tub.udacity import import_udacity

    try:
        report = import_udacity(args.source, args.tub, max_catalog_len=args.max_catalog_len,
                                progress=_tty())
    except _errors() as exc:
        raise _user_error(exc) from exc
    _out(f"{report.tub}: imported {report.imported} records, skipped {len(report.skipped)}")
    for line in report.skipped[:10]:
        _out(f"  skipped {line}")
    return 0 if report.imported else 1


def cmd_export_udacity(args: argparse.Namespace) -> int:
    from parts.tub.udacity import export_udacity

    try:
        report = export_udacity(args.tubs, args.out, style=args.style, progress=_tty())
    except _errors() as exc:
        raise _user_error(exc) from exc
    _out(f"{report.out}: {report.rows} rows ({', '.join(report.cameras)} camera"
         f"{'s' if len(report.cameras) > 1 else ''}), {report.skipped_summary()}")
    for line in report.skipped[:10]:
        _out(f"  skipped {line}")
    return 0


def cmd_export_lerobot(args: argparse.Namespace) -> int:
    from parts.tub.lerobot.export import DEFAULT_MAX_EPISODE_S, DEFAULT_TASK, MAX_EPISODE_S, export_lerobot

    # the options' own names in the message (the library names its parameters)
    max_episode_s = DEFAULT_MAX_EPISODE_S if args.max_episode_s is None else args.max_episode_s
    if not args.max_gap >= 0:
        raise UserError(f"--max-gap must be >= 0 seconds (0: never split on a gap), got {args.max_gap:g}")
    if not 0 < max_episode_s <= MAX_EPISODE_S:
        raise UserError(f"--max-episode-s must be > 0 and <= {MAX_EPISODE_S} s (LeRobot's float32 timestamps "
                        f"lose its 1e-4 s tolerance beyond), got {max_episode_s:g}")
    try:
        report = export_lerobot(args.tubs, args.out, fps=args.fps, video=args.video, codec=args.vcodec,
                                crf=args.crf, task=args.task or DEFAULT_TASK, max_gap_s=args.max_gap,
                                max_episode_s=max_episode_s, progress=_tty())
    except _errors() as exc:
        raise _user_error(exc) from exc
    _out("\n".join(report.lines()))
    for line in report.skipped[:10]:
        _out(f"  skipped {line}")
    return 0


def cmd_import_lerobot(args: argparse.Namespace) -> int:
    from parts.tub.lerobot.load import import_lerobot

    try:
        report = import_lerobot(args.dataset, args.out, jpeg_quality=args.jpeg_quality, progress=_tty())
    except _errors() as exc:
        raise _user_error(exc) from exc
    _out("\n".join(report.lines()))
    return 0
