"""``vehicle camera calibrate``: find the camera matrix and lens distortion from chessboard views.

    vehicle camera calibrate --images photos/          # photos of the printed board (the thesis's way)
    vehicle camera calibrate --live --views 15         # hold the board in front of the car's camera
    vehicle camera calibrate --live --web              # ... and watch the detected corners in a browser
    vehicle camera calibrate --sim                     # the simulator's camera (SIM_CAMERA_DISTORTION)

Print a chessboard (default 10 x 7 inner corners, CAMERA_CALIB_BOARD), photograph it from at least
ten angles covering the whole image, corners included. The result goes to the car folder
(CAMERA_CALIBRATION_PATH); set CAMERA_UNDISTORT = True to undistort every frame with it.
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from pathlib import Path
from typing import Any

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
                     help="where --live/--sim write the views (default calibration_views/ in the car)")
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


class _StopWhenDone:
    """Part: stop the vehicle once the collector has its views, or after ``timeout`` seconds."""

    def __init__(self, V: Any, collector: Any, timeout: float, clock: Any = time.monotonic) -> None:
        self.V, self.collector, self.timeout, self.clock = V, collector, timeout, clock
        self.started = clock()
        self.timed_out = False

    def run(self) -> None:
        if self.collector.done:
            self.V.stop()
        elif self.clock() - self.started > self.timeout:
            self.timed_out = True
            self.V.stop()


def collect_live(cfg: Any, board: Any, folder: Path, views: int, timeout: float, *, sim: bool, web: bool) -> int:
    """Run a vehicle (camera -> ChessboardCollector [-> web page]) until ``views`` views are kept;
    returns how many were kept."""
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
            raise UserError(f"simulated calibration: {exc} (SIM_CAMERA_* settings)") from exc
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
    stopper = _StopWhenDone(V, collector, math.inf if sim else timeout, clock=V.clock.now)
    V.add(stopper)
    _say(f"collecting {views} chessboard views into {folder} (the board whole in view, different angles and "
         "places, image corners included) ...")
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=(views + 5) * 4 * 10 if sim else None)
    if stopper.timed_out:
        _say(f"stopped after {timeout:.0f} s with {len(collector.kept)} views")
    return len(collector.kept)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Calibrate and save; print the figures a user checks."""
    import numpy as np

    from parts.vision.calibration import MIN_VIEWS, CalibrationError, calibrate_folder, read_rgb, write_rgb
    from parts.vision.undistort import Undistort

    cfg = load_for_command(args)
    board = _board(args, cfg)
    model = args.model or cfg.CAMERA_CALIB_MODEL
    if args.views < MIN_VIEWS:
        raise UserError(f"--views {args.views}: collect at least {MIN_VIEWS} (better 10 or more)")
    out = Path(args.out) if args.out else cfg.path("CAMERA_CALIBRATION_PATH")
    if args.images:
        folder = Path(args.images)
        annotate = folder / "corners"
    else:
        folder = Path(args.views_dir) if args.views_dir else Path(cfg.CAR_PATH) / "calibration_views"
        annotate = None  # the collector wrote corners_*.png next to the views
        kept = collect_live(cfg, board, folder, args.views, args.timeout, sim=args.sim, web=args.web)
        if kept < MIN_VIEWS:
            raise UserError(f"only {kept} chessboard views were collected: hold the whole board in view, at "
                            "different angles, and try again (or use --images)")
    try:
        result = calibrate_folder(folder, board, model=model, annotate_to=annotate)
    except CalibrationError as exc:
        raise UserError(f"{exc}") from exc
    cal = result.calibration
    cal.save(out)
    k, d = cal.camera_matrix, cal.dist_coeffs
    worst = sorted(zip(cal.view_errors, cal.views, strict=True), reverse=True)[:3]
    _say(f"calibrated from {len(cal.views)} views of {cal.image_size[0]}x{cal.image_size[1]} "
         f"({len(result.rejected)} without the whole board: {', '.join(result.rejected[:5]) or 'none'})")
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
    # a before/after picture of the first view, to see straight lines come out straight
    first = read_rgb(folder / cal.views[0])
    after = Undistort(cal, alpha=cfg.CAMERA_UNDISTORT_ALPHA).undistort(first)
    check = out.with_name(out.stem + "_check.png")
    write_rgb(check, np.hstack([first, np.zeros((first.shape[0], 4, 3), np.uint8), after]))
    _say(f"wrote {out} and {check} (left: as taken, right: undistorted)")
    if not cfg.CAMERA_UNDISTORT:
        _say("to undistort every frame: CAMERA_UNDISTORT = True in myconfig.py")
    return 0
