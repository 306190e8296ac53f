"""``vehicle sim ...``: draw tracks, evaluate pilots, record expert demonstrations, serve the
simulator to Donkey-simulator clients (gym-donkeycar, DonkeyCar)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import PartError, UserError

logger = logging.getLogger(__name__)


def register(subparsers: Any) -> None:
    """Add the ``sim`` command and its subcommands."""
    sim = subparsers.add_parser("sim", help="built-in simulator: tracks, evaluation, expert recording",
                                description=__doc__)
    sub = sim.add_subparsers(dest="sim_command", metavar="SUBCOMMAND", required=True)
    fmt = argparse.ArgumentDefaultsHelpFormatter

    track = sub.add_parser("track", help="draw a generated track (top view) as PNG", formatter_class=fmt)
    track.add_argument("--seed", type=int, required=True, help="track seed")
    track.add_argument("--png", required=True, type=_png, help="output PNG file")
    track.add_argument("--camera", metavar="PNG", type=_png, help="also write the camera's view from the start line")
    track.add_argument("--views", type=int, default=1, metavar="N",
                       help="with --camera: N views from points spread evenly around the track, tiled")
    track.add_argument("--zoom", type=int, default=1, metavar="K",
                       help="with --camera: enlarge the views K times (pixels stay square)")
    track.add_argument("--size", type=int, default=800, help="image size in pixels")
    _world_options(track)
    track.set_defaults(func=cmd_track)

    ev = sub.add_parser("eval", help="closed-loop evaluation of a pilot on simulated tracks", formatter_class=fmt)
    ev.add_argument("--pilot", help="'expert' or a trained model file")
    ev.add_argument("--path", metavar="CSV", help="follow this recorded path (docs/path_follow.md) on its track; "
                                                  "with --pilot too, both drive and one table compares them")
    ev.add_argument("--localizer", choices=["odometry", "gps", "fused"],
                    help="with --path: the pose from the simulated encoder, GPS or both (default PATH_LOCALIZER)")
    ev.add_argument("--tracks", type=_seeds, help="comma-separated track seeds (default SIM_EVAL_TRACK_SEEDS)")
    ev.add_argument("--laps", type=int, help="laps per track (default SIM_EVAL_LAPS)")
    ev.add_argument("--max-time", type=float, help="simulated seconds per track at most")
    ev.add_argument("--throttle", type=float, help="fixed throttle: use only the pilot's steering")
    ev.add_argument("--workers", type=int, metavar="N",
                    help="tracks evaluated in parallel processes (default SIM_EVAL_WORKERS: 0 = one per core)")
    ev.add_argument("--sim", choices=["builtin", "donkey", "udacity"], default="builtin",
                    help="simulator to evaluate in: ours, the Donkey simulator (SIM_HOST:SIM_PORT, or `vehicle sim "
                         "serve`; synchronous steps) or the Udacity simulator (real time, on the track it shows)")
    ev.add_argument("--scenes", help="with --sim donkey: comma-separated scenes, one episode each (default "
                                     "DONKEY_GYM_ENV_NAME; --tracks N stands for scene track_N of `vehicle sim serve`)")
    ev.add_argument("--json", help="write the full report (metrics and trajectories) here")
    ev.add_argument("--png", type=_png, help="write the driven trajectories over the track maps here (.png)")
    ev.add_argument("--lane-changes", action=argparse.BooleanOptionalAction, default=None,
                    help="command lane changes and score them (default: for a behaviour pilot when SIM_LANES = 2)")
    ev.add_argument("--store", action=argparse.BooleanOptionalAction, default=None,
                    help="keep the result in the car's model database, where `vehicle models` shows it and the "
                         "leaderboard ranks it (default: when the model is registered; --store: it must be)")
    ev.add_argument("--draws", type=int, metavar="N",
                    help="robustness: drive the tracks in each theme of --theme (default SIM_THEME) under N hidden "
                         "randomisation draws (seeds 1001..1000+N, never used for training) and report per theme "
                         "the mean and the worst draw, beside the expert's speed (docs/simulator.md)")
    ev.add_argument("--gallery", metavar="DIR",
                    help="write a failure gallery of a model file into the new folder DIR: the frames before each "
                         "intervention and worst |CTE| moment with the pilot's and the expert's steering and where "
                         "the pilot looked (DIR/index.html, DIR/gallery.json; docs/insight.md)")
    ev.add_argument("--gallery-seconds", type=float, default=2.0, metavar="S", help="seconds shown before each moment")
    ev.add_argument("--gallery-frames", type=int, default=6, metavar="N", help="frames shown per moment")
    ev.add_argument("--gallery-worst", type=int, default=3, metavar="N",
                    help="worst-|CTE| moments per track besides the interventions")
    ev.add_argument("--gallery-method", choices=["integrated", "smoothgrad", "occlusion"], default="integrated",
                    help="saliency method of the gallery")
    _world_options(ev)
    ev.set_defaults(func=cmd_eval)

    _robustness_parser(sub)

    rec = sub.add_parser("record", help="record expert demonstrations into a tub", formatter_class=fmt)
    rec.add_argument("--records", type=int, required=True, help="number of records")
    rec.add_argument("--tracks", type=_seeds, help="comma-separated track seeds (default SIM_TRACK_SEEDS)")
    rec.add_argument("--tub", help="tub folder (default: a new tub in the car's data folder)")
    rec.add_argument("--noise", type=float, help="steering noise injection amplitude (default SIM_EXPERT_NOISE)")
    rec.add_argument("--lane-changes", type=int, metavar="N",
                     help="two-lane tracks (SIM_LANES = 2): switch the behaviour (Left_Lane / Right_Lane) N times at "
                          "random; the expert changes lanes and the records carry the behaviour")
    _world_options(rec)
    rec.set_defaults(func=cmd_record)

    rp = sub.add_parser("record-path", help="the expert drives one lap; save it as a path file (path follow)",
                        formatter_class=fmt)
    rp.add_argument("--track", type=int, default=1, help="track seed")
    rp.add_argument("--localizer", choices=["odometry", "gps", "fused"],
                    help="record the pose from the simulated encoder, GPS or both (default PATH_LOCALIZER)")
    rp.add_argument("--out", required=True, metavar="CSV", help="path file to write")
    _world_options(rp)
    rp.set_defaults(func=cmd_record_path)

    serve = sub.add_parser("serve", formatter_class=fmt,
                           help="serve the simulator over the Donkey simulator's protocol (gym-donkeycar, DonkeyCar)",
                           description="Serve the built-in simulator over the Donkey simulator's TCP protocol: "
                                       "gym-donkeycar environments, DonkeyCar's DonkeyGymEnv part and any Donkey "
                                       "client drive it, headless, one car per connection, faster than real time "
                                       "when the client asks for step_mode synchronous. See docs/simulators.md.")
    serve.add_argument("--port", type=int, default=9091, help="TCP port (the Donkey simulator's is 9091)")
    serve.add_argument("--host", default="127.0.0.1",
                       help="interface to listen on; 0.0.0.0 lets clients on other machines connect")
    serve.add_argument("--tracks", type=_seeds,
                       help="comma-separated track seeds served (default SIM_TRACK_SEEDS); every Donkey scene "
                            "name maps onto them in turn, and track_<seed> loads a seed")
    serve.add_argument("--hz", type=float, default=20.0, help="telemetry rate in real-time mode")
    serve.add_argument("--max-clients", type=int, default=16, help="connections served at once")
    add_car_options(serve)
    serve.set_defaults(func=cmd_serve)


def _robustness_parser(sub: Any) -> None:
    """``vehicle sim robustness``: the demo's recipe over training seeds x precisions x hidden draws."""
    from vehicle.app.demo import DEFAULTS, RECIPES

    rb = sub.add_parser("robustness", help="retrain the demo's recipe over seeds and precisions and report the "
                                           "mean, worst draw and worst seed per theme",
                        description=_robustness_doc(), formatter_class=argparse.RawDescriptionHelpFormatter)
    rb.add_argument("--recipe", choices=list(RECIPES), default="plain",
                    help="the recipe of vehicle demo --recipe (default plain): "
                         + "; ".join(f"{k}: {r.what}" for k, r in RECIPES.items()))
    rb.add_argument("--lanes", action="store_true",
                    help="the lanes demo's models instead (vehicle demo --lanes: the two-stream lanes and the "
                         "single-stream behavior model), driven with commanded lane changes; reported per model "
                         "(docs/vision.md)")
    rb.add_argument("--lane-changes", type=int, metavar="N",
                    help="--lanes: lane changes commanded while recording (default the demo's)")
    rb.add_argument("--seeds", type=_seeds, default=[1, 2, 3], metavar="N,N",
                    help="training seeds (vehicle demo --seed; default 1,2,3)")
    rb.add_argument("--precisions", metavar="P,P",
                    help="training precisions, of fp32 and bf16 (default fp32,bf16 on a CPU with native bf16, else "
                         "fp32)")
    rb.add_argument("--draws", type=int, default=3, metavar="N", help="hidden randomisation draws per theme "
                                                                      "(default 3)")
    rb.add_argument("--eval-tracks", type=_seeds, metavar="SEEDS",
                    help=f"unseen track seeds (default the demo's, {_ints(DEFAULTS['eval_tracks'])})")
    rb.add_argument("--laps", type=int, help=f"laps per track and draw (default the demo's, {DEFAULTS['laps']})")
    rb.add_argument("--records", type=int, help=f"records per recording (default the demo's, {DEFAULTS['records']})")
    rb.add_argument("--epochs", type=int, help=f"most training epochs (default the demo's, {DEFAULTS['epochs']})")
    rb.add_argument("--train-tracks", type=_seeds, metavar="SEEDS",
                    help="training track seeds (default the demo's, 1-64; fewer only for tiny trial runs)")
    rb.add_argument("--jobs", type=int, metavar="N",
                    help="runs at a time, each with one torch thread (default: one per core)")
    rb.add_argument("--out", default="robustness", metavar="DIR",
                    help="working folder: runs/ and robustness.json, robustness.md (default ./robustness)")
    rb.set_defaults(func=cmd_robustness)


def _ints(values: list[int]) -> str:
    return ",".join(map(str, values))


def _robustness_doc() -> str:
    import vehicle.app.robustness

    return vehicle.app.robustness.__doc__ or ""


def _world_options(p: argparse.ArgumentParser) -> None:
    """--theme, --randomize and the car options."""
    p.add_argument("--theme", type=_themes, metavar="NAME[,NAME]",
                   help="visual theme(s): road, indoor, park; several are dealt to the tracks in turn "
                        "(default SIM_THEME)")
    p.add_argument("--randomize", type=_randomize, metavar="SEED|off",
                   help="domain randomisation seed, or 'off' (default SIM_RANDOMIZE); use a seed the pilot "
                        "was not trained on for held-out conditions")
    add_car_options(p)


def _themes(text: str) -> list[str]:
    from parts.sim.themes import ThemeError, theme_list

    try:
        return theme_list(text)
    except ThemeError as exc:
        raise argparse.ArgumentTypeError(str(exc).replace(" (SIM_THEME)", "")) from None


def _png(text: str) -> str:
    if not text.lower().endswith(".png"):
        raise argparse.ArgumentTypeError(f"expected a .png file name, got {text!r}")
    return text


_OFF = "off"


def _randomize(text: str) -> int | str:
    if text.strip().lower() in ("off", "none", "no"):
        return _OFF
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer seed or 'off', got {text!r}") from None


def load_world_config(args: argparse.Namespace) -> Any:
    """The command's settings (:func:`load_for_command`) with --theme and --randomize applied, the
    themes and randomisation ranges checked before any work."""
    from parts.sim.randomize import check_ranges
    from parts.sim.themes import ThemeError, get_theme, theme_list

    cfg = load_for_command(args)
    overrides: dict[str, Any] = {}
    if getattr(args, "theme", None):
        overrides["SIM_THEME"] = args.theme if len(args.theme) > 1 else args.theme[0]
    if getattr(args, "randomize", None) is not None:
        overrides["SIM_RANDOMIZE"] = None if args.randomize == _OFF else args.randomize
    cfg = cfg.replace(**overrides) if overrides else cfg
    try:
        themes = theme_list(cfg.SIM_THEME)
        check_ranges(cfg.SIM_RANDOMIZE_RANGES)
        if cfg.SIM_LANES == 2:
            for name in themes:
                if get_theme(name).divider is None:
                    raise ThemeError(f"theme {name!r} has no two-lane variant: use SIM_LANES = 1 or the road "
                                     "or indoor theme")
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    return cfg


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
    """Draw one track (and optionally camera views from its start and around it)."""
    import cv2

    from parts.sim.eval_report import track_image, write_panels
    from parts.sim.track import TrackError

    cfg = load_world_config(args)
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

        if not 1 <= args.views <= 64 or not 1 <= args.zoom <= 8:
            raise UserError(f"--views {args.views} / --zoom {args.zoom}: use 1 .. 64 views and a zoom of 1 .. 8")
        sim = SimCar.from_config(cfg, seeds=[args.seed], realtime=False)
        views = []
        for k in range(args.views):
            sim.car.place(*sim.track.pose_at(k * sim.track.length / args.views, sim.start_offset))
            frame = sim.render()
            views.append(cv2.resize(frame, None, fx=args.zoom, fy=args.zoom, interpolation=cv2.INTER_NEAREST))
        try:
            path = write_panels(views, args.camera, cols=min(args.views, 4))
        except OSError as exc:
            raise UserError(str(exc)) from exc
        print(f"camera view{'s' if args.views > 1 else ''}: wrote {path}")  # noqa: T201
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    """Evaluate a pilot and print the table; write JSON / PNG on request."""
    from parts.sim.eval_report import format_table
    from vehicle.app.evaluate import evaluate

    cfg = load_world_config(args)
    seeds = args.tracks or list(cfg.SIM_EVAL_TRACK_SEEDS)
    laps = args.laps if args.laps is not None else cfg.SIM_EVAL_LAPS
    if laps < 1:
        raise UserError(f"--laps {laps}: give at least 1 lap")
    workers = args.workers if args.workers is not None else cfg.SIM_EVAL_WORKERS
    if workers < 0:
        raise UserError(f"--workers {workers}: give 1 or more processes, or 0 for one per core")
    if args.pilot is None and args.path is None:
        raise UserError("give --pilot ('expert' or a model file) or --path (a recorded path), or both")
    path_driver = None
    if args.path is not None:
        path_driver = _path_driver(args, cfg, seeds)
        if args.pilot is None:
            return _eval_path(args, cfg, seeds, laps, path_driver)
    if args.pilot != "expert" and not Path(args.pilot).exists():
        raise UserError(f"--pilot {args.pilot}: no such model file; pass 'expert' or a trained model "
                        "(e.g. models/mypilot.pt)")
    if args.sim != "builtin" and args.png:
        raise UserError("--png draws the built-in simulator's tracks: drop it with --sim " + args.sim)
    if args.scenes and args.sim != "donkey":
        raise UserError("--scenes names Donkey simulator scenes: use it with --sim donkey")
    if args.sim == "udacity" and args.tracks:
        raise UserError("--tracks: the Udacity simulator drives the track it shows (choose it in its menu)")
    gallery = _gallery_spec(args, path_driver)
    if args.draws is not None:
        if path_driver is not None:
            raise UserError("--draws compares pilots under hidden draws; a path is followed in the track's own "
                            "look: drop --path or --draws")
        return _eval_draws(args, cfg, seeds, laps, workers, gallery)
    scenes = None
    if args.sim == "donkey":
        scenes = [x.strip() for x in args.scenes.split(",") if x.strip()] if args.scenes else (
            [f"track_{s}" for s in args.tracks] if args.tracks else None)
    try:
        report = evaluate(args.pilot, seeds, laps, cfg=cfg, max_time=args.max_time,
                          fixed_throttle=args.throttle, sim=args.sim, scenes=scenes,
                          lane_changes=args.lane_changes, workers=workers, gallery=gallery)
    except (ValueError, FileNotFoundError) as exc:
        raise UserError(str(exc)) from exc
    except PartError as exc:  # e.g. a model made for another image size: the loop stopped safely
        raise UserError(f"evaluation stopped: {exc}") from exc
    print(format_table(report))  # noqa: T201 - CLI output
    if gallery is not None:
        print(f"gallery: {report['gallery']}")  # noqa: T201
    if path_driver is not None:
        path_report = _eval_path(args, cfg, seeds, laps, path_driver, quiet=True)
        from parts.sim.eval_report import format_comparison

        print("\n" + format_comparison([report, path_report]))  # noqa: T201
    _write_and_store(args, cfg, report)
    return 0


def _gallery_spec(args: argparse.Namespace, path_driver: Any) -> Any:
    """--gallery*, checked before any work (UserError, one line): a model file, the built-in
    simulator, a folder that does not exist yet."""
    if args.gallery is None:
        return None
    from vehicle.app.failure_moments import GallerySpec
    from vehicle.app.gallery import check_new_folder

    if args.pilot in (None, "expert") or path_driver is not None:
        raise UserError("--gallery shows where a model looks: give --pilot a model file (and no --path)")
    if args.sim != "builtin":
        raise UserError(f"--gallery shows the built-in simulator's frames: drop it with --sim {args.sim}")
    spec = GallerySpec(args.gallery, args.pilot, window_s=args.gallery_seconds, frames=args.gallery_frames,
                       worst=args.gallery_worst, method=args.gallery_method)
    try:
        spec.check()
        check_new_folder(args.gallery)
    except ValueError as exc:
        raise UserError(f"--gallery: {exc}") from exc
    return spec


def _eval_draws(args: argparse.Namespace, cfg: Any, seeds: list[int], laps: int, workers: int,
                gallery: Any = None) -> int:
    """``vehicle sim eval --draws N``: every theme under N hidden draws, mean and worst per theme."""
    from parts.sim.themes import theme_list
    from vehicle.app.eval_draws import evaluate_draws, format_draws_table, hidden_draws

    if args.sim != "builtin" or args.randomize is not None:
        raise UserError("--draws draws the built-in simulator's randomisation itself: drop --sim and --randomize")
    try:
        draws = hidden_draws(args.draws, cfg.SIM_RANDOMIZE)
        report = evaluate_draws(args.pilot, seeds, laps, cfg=cfg, draws=draws, themes=theme_list(cfg.SIM_THEME),
                                workers=workers, max_time=args.max_time, gallery=gallery)
    except (ValueError, FileNotFoundError) as exc:
        raise UserError(str(exc)) from exc
    except PartError as exc:
        raise UserError(f"evaluation stopped: {exc}") from exc
    print(format_draws_table(report))  # noqa: T201 - CLI output
    if gallery is not None:
        print(f"galleries: {report['gallery']}")  # noqa: T201
    _write_and_store(args, cfg, report)
    return 0


def _write_and_store(args: argparse.Namespace, cfg: Any, report: dict[str, Any]) -> None:
    """--json, --png and --store of ``vehicle sim eval``."""
    from parts.sim.eval_report import write_json, write_png

    if args.json:
        print(f"wrote {write_json(report, args.json)}")  # noqa: T201
    if args.png:
        print(f"wrote {write_png(report, args.png, cfg)}")  # noqa: T201
    if args.pilot in (None, "expert"):
        if args.store:
            raise UserError("--store keeps evaluations of registered models; the expert (or a path alone) is not one")
        return
    if args.store is False:
        return
    from training.model_db import ModelDBError
    from vehicle.app.eval_store import store_report

    try:
        ev = store_report(cfg, Path(args.pilot), report)
    except ModelDBError as exc:
        if args.store:
            raise UserError(f"--store: {exc}") from exc
        print(f"not stored: {args.pilot} is not in the car's model database ({cfg.path('MODELS_PATH')})")  # noqa: T201
        return
    print(f"stored as evaluation {ev.id} of {ev.model} (shown by `vehicle models`; --no-store leaves it out)")  # noqa: T201


def _path_driver(args: argparse.Namespace, cfg: Any, seeds: list[int]) -> Any:
    """The path follower of ``--path`` / ``--localizer`` (a path belongs to the track it was recorded on)."""
    from parts.path.pathfile import load_path
    from vehicle.app.path_sim import PathDriver

    if args.sim != "builtin":
        raise UserError("--path follows a path in the built-in simulator: drop --sim " + args.sim)
    if len(seeds) != 1:
        raise UserError(f"--path: a path belongs to the track it was recorded on; give one --tracks seed, not "
                        f"{len(seeds)}")
    localizer = args.localizer or cfg.PATH_LOCALIZER
    return PathDriver(load_path(args.path), localizer, cfg, name=f"path {Path(args.path).name} ({localizer})")


def _eval_path(args: argparse.Namespace, cfg: Any, seeds: list[int], laps: int, driver: Any,
               quiet: bool = False) -> Any:
    """Evaluate the path follower (serially: it is no model file); print its table unless ``quiet``."""
    from parts.sim.eval_report import format_table, write_json
    from vehicle.app.evaluate import evaluate

    if args.store and not quiet:
        raise UserError("--store keeps evaluations of registered models; a path is not one")
    try:
        report = evaluate(driver, seeds, laps, cfg=cfg, max_time=args.max_time, fixed_throttle=args.throttle)
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    if quiet:
        return report
    print(format_table(report))  # noqa: T201 - CLI output
    if args.json:
        print(f"wrote {write_json(report, args.json)}")  # noqa: T201
    if args.png:
        from parts.sim.eval_report import write_png

        print(f"wrote {write_png(report, args.png, cfg)}")  # noqa: T201
    return 0


def cmd_record_path(args: argparse.Namespace) -> int:
    """Record one expert lap of --track in the localiser's frame and write it as CSV."""
    from parts.path.pathfile import save_path
    from vehicle.app.path_sim import record_path

    cfg = load_world_config(args)
    localizer = args.localizer or cfg.PATH_LOCALIZER
    path = record_path(cfg, args.track, localizer)
    print(f"recorded {len(path)} points ({path.length:.1f} m) on track {args.track} with {localizer}: "  # noqa: T201
          f"wrote {save_path(path, args.out)}")
    return 0


def cmd_record(args: argparse.Namespace) -> int:
    """Record expert demonstrations."""
    from vehicle.app.record import record_expert

    cfg = load_world_config(args)
    if args.records < 1:
        raise UserError(f"--records {args.records}: give at least 1 record")
    if args.lane_changes is not None and args.lane_changes < 0:
        raise UserError(f"--lane-changes {args.lane_changes}: give 0 or more")
    try:
        path = record_expert(cfg, args.tracks, args.records, args.tub, noise=args.noise,
                             lane_changes=args.lane_changes)
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    print(f"recorded {args.records} records into {path}")  # noqa: T201
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C."""
    from parts.bridges.donkey_server import DonkeyServer, scene_names

    cfg = load_for_command(args)
    if not 0 < args.port <= 65535:
        raise UserError(f"--port {args.port}: give a TCP port in 1..65535")
    if not 0 < args.hz <= 1000:
        raise UserError(f"--hz {args.hz}: give a telemetry rate in (0, 1000] Hz")
    if args.max_clients < 1:
        raise UserError(f"--max-clients {args.max_clients}: give at least 1")
    seeds = args.tracks or list(cfg.SIM_TRACK_SEEDS)
    try:
        server = DonkeyServer(args.host, args.port, seeds=seeds, cfg=cfg, telemetry_hz=args.hz,
                              max_clients=args.max_clients)
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    server.start()
    print(f"Donkey-protocol simulator on {args.host}:{server.port} (tracks {','.join(map(str, seeds))}); "  # noqa: T201
          f"scenes: {', '.join(scene_names(seeds))}. Ctrl-C to stop.", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
    return 0


def robustness_protocol(args: argparse.Namespace) -> Any:
    """The :class:`vehicle.app.robustness.Protocol` of the command line, checked (UserError)."""
    import os

    from training.acceleration import cpu_caps
    from vehicle.app.commands.demo import check_precision
    from vehicle.app.demo import DEFAULTS, MAX_SEED
    from vehicle.app.demo_lanes import DEFAULTS as LANE_DEFAULTS
    from vehicle.app.robustness import LANES, PRECISIONS, Protocol

    native = cpu_caps().native_bf16
    precisions = [p.strip() for p in (args.precisions or ("fp32,bf16" if native else "fp32")).split(",") if p.strip()]
    if not precisions or any(p not in PRECISIONS for p in precisions) or len(set(precisions)) < len(precisions):
        raise UserError(f"--precisions {args.precisions}: give fp32, bf16 or fp32,bf16")
    for p in precisions:
        check_precision(p, "--precisions")
    bad = [s for s in args.seeds if not 1 <= s <= MAX_SEED]
    if bad or len(set(args.seeds)) < len(args.seeds):
        raise UserError(f"--seeds {_ints(args.seeds)}: give different seeds of 1 .. {MAX_SEED}")
    for option, value, least in (("--draws", args.draws, 1), ("--laps", args.laps, 1),
                                 ("--records", args.records, 100), ("--epochs", args.epochs, 1),
                                 ("--jobs", args.jobs, 1), ("--lane-changes", args.lane_changes, 1)):
        if value is not None and value < least:
            raise UserError(f"{option} {value}: give at least {least}")
    if args.lanes and args.recipe != "plain":
        raise UserError("--recipe chooses the plain demo's recipe: leave it out with --lanes")
    if args.lane_changes is not None and not args.lanes:
        raise UserError("--lane-changes belongs to --lanes: add --lanes or leave it out")
    defaults = LANE_DEFAULTS if args.lanes else DEFAULTS
    overlap = set(args.train_tracks or defaults["train_tracks"]) & set(args.eval_tracks or defaults["eval_tracks"])
    if overlap:
        raise UserError(f"--eval-tracks: {_ints(sorted(overlap))} are training tracks; evaluate on others")
    return Protocol(out=Path(args.out).resolve(), recipe=LANES if args.lanes else args.recipe, seeds=args.seeds,
                    precisions=precisions, draws=args.draws, eval_tracks=args.eval_tracks, laps=args.laps,
                    records=args.records, epochs=args.epochs, train_tracks=args.train_tracks,
                    jobs=args.jobs or os.cpu_count() or 1, lane_changes=args.lane_changes)


def cmd_robustness(args: argparse.Namespace) -> int:
    """Run (or resume) the robustness protocol and report it (docs/pilot.md)."""
    from vehicle.app.robustness import run_protocol

    return run_protocol(robustness_protocol(args))
