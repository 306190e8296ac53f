"""``vehicle lanes ...``: tune the lane extraction of the two-stream ``lanes`` pilot (thesis ch. 7).

    vehicle lanes preview --tub data/tub_1_24-05-01      # raw | bird's-eye | lanes, 6 frames of a tub
    vehicle lanes preview --images photos/ --png p.png   # frames from a folder of images
    vehicle lanes preview --sim --tracks 1,2             # frames from the simulator
    vehicle lanes points --sim                           # LANE_* settings for the simulated camera

The preview outlines the region of interest (LANE_SOURCE_POINTS) on each raw frame: on a straight
road its sides should run along the lane lines, so that they come out parallel in the bird's-eye
view; then tune LANE_S_THRESHOLD / LANE_COLOR_MASK until the lane image shows the lines and
little else.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError


def register(subparsers: Any) -> None:
    """Add the ``lanes`` command and its subcommands."""
    lanes = subparsers.add_parser("lanes", help="lane extraction: preview and points for the lanes pilot",
                                  description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = lanes.add_subparsers(dest="lanes_command", metavar="SUBCOMMAND", required=True)
    pre = sub.add_parser("preview", help="PNG strip of raw / bird's-eye / lane frames to tune the settings",
                         formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    source = pre.add_mutually_exclusive_group(required=True)
    source.add_argument("--tub", help="tub (or folder of tubs) to take frames from")
    source.add_argument("--images", metavar="DIR", help="folder of images to take frames from, as the car's camera "
                                                        "delivers them (undistorted here with CAMERA_UNDISTORT)")
    source.add_argument("--sim", action="store_true", help="render frames in the simulator (SIM_* settings)")
    pre.add_argument("--tracks", type=_seeds, help="--sim: track seeds (default SIM_TRACK_SEEDS)")
    pre.add_argument("--frames", type=int, default=6, help="frames in the strip, spread over the source")
    pre.add_argument("--png", default="lanes_preview.png", help="output PNG")
    pre.add_argument("--scale", type=int, default=2, help="pixel zoom of the strip")
    add_car_options(pre)
    pre.set_defaults(func=cmd_preview)
    pts = sub.add_parser("points", help="print LANE_* settings that give a true bird's-eye view of the "
                                        "simulated camera", formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    pts.add_argument("--sim", action="store_true", required=True, help="for the simulated camera (SIM_CAMERA_*)")
    pts.add_argument("--near", type=float, help="metres ahead of the rear axle (default: the nearest ground in view)")
    pts.add_argument("--far", type=float, default=1.2, help="metres ahead of the rear axle")
    pts.add_argument("--half-width", type=float, default=0.5, help="metres to each side")
    add_car_options(pts)
    pts.set_defaults(func=cmd_points)


def _seeds(text: str) -> list[int]:
    from vehicle.app.commands.sim import _seeds as parse

    return parse(text)


def _say(text: str) -> None:
    print(text, flush=True)  # noqa: T201 - the command's own output


def _spread(n_total: int, n: int) -> list[int]:
    return sorted({int(round(i)) for i in np.linspace(0, n_total - 1, min(n, n_total))})


def _frames(args: argparse.Namespace, cfg: Any) -> list[np.ndarray]:
    """The frames to preview, as the pilot sees them: a tub's as recorded (the car undistorted
    them already when it does), images and simulator frames undistorted with CAMERA_UNDISTORT."""
    raw = _source_frames(args, cfg)
    if args.tub:
        return raw
    from vehicle.app.assembly.camera import make_undistort

    size = (raw[0].shape[1], raw[0].shape[0])
    settings = "SIM_CAMERA_W x SIM_CAMERA_H" if args.sim else f"the images' size, {size[0]}x{size[1]}"
    undistort = make_undistort(cfg, size, settings)
    if undistort is None:
        return raw
    _say(f"undistorting the frames as the car does (CAMERA_UNDISTORT, {cfg.path('CAMERA_CALIBRATION_PATH')})")
    try:
        return [undistort.undistort(f) for f in raw]
    except ValueError as exc:  # an image of another aspect ratio than the first
        raise UserError(f"--images {args.images}: {exc}") from exc


def _source_frames(args: argparse.Namespace, cfg: Any) -> list[np.ndarray]:
    if args.tub:
        from parts.tub.reader import load_records

        if not Path(args.tub).exists():
            raise UserError(f"--tub {args.tub}: no such tub or folder")
        records = list(load_records([args.tub]))
        if not records:
            raise UserError(f"--tub {args.tub}: no records")
        return [records[i].image("cam/image_array") for i in _spread(len(records), args.frames)]
    if args.images:
        from parts.vision.calibration import CalibrationError, image_files, read_rgb

        if not Path(args.images).is_dir():
            raise UserError(f"--images {args.images}: no such folder; give a folder of frames (.png, .jpg)")
        try:
            files = image_files(args.images)
            if not files:
                raise UserError(f"--images {args.images}: no image files there")
            return [read_rgb(files[i]) for i in _spread(len(files), args.frames)]
        except CalibrationError as exc:
            raise UserError(str(exc)) from exc
    from parts.sim.simulator import SimCar

    seeds = args.tracks or list(cfg.SIM_TRACK_SEEDS)
    frames = []
    for k in range(args.frames):
        sim = SimCar.from_config(cfg, seeds=[seeds[k % len(seeds)]])
        lap = sim.track.length
        x, y, h = sim.track.pose_at(lap * (k // len(seeds) + 0.5) / max(1, args.frames // len(seeds) + 1),
                                    sim.start_offset)
        sim.car.place(x, y, h)
        frames.append(sim.render())
    return frames


def cmd_preview(args: argparse.Namespace) -> int:
    """Write the preview strip and say how much of each lane image is lane."""
    from parts.vision.calibration import write_rgb
    from parts.vision.lanes import LaneExtractor, LaneSettings, preview_strip

    cfg = load_for_command(args)
    if args.frames < 1 or args.scale < 1:
        raise UserError("--frames and --scale must be at least 1")
    try:
        extractor = LaneExtractor(LaneSettings.from_config(cfg))
    except ValueError as exc:
        raise UserError(f"{exc} (check the LANE_* settings in myconfig.py)") from exc
    frames = _frames(args, cfg)
    strip = preview_strip(frames, extractor, scale=args.scale)
    out = Path(args.png)
    try:
        write_rgb(out, strip)
    except OSError as exc:
        raise UserError(f"--png {out}: {exc.strerror or exc}") from exc
    shares = [float((extractor.extract(f) > 0).mean()) for f in frames]
    s = extractor.settings
    _say(f"wrote {out}: {len(frames)} frames of {frames[0].shape[1]}x{frames[0].shape[0]} "
         f"(raw + region | bird's-eye | lanes)")
    _say(f"  S threshold {s.s_threshold}, colour mask {s.color_mask}; lane pixels per frame: "
         + ", ".join(f"{100 * v:.1f} %" for v in shares))
    if max(shares) > 0.4:
        _say("  much of the image counts as lane: raise LANE_S_THRESHOLD's low value or use LANE_COLOR_MASK")
    elif max(shares) < 0.005:
        _say("  almost nothing counts as lane: lower LANE_S_THRESHOLD, or LANE_COLOR_MASK = 'white' for white tape")
    return 0


def cmd_points(args: argparse.Namespace) -> int:
    """Print the myconfig.py lines for the simulated camera."""
    from parts.sim.camera import camera_from_config, lane_region_points
    from vehicle.app.assembly.camera import make_undistort

    cfg = load_for_command(args)
    try:
        camera = camera_from_config(cfg)
    except ValueError as exc:
        raise UserError(f"{exc} (check the SIM_CAMERA_* settings)") from exc
    # the points are for the frames the pilot sees: undistorted with CAMERA_UNDISTORT
    undistort = make_undistort(cfg, (camera.width, camera.height), "SIM_CAMERA_W x SIM_CAMERA_H")
    note = ""
    intrinsics = None
    if undistort is not None:
        intrinsics = undistort.output_camera_matrix(camera.width, camera.height)
        note = f"; for the frames undistorted with {cfg.path('CAMERA_CALIBRATION_PATH')} (CAMERA_UNDISTORT)"
    elif camera.distortion is not None:
        # a bent image has no true bird's-eye view: the lens's pinhole is the nearest
        intrinsics = camera.intrinsics
        note = ("; SIM_CAMERA_DISTORTION bends straight lines and CAMERA_UNDISTORT is off, so the view is only "
                "near bird's-eye (calibrate and set CAMERA_UNDISTORT = True for a true one)")
    try:
        points = lane_region_points(camera, near=args.near, far=args.far, half_width=args.half_width,
                                    intrinsics=intrinsics)
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    _say(f"# lane extraction for the simulated {cfg.SIM_CAMERA_W}x{cfg.SIM_CAMERA_H} camera "
         f"(ground {args.far} m ahead, ±{args.half_width} m{note}): paste into myconfig.py")
    for name, value in points.items():
        text = [tuple(p) for p in value] if name != "LANE_POINTS_SIZE" else tuple(value)
        _say(f"{name} = {text!r}")
    return 0
