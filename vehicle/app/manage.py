"""What a car's manage.py uses: its command line, config loading and how a drive ends.

A ``manage.py`` stays short and editable: it declares its commands with :func:`command_parser`
and :func:`add_command`, builds the vehicle with ``vehicle.app.assembly`` helpers, and hands control
to :func:`main`, which loads the config, runs the command and turns every way of stopping into an
exit code with a message.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from vehicle.app.cli import ArgumentParser, RawHelpFormatter, configure_logging, stop_code
from vehicle.config import Config, load_config
from vehicle.errors import PartError, UserError, VehicleError, VehicleStopped
from vehicle.keys import MODES, Mode

logger = logging.getLogger(__name__)

Command = Callable[[Config, argparse.Namespace], int | None]


def command_parser(doc: str | None) -> argparse.ArgumentParser:
    """The manage.py parser: ``--myconfig``, ``-v`` and a subcommand slot."""
    parser = ArgumentParser(description=doc, formatter_class=RawHelpFormatter)
    parser.add_argument("--myconfig", default=None,
                        help="override file to load instead of myconfig.py (relative to the car folder)")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv: debug)")
    parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    return parser


def add_command(parser: argparse.ArgumentParser, name: str, func: Command, help: str) -> argparse.ArgumentParser:
    """Add a subcommand that runs ``func(cfg, args)``; returns its parser for more arguments."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    p = sub.add_parser(name, help=help, description=help)
    p.add_argument("--myconfig", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    p.set_defaults(func=func)
    return p


def add_train_command(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add ``train``: the options of ``vehicle train`` on this car's tubs (default ``data/``)."""
    from vehicle.app.commands.train import add_train_arguments, train_car

    p = add_command(parser, "train", train_car, "train a pilot from this car's tubs")
    add_train_arguments(p)
    return p


def add_console_command(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add ``console``: the trainer console of this car in the browser (``vehicle console``)."""
    from vehicle.app.commands.console import add_console_arguments, serve

    p = add_command(parser, "console", serve, "the trainer console in the browser: datasets, training, models")
    add_console_arguments(p)
    return p


def main(parser: argparse.ArgumentParser, car_path: str | Path, argv: Sequence[str] | None = None) -> int:
    """Parse ``argv``, load the car's config and run the chosen command; returns the exit code."""
    args = parser.parse_args(argv)
    configure_logging(args.verbose)
    try:
        cfg = load_config(args.myconfig, car_path=car_path)
        if getattr(args, "js", False):  # DonkeyCar's `manage.py drive --js`: the gamepad, this run
            cfg = cfg.replace(USE_JOYSTICK_AS_DEFAULT=True)
        return int(args.func(cfg, args) or 0)
    except VehicleError as exc:
        print(f"error: {exc}", file=sys.stderr)  # noqa: T201 - the CLI's own output
        return 2
    except (VehicleStopped, KeyboardInterrupt, PartError) as exc:  # a vehicle a command started
        return stop_code(exc, driving=args.command == "drive")  # train, console: no throttle


def add_mode_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--mode user|local_angle|local``: who drives from the first loop (DEFAULT_MODE for one drive)."""
    parser.add_argument("--mode", choices=MODES, help="who drives from the first loop: user (you), local_angle "
                        "(the pilot steers, you set the throttle) or local (the pilot drives; with --model); "
                        "default: DEFAULT_MODE")


def start_mode(cfg: Config, mode: str | None, model: str | None) -> Config:
    """``cfg`` with DEFAULT_MODE = ``mode`` (the ``--mode`` option) when one is given.

    Raises:
        UserError: a pilot mode without a model: nothing would steer.
    """
    if mode is None:
        return cfg
    if mode != Mode.USER and not model:
        raise UserError(f"--mode {mode} needs a pilot: add --model FILE (a models/*.pt file)")
    if mode != Mode.USER:
        logger.warning("--mode %s: the pilot %s from the first loop", mode,
                       "drives" if mode == Mode.LOCAL else "steers")
    return cfg.replace(DEFAULT_MODE=mode)


def int_list(text: str) -> list[int]:
    """Parse ``"1,2,3"`` (an argparse type) into ``[1, 2, 3]``."""
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers like 1,2,3, got {text!r}") from None


def positive_int(text: str) -> int:
    """Parse a count that must be at least 1 (an argparse type: ``--max-loops``, ``--record-records``)."""
    return _whole_number(text, 1)


def non_negative_int(text: str) -> int:
    """Parse a count that may be 0 (an argparse type: ``--lane-changes``)."""
    return _whole_number(text, 0)


def _whole_number(text: str, least: int) -> int:
    try:
        value = int(text)
    except ValueError:
        value = None
    if value is None or value < least:
        raise argparse.ArgumentTypeError(f"expected a whole number ≥ {least}, got {text!r}")
    return value


def _check_drive_logic(V: Any, cfg: Config) -> None:
    """A manage.py written before the speed limit and the obstacle stop were added by name (they
    came with ``add_drive_mode``) would drive without them: refuse, saying the two lines to add.

    Raises:
        UserError: the car has a drive mode and OBSTACLE_STOP is on, or the web page can set a
            speed limit, but the part that enforces it is missing.
    """
    from parts.drive.modes import DriveMode
    from parts.drive.obstacle import ObstacleStop
    from parts.drive.speed import SpeedLimit
    from vehicle.app.assembly.pilot import speed_key_of

    if not V.find(DriveMode):
        return
    missing = []
    if cfg.OBSTACLE_STOP and V.produces("lidar/dist_array") and not V.find(ObstacleStop):
        missing.append("assembly.add_obstacle_stop(V, cfg)")
    if V.produces("user/speed_limit") and V.produces(speed_key_of(V, cfg)) and not V.find(SpeedLimit):
        missing.insert(0, "assembly.add_speed_limit(V, cfg)")
    if missing:
        raise UserError(f"this manage.py adds the drive mode but not {' and '.join(missing)}: add "
                        f"{'them' if len(missing) > 1 else 'it'} right after assembly.add_drive_mode(V, cfg) "
                        "(see the templates' manage.py; they used to come with the drive mode)")


def run(V: Any, cfg: Config, max_loops: int | None = None) -> int:
    """Start the vehicle at DRIVE_LOOP_HZ and map how it stopped to an exit code.

    The vehicle has already put actuators to neutral and shut every part down when this returns.
    0: max loops reached or stopped by a part; 1: a part failed; 130: Ctrl-C; 128+N: signal N.
    """
    loops = max_loops if max_loops is not None else cfg.MAX_LOOPS
    _check_drive_logic(V, cfg)
    logger.info("starting at %d Hz%s\n%s", cfg.DRIVE_LOOP_HZ,
                f" for {loops} loops" if loops else " (Ctrl-C to stop)", V.describe())
    try:
        V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=loops)
    except (VehicleStopped, KeyboardInterrupt, PartError) as exc:
        return stop_code(exc)
    return 0
