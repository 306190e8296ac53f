"""``vehicle camera calibrate``: find the camera matrix and lens distortion from chessboard views.

    vehicle camera calibrate --images photos/          # photos of the printed board (the thesis's way)
    vehicle camera calibrate --live --views 15         # hold the board in front of the car's camera
    vehicle camera calibrate --live --web              # ... and watch the detected corners in a browser
    vehicle camera calibrate --sim                     # the simulator's camera (SIM_CAMERA_DISTORTION)

Print a chessboard (default 10 x 7 inner corners, CAMERA_CALIB_BOARD: count where four squares
meet, so an 11 x 8 squares print), photograph it with the car's own camera from at least ten
angles covering the whole image, corners included. The result goes to the car folder
(CAMERA_CALIBRATION_PATH); set CAMERA_UNDISTORT = True to undistort every frame with it. Copies
with the detected corners drawn go to calibration_corners/ (--images) or next to the views
(calibration_views/<run>/, --live and --sim).
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from pathlib import Path
from typing import Any, ClassVar

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def register(subparsers: Any) -> None:
    """Add the ``camera`` command and its subcommands."""
    cam = subparsers.add_parser("camera", help="camera calibration (intrinsics, lens distortion)",
                                description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = cam.add_subparsers(dest="camera_command", metavar="SUBCOMMAND", required=True)
    cal = sub.add_parser("calibrate", help="calibrate from chessboard views", description=__doc__,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    source = cal.add_mutually_exclusive_group(required=True)
    source.add_argument("--images", metavar="DIR", help="folder of chessboard photos, all of one size")
    source.add_argument("--live", action="store_true", help="collect views from the car's camera (CAMERA_TYPE)")
    source.add_argument("--sim", action="store_true",
                        help="collect views of a board moved in front of the simulated camera")
    cal.add_argument("--views", type=int, default=15, help="views to collect (--live, --sim); default 15")
    cal.add_argument("--timeout", type=float, default=300.0, help="seconds to collect views at most (--live)")
    cal.add_argument("--board", metavar="COLSxROWS", help="inner corners, e.g. 10x7 (default CAMERA_CALIB_BOARD)")
    cal.add_argument("--square-mm", type=float, help="printed square size in mm (default CAMERA_CALIB_SQUARE_MM)")
    cal.add_argument("--model", choices=("standard", "rational"), help="distortion model (default CAMERA_CALIB_MODEL)")
    cal.add_argument("--out", metavar="FILE", help="calibration file (default CAMERA_CALIBRATION_PATH in the car)")
    cal.add_argument("--views-dir", metavar="DIR",
                     help="where --live/--sim write the views (default calibration_views/<date-time>/ in the car); "
                          "only this run's views are calibrated")
    cal.add_argument("--web", action="store_true", help="--live: show the camera with the detected corners on the "
                                                        "web page (WEB_HOST:WEB_CONTROL_PORT)")
    add_car_options(cal)
    cal.set_defaults(func=cmd_calibrate)


def _say(text: str) -> None:
    print(text, flush=True)  # noqa: T201 - the command's own output


def _board(args: argparse.Namespace, cfg: Any) -> Any:
    from parts.vision.calibration import CalibrationError, Chessboard

    columns, rows = cfg.CAMERA_CALIB_BOARD
    if args.board:
        try:
            columns, rows = (int(v) for v in args.board.lower().split("x"))
        except ValueError:
            raise UserError(f"--board {args.board!r}: give the inner corners as COLSxROWS, e.g. 10x7") from None
    try:
        return Chessboard(columns, rows, args.square_mm if args.square_mm is not None else cfg.CAMERA_CALIB_SQUARE_MM)
    except CalibrationError as exc:
        raise UserError(str(exc)) from exc


#: seconds without the board in view between two "board not found" messages (--live, --sim)
NOT_FOUND_EVERY_S = 10.0


def board_hint(board: Any) -> str:
    """What to check when the board is never found: inner corners, not squares, and where to set them."""
    return (f"the board is looked for as {board.columns}x{board.rows} inner corners (where four squares meet: a "
            f"{board.columns + 1}x{board.rows + 1} squares print), not squares: check --board / CAMERA_CALIB_BOARD, "
            "and hold the whole board in view, sharp and well lit")


class _Progress:
    """Part: stop the vehicle once the collector has its views, or after ``timeout`` seconds; every
    NOT_FOUND_EVERY_S seconds without the board in view, say so (a wrong board size looks like this)."""

    INPUTS: ClassVar[tuple[str, ...]] = ("calib/found",)

    def __init__(self, V: Any, collector: Any, board: Any, timeout: float, every: float,
                 clock: Any = time.monotonic) -> None:
        self.V, self.collector, self.board, self.timeout, self.clock = V, collector, board, timeout, clock
        self.every = every
        self.started = self.last_seen = clock()
        self.timed_out = False
        self.ever_found = False
        self._told = 0  # NOT_FOUND_EVERY_S periods already reported since the board was last seen

    def run(self, found: Any) -> None:
        now = self.clock()
        if found:
            self.ever_found = True
            self.last_seen, self._told = now, 0
        elif (periods := int((now - self.last_seen) // self.every)) > self._told:
            self._told = periods
            logger.warning("board not found for %g s: %s", periods * self.every, board_hint(self.board))
        if self.collector.done:
            self.V.stop()
        elif now - self.started > self.timeout:
            self.timed_out = True
            self.V.stop()


def run_folder(root: Path) -> Path:
    """A new folder for this run's views under ``root``: ``root/YYYYmmdd-HHMMSS`` (``-2``, ... when taken)."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    folder, n = root / stamp, 1
    while folder.exists():
        n += 1
        folder = root / f"{stamp}-{n}"
    return folder


def collect_live(cfg: Any, board: Any, folder: Path, views: int, timeout: float, *, sim: bool,
                 web: bool) -> tuple[list[Path], bool]:
    """Run a vehicle (camera -> ChessboardCollector [-> web page]) until ``views`` views are kept;
    returns the view files this run wrote and whether the board was ever seen."""
    from parts.vision.calibration import ChessboardCollector
    from vehicle.clock import SimulatedClock
    from vehicle.vehicle import Vehicle

    clock = SimulatedClock() if sim else None
    V = Vehicle(clock=clock) if clock is not None else Vehicle()
    if sim:
        from parts.sim.camera import camera_from_config
        from parts.sim.chessboard import ChessboardCamera

        try:
            source = ChessboardCamera(camera_from_config(cfg), board.columns, board.rows, poses=max(30, 2 * views),
                                      seed=cfg.SIM_SEED, square_mm=board.square_mm)
        except ValueError as exc:
            raise UserError(f"simulated calibration: {exc} with squares large enough to find: simulate a "
                            "larger camera (SIM_CAMERA_W = 320, SIM_CAMERA_H = 240) or use a board with fewer "
                            "corners (CAMERA_CALIB_BOARD = (7, 5) in myconfig.py, or --board 7x5)") from exc
        V.add(source, outputs=list(ChessboardCamera.OUTPUTS))
    else:
        from vehicle.app.assembly.camera import add_camera

        add_camera(V, cfg.replace(CAMERA_UNDISTORT=False))  # calibrate the raw frames
    # in simulated time the views come at once; a person moving the board needs a moment
    collector = ChessboardCollector(folder, board, target=views, min_interval=0.0 if sim else 1.0,
                                    clock=V.clock.now)
    V.add(collector, inputs=["cam/image_array"], outputs=list(ChessboardCollector.OUTPUTS))
    if web:
        from parts.web.controller import WebController

        page = WebController.from_config(cfg)
        # the page shows its first input as the camera view: give it the frame with the corners; its
        # commands go nowhere (this vehicle has no drivetrain)
        inputs = ["calib/image", *WebController.INPUTS[1:]]
        V.add(page, inputs=inputs, optional_inputs=inputs[1:], threaded=True)
        _say("the web page (its address is logged when it starts) shows the camera with the detected corners")
    progress = _Progress(V, collector, board, math.inf if sim else timeout, NOT_FOUND_EVERY_S, clock=V.clock.now)
    V.add(progress)
    _say(f"collecting {views} chessboard views into {folder} (the board whole in view, different angles and "
         "places, image corners included) ...")
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=(views + 5) * 4 * 10 if sim else None)
    if progress.timed_out:
        _say(f"stopped after {timeout:.0f} s with {len(collector.kept)} views")
    return list(collector.written), progress.ever_found


def camera_size(cfg: Any, sim: bool) -> tuple[int, int, str]:
    """(width, height) of the car's camera frames and the settings that set them."""
    if sim:
        return cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H, "SIM_CAMERA_W x SIM_CAMERA_H"
    return cfg.IMAGE_W, cfg.IMAGE_H, "IMAGE_W x IMAGE_H"


def _check_size(cal: Any, cfg: Any, sim: bool) -> None:
    """Refuse a calibration at another aspect ratio than the car's frames; warn at another size."""
    w0, h0 = cal.image_size
    w, h, settings = camera_size(cfg, sim)
    if (w0, h0) == (w, h):
        return
    if abs(w / h - w0 / h0) > 0.01:
        raise UserError(f"the images are {w0}x{h0} but the car's camera delivers {w}x{h} ({settings}), another aspect "
                        "ratio: the calibration would not fit its frames; take the photos with the car's camera "
                        "(or use --live), or correct the settings")
    _say(f"  note: the images are {w0}x{h0}, the car's camera delivers {w}x{h} ({settings}): the calibration is "
         "scaled to it, which is right only for photos taken with the car's own camera at its full field of view")


def _oserror_text(exc: OSError) -> str:
    return f"{exc.filename}: {exc.strerror or exc}" if exc.filename else str(exc)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Calibrate and save; print the figures a user checks."""
    try:
        return _calibrate(args)
    except OSError as exc:  # a folder or file the calibration writes: one line naming it
        raise UserError(_oserror_text(exc)) from exc


def _calibrate(args: argparse.Namespace) -> int:
    import numpy as np

    from parts.vision.calibration import (
        MIN_VIEWS,
        CalibrationError,
        calibrate_files,
        image_files,
        read_rgb,
        unreadable_hint,
        write_rgb,
    )
    from parts.vision.undistort import Undistort

    cfg = load_for_command(args)
    board = _board(args, cfg)
    model = args.model or cfg.CAMERA_CALIB_MODEL
    if args.views < MIN_VIEWS:
        raise UserError(f"--views {args.views}: collect at least {MIN_VIEWS} (better 10 or more)")
    if args.live and not args.timeout > 0:
        raise UserError(f"--timeout {args.timeout:g}: give the seconds to collect views, more than 0 (default 300)")
    out = Path(args.out) if args.out else cfg.path("CAMERA_CALIBRATION_PATH")
    try:
        if args.images:
            folder = Path(args.images)
            files = image_files(folder)
            # the annotated copies go to the car folder: the user's photo folder is left as it was
            annotate: Path | None = Path(cfg.CAR_PATH) / "calibration_corners"
        else:
            root = Path(args.views_dir) if args.views_dir else Path(cfg.CAR_PATH) / "calibration_views"
            folder = root if args.views_dir else run_folder(root)
            annotate = None  # the collector wrote corners_*.png next to the views
            files, seen = collect_live(cfg, board, folder, args.views, args.timeout, sim=args.sim, web=args.web)
            if len(files) < MIN_VIEWS:
                if not seen:
                    raise UserError(f"no chessboard was seen: {board_hint(board)}")
                raise UserError(f"only {len(files)} chessboard views were collected: hold the whole board in view, at "
                                "different angles, and try again (or use --images)")
        result = calibrate_files(files, board, model=model, annotate_to=annotate, source=str(folder))
    except CalibrationError as exc:
        raise UserError(f"{exc}") from exc
    cal = result.calibration
    _check_size(cal, cfg, args.sim)
    cal.save(out)
    k, d = cal.camera_matrix, cal.dist_coeffs
    worst = sorted(zip(cal.view_errors, cal.views, strict=True), reverse=True)[:3]
    _say(f"calibrated from {len(cal.views)} views of {cal.image_size[0]}x{cal.image_size[1]} "
         f"({len(result.rejected)} without the whole board: {', '.join(result.rejected[:5]) or 'none'})")
    if result.duplicates:
        _say(f"  left out, near-duplicates of an earlier view: {', '.join(result.duplicates)}")
    if result.unreadable:
        _say(f"  left out, unreadable: {', '.join(result.unreadable)}{unreadable_hint(result.unreadable)}")
    if cal.dropped_views:
        _say(f"  left out, corners found wrongly: {', '.join(cal.dropped_views)} (see the corners_*.png pictures)")
    _say(f"  reprojection error: RMS {cal.rms:.3f} px; worst views " +
         ", ".join(f"{name} {err:.3f}" for err, name in worst))
    _say(f"  fx {k[0, 0]:.2f}  fy {k[1, 1]:.2f}  cx {k[0, 2]:.2f}  cy {k[1, 2]:.2f}  "
         f"(field of view {cal.fov_deg[0]:.1f} x {cal.fov_deg[1]:.1f} deg)")
    _say("  distortion (" + ", ".join(("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")[:d.size]) + "): "
         + ", ".join(f"{v:+.5f}" for v in d))
    if args.sim and cfg.SIM_CAMERA_DISTORTION:
        _say("  simulated lens:  " + ", ".join(f"{v:+.5f}" for v in cfg.SIM_CAMERA_DISTORTION))
    if cal.rms > 1.0:
        _say("  the error is large: check the board's corner counts and square size, and retake blurred views")
    if cal.uncertain:
        _say(f"  {cal.uncertain}")
    # a before/after picture of the first view, to see straight lines come out straight
    first = read_rgb(next(f for f in files if f.name == cal.views[0]))
    after = Undistort(cal, alpha=cfg.CAMERA_UNDISTORT_ALPHA).undistort(first)
    check = out.with_name(out.stem + "_check.png")
    write_rgb(check, np.hstack([first, np.zeros((first.shape[0], 4, 3), np.uint8), after]))
    where = f"; detected corners in {annotate}" if annotate is not None else f"; views and corners in {folder}"
    _say(f"wrote {out} and {check} (left: as taken, right: undistorted){where}")
    if not cfg.CAMERA_UNDISTORT:
        _say("to undistort every frame: CAMERA_UNDISTORT = True in myconfig.py")
    return 0
