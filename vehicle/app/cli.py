"""The ``vehicle`` command: one root command; each verb group is a module of vehicle.app.commands."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from vehicle.errors import PartError, VehicleError, VehicleStopped

logger = logging.getLogger(__name__)

# Each module defines register(subparsers); handlers return an exit code.
COMMAND_MODULES: tuple[str, ...] = (
    "vehicle.app.commands.createcar",
    "vehicle.app.commands.models",
    "vehicle.app.commands.demo",
    "vehicle.app.commands.train",
    "vehicle.app.commands.calibrate",
    "vehicle.app.commands.camera",
    "vehicle.app.commands.lanes",
    "vehicle.app.commands.createjs",
    "vehicle.app.commands.sim",
    "vehicle.app.commands.rl",
    "vehicle.app.commands.tub",
    "vehicle.app.commands.udacity",
    "vehicle.app.commands.console",
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    parser = argparse.ArgumentParser(prog="vehicle", description=__doc__,
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv: debug)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMAND_MODULES:
        importlib.import_module(module).register(sub)
    return parser


def configure_logging(verbosity: int) -> None:
    """Log to stderr; INFO by default, DEBUG with -vv."""
    level = logging.DEBUG if verbosity >= 2 else logging.INFO
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)-7s %(name)s: %(message)s",
                        datefmt="%H:%M:%S")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``vehicle`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    configure_logging(args.verbose)
    try:
        return int(args.func(args) or 0)
    except VehicleError as exc:
        print(f"error: {exc}", file=sys.stderr)  # noqa: T201 - the CLI's own output
        return 2
    except (VehicleStopped, KeyboardInterrupt, PartError) as exc:
        return stop_code(exc)


def stop_code(exc: VehicleStopped | KeyboardInterrupt | PartError) -> int:
    """Log how a vehicle stopped (it has put the actuators to neutral and shut its parts down)
    and return the exit code: 130 for Ctrl-C, 128+N for signal N, 1 for a failed part, 2 for a
    part that refused the user's input (its :class:`VehicleError` says how to fix it)."""
    if isinstance(exc, PartError) and isinstance(exc.cause, VehicleError):
        logger.warning("vehicle stopped: throttle set to neutral")
        print(f"error: {exc.part_name}: {exc.cause}", file=sys.stderr)  # noqa: T201 - the CLI's own output
        return 2
    if isinstance(exc, VehicleStopped):
        logger.warning("vehicle stopped by %s: throttle set to neutral", exc.signal_name)
        return 128 + exc.signum
    if isinstance(exc, KeyboardInterrupt):
        logger.info("vehicle stopped by Ctrl-C: throttle set to neutral")
        return 130
    logger.error("vehicle stopped because %s; throttle set to neutral", exc, exc_info=exc.__cause__)
    return 1


if __name__ == "__main__":
    sys.exit(main())
