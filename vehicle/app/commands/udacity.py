"""``vehicle udacity drive MODEL [IMAGE_FOLDER]``: what the behavioural-cloning ``drive.py model.h5``
did, with a model of ours.

Start the Udacity simulator, choose a track and Autonomous Mode, then run this command: the
simulator connects, the pilot steers every frame it sends, and the throttle comes from a speed
controller (drive.py's PI controller to a set speed, or ``1 - speed / limit`` of the Track Driver
AI's driver) or from the model. With IMAGE_FOLDER, every frame the pilot drove is saved there as a
tub (frames, the commands sent, the speed), like drive.py's image folder. Ctrl-C stops; the last
command sent is neutral.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any, ClassVar

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError

logger = logging.getLogger(__name__)

MS_PER_MPH = 0.44704
#: what the tub of IMAGE_FOLDER records (the driven frame, the commands sent, the simulator's state)
TUB_INPUTS = ["cam/image_array", "angle", "throttle", "pilot/angle", "pilot/throttle", "sim/speed",
              "sim/steering_deg", "user/mode"]
TUB_TYPES = ["image_array", "float", "float", "float", "float", "float", "float", "str"]


def register(subparsers: Any) -> None:
    """Add the ``udacity`` command and its ``drive`` subcommand."""
    udacity = subparsers.add_parser("udacity", help="drive the Udacity simulator with a trained pilot",
                                    description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = udacity.add_subparsers(dest="udacity_command", metavar="SUBCOMMAND", required=True)
    d = sub.add_parser("drive", help="drive the Udacity simulator with MODEL (drive.py MODEL [IMAGE_FOLDER])",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    d.add_argument("model", metavar="MODEL", help="trained model file (models/*.pt)")
    d.add_argument("image_folder", metavar="IMAGE_FOLDER", nargs="?",
                   help="save the driven frames here, as a tub (created if missing)")
    speed = d.add_mutually_exclusive_group()
    speed.add_argument("--set-speed", type=float, metavar="MPH", default=9.0,
                       help="PI speed controller to this speed, as drive.py (default 9 mph)")
    speed.add_argument("--speed-limit", type=float, metavar="MPH",
                       help="throttle = 1 - speed / limit instead (the Track Driver AI's rule, e.g. 20; "
                            "PILOT_SPEED_LIMIT_HEADROOM = 1.25 for its later 1 - speed / (limit * 1.25))")
    d.add_argument("--drive-py", action="store_true",
                       help="drive.py's own SimplePIController(0.1, 0.002) to --set-speed, in its units "
                            "(mph, integral per frame), as the udacity-bc recipe's document")
    speed.add_argument("--model-throttle", action="store_true", help="use the model's own throttle")
    d.add_argument("--jpeg-folder", metavar="DIR",
                   help="also save each driven frame as DIR/<UTC time>.jpg, the folder recreated, as drive.py's "
                        "image folder did (a folder holding other files is refused)")
    d.add_argument("--port", type=int, help="port the simulator connects to (default UDACITY_PORT, 4567)")
    d.add_argument("--host", help="interface to listen on (default UDACITY_HOST, 127.0.0.1)")
    d.add_argument("--echo", action="store_true",
                   help="print 'steering throttle speed_mph' for every frame, as drive.py did")
    d.add_argument("--max-loops", type=int, metavar="N", help="stop after N loops")
    add_car_options(d)
    d.set_defaults(func=cmd_drive)


class PilotDrives:
    """The drive mode of this command: the pilot drives while frames are fresh (``cam/ok``), else
    the commands are neutral (user mode, throttle 0); a frame is recorded once, when it is new."""

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/frame_id", "cam/ok")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/mode", "user/angle", "user/throttle", "recording")

    def __init__(self, record: bool) -> None:
        self.record = record
        self._last_frame = 0

    def run(self, frame_id: Any, cam_ok: Any) -> tuple[str, float, float, bool]:
        """Mode "local" on fresh frames; recording on the loops that see a new frame."""
        new = isinstance(frame_id, int) and frame_id != self._last_frame
        if new:
            self._last_frame = frame_id
        return ("local" if cam_ok else "user"), 0.0, 0.0, self.record and new and bool(cam_ok)


class Echo:
    """Prints ``steering throttle speed_mph`` once per new frame (drive.py's console output)."""

    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle", "sim/speed", "cam/frame_id")

    def __init__(self) -> None:
        self._last_frame = 0

    def run(self, angle: Any, throttle: Any, speed: Any, frame_id: Any) -> None:
        """Write one line for a new frame."""
        if isinstance(frame_id, int) and frame_id != self._last_frame and angle is not None:
            self._last_frame = frame_id
            mph = speed / MS_PER_MPH if isinstance(speed, int | float) else float("nan")
            sys.stdout.write(f"{angle:.4f} {throttle or 0.0:.4f} {mph:.4f}\n")
            sys.stdout.flush()


def speed_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The PILOT_SPEED_* settings the speed options stand for (limits in m/s)."""
    if args.drive_py and (args.model_throttle or args.speed_limit is not None):
        raise UserError("--drive-py is drive.py's PI controller to --set-speed: leave out "
                        "--speed-limit/--model-throttle")
    if args.model_throttle:
        return {"PILOT_SPEED_CONTROL": "off"}
    if args.speed_limit is not None:
        if not 0 < args.speed_limit <= 35:
            raise UserError(f"--speed-limit {args.speed_limit}: give a speed in mph in (0, 35] (the simulator "
                            "tops out at 30.2 mph)")
        return {"PILOT_SPEED_CONTROL": "limit", "PILOT_SPEED_LIMIT": args.speed_limit * MS_PER_MPH}
    if not 0 < args.set_speed <= 35:
        raise UserError(f"--set-speed {args.set_speed}: give a speed in mph in (0, 35]")
    return {"PILOT_SPEED_CONTROL": "drivepy" if args.drive_py else "pi",
            "PILOT_SPEED_LIMIT": args.set_speed * MS_PER_MPH}


def cmd_drive(args: argparse.Namespace) -> int:
    """Drive the Udacity simulator with a pilot until Ctrl-C (or --max-loops)."""
    from vehicle import Vehicle
    from vehicle.app import assembly, manage

    cfg = load_for_command(args)
    model = Path(args.model).expanduser()
    if not model.is_file():
        raise UserError(f"MODEL {args.model}: no such model file; train one with `vehicle train` "
                        "(Keras .h5 files cannot be loaded: import the recording and train here)")
    if args.max_loops is not None and args.max_loops < 1:
        raise UserError(f"--max-loops {args.max_loops}: give at least 1 loop")
    overrides: dict[str, Any] = {"SIM_TYPE": "udacity", **speed_settings(args)}
    if args.port is not None:
        overrides["UDACITY_PORT"] = args.port
    if args.host is not None:
        overrides["UDACITY_HOST"] = args.host
    cfg = cfg.replace(**overrides)
    V = Vehicle()
    assembly.add_simulator(V, cfg)  # the server the simulator connects to
    V.add(PilotDrives(record=args.image_folder is not None))  # the pilot drives while frames are fresh
    if args.jpeg_folder is not None:
        from parts.tub.image_folder import ImageFolderWriter, prepare_folder

        try:
            jpeg_folder = prepare_folder(Path(args.jpeg_folder).expanduser().resolve())
        except (ValueError, OSError) as exc:
            raise UserError(f"--jpeg-folder: {exc}") from exc
        V.add(ImageFolderWriter(jpeg_folder))
        logger.info("saving the driven frames as JPEG files in %s", jpeg_folder)
    assembly.add_pilot(V, cfg, model)
    assembly.add_drive_mode(V, cfg)
    assembly.add_speed_limit(V, cfg)
    assembly.add_obstacle_stop(V, cfg)
    if args.echo:
        V.add(Echo())
    if args.image_folder is not None:
        folder = Path(args.image_folder).expanduser().resolve()
        if folder.exists() and not folder.is_dir():
            raise UserError(f"IMAGE_FOLDER {folder} is a file: give a folder for the tub")
        tub_cfg = cfg.replace(DATA_PATH=str(folder), AUTO_CREATE_NEW_TUB=False)
        assembly.add_tub_writer(V, tub_cfg, inputs=list(TUB_INPUTS), types=list(TUB_TYPES))
        logger.info("recording the driven frames into %s", folder)
    else:
        logger.info("not recording this run (give IMAGE_FOLDER to save the driven frames)")
    assembly.add_simulator_commands(V)  # the answer for a frame leaves in the loop that saw it
    return manage.run(V, cfg, args.max_loops)
