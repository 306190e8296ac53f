"""The ``vehicle`` command: one root command; each verb group is a module of vehicle.app.commands.

Every parser of the tree (and of a car's manage.py) is an :class:`ArgumentParser`: one help
style, and a misspelt option is named before anything else is checked.
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import logging
import sys
from collections.abc import Sequence
from typing import Any

from vehicle.errors import PartError, VehicleError, VehicleStopped

logger = logging.getLogger(__name__)

#: what ``vehicle --help`` opens with
DESCRIPTION = """Drive, record, train and evaluate pilots for small self-driving cars.

Start with `vehicle createcar --path ~/mycar` (then `python ~/mycar/manage.py drive`), or
`vehicle demo` to record, train and evaluate a pilot in the built-in simulator. `vehicle COMMAND
--help` tells more about each command."""


class _HelpText:
    """An option's default added once, where its help does not give it already; reStructuredText's
    ``double backticks`` (docstrings used as descriptions) left out."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if (action.option_strings and "default" not in text.lower() and action.default is not None
                and action.default is not False and action.default is not argparse.SUPPRESS):
            text += " (default: %(default)s)"
        return text

    def _format_text(self, text: str) -> str:
        return super()._format_text(text.replace("``", ""))  # type: ignore[misc]

    def _expand_help(self, action: argparse.Action) -> str:
        return super()._expand_help(action).replace("``", "")  # type: ignore[misc]


class HelpFormatter(_HelpText, argparse.HelpFormatter):
    """The help of every command: descriptions wrapped to the terminal."""


class RawHelpFormatter(_HelpText, argparse.RawDescriptionHelpFormatter):
    """The help of a command whose description is laid out by hand (a module docstring)."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser with :class:`HelpFormatter` and a check of the options first: a misspelt
    option is named (with the closest valid one) instead of a required argument's error or the
    root command's "unrecognized arguments"."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # one help style for every command; a description laid out by hand stays as written
        raw = issubclass(kwargs.get("formatter_class", HelpFormatter), argparse.RawDescriptionHelpFormatter)
        kwargs["formatter_class"] = RawHelpFormatter if raw else HelpFormatter
        super().__init__(*args, **kwargs)

    def parse_known_args(self, args: Sequence[str] | None = None, namespace: Any = None) -> Any:
        args = list(sys.argv[1:] if args is None else args)
        self._check_options(args)
        return super().parse_known_args(args, namespace)

    def _check_options(self, args: list[str]) -> None:
        known = [s for a in self._actions for s in a.option_strings]
        subcommands = {name for a in self._actions if isinstance(a, argparse._SubParsersAction) for name in a.choices}
        takes_value = False
        for token in args:
            if takes_value:  # an option's value, whatever it looks like (--comment "--fast")
                takes_value = False
                continue
            if token == "--" or token in subcommands:  # the rest belongs to the subcommand
                return
            if not token.startswith("--"):
                continue
            name = token.split("=", 1)[0]
            matches = [k for k in known if k == name] or \
                ([k for k in known if k.startswith(name)] if self.allow_abbrev else [])
            if len(matches) == 1:
                action = self._option_string_actions[matches[0]]
                takes_value = "=" not in token and action.nargs is None  # exactly one value follows
                continue
            close = difflib.get_close_matches(name, [k for k in known if k.startswith("--")], n=1)
            self.error(f"unknown option {name}" + (f": did you mean {close[0]}?" if close else
                                                  f" (see {self.prog} --help)"))


# Each module defines register(subparsers); handlers return an exit code.
COMMAND_MODULES: tuple[str, ...] = (
    "vehicle.app.commands.createcar",
    "vehicle.app.commands.models",
    "vehicle.app.commands.demo",
    "vehicle.app.commands.train",
    "vehicle.app.commands.calibrate",
    "vehicle.app.commands.drivetrain",
    "vehicle.app.commands.hw",
    "vehicle.app.commands.camera",
    "vehicle.app.commands.lanes",
    "vehicle.app.commands.createjs",
    "vehicle.app.commands.sim",
    "vehicle.app.commands.rl",
    "vehicle.app.commands.tub",
    "vehicle.app.commands.udacity",
    "vehicle.app.commands.console",
    "vehicle.app.commands.car",
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    parser = ArgumentParser(prog="vehicle", description=DESCRIPTION, formatter_class=RawHelpFormatter)
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
    # a command's own --debug (e.g. hw check) logs as -vv does, tracebacks included
    configure_logging(2 if getattr(args, "debug", False) else args.verbose)
    try:
        return int(args.func(args) or 0)
    except VehicleError as exc:
        print(f"error: {exc}", file=sys.stderr)  # noqa: T201 - the CLI's own output
        return 2
    except (VehicleStopped, KeyboardInterrupt, PartError) as exc:
        return stop_code(exc, driving=False)  # a drive (udacity drive) reports its own stop: manage.run


def stop_code(exc: VehicleStopped | KeyboardInterrupt | PartError, driving: bool = True) -> int:
    """Log how a vehicle stopped (it has put the actuators to neutral and shut its parts down)
    and return the exit code: 130 for Ctrl-C, 128+N for signal N, 1 for a failed part, 2 for a
    part that refused the user's input (its :class:`VehicleError` says how to fix it).

    ``driving``: whether the command drove a car. A Ctrl-C in a command that did not (training,
    an evaluation, the demo) is reported without the throttle, which it never had.
    """
    if isinstance(exc, PartError) and isinstance(exc.cause, VehicleError):
        logger.warning("vehicle stopped: throttle set to neutral")
        print(f"error: {exc.part_name}: {exc.cause}", file=sys.stderr)  # noqa: T201 - the CLI's own output
        return 2
    if isinstance(exc, VehicleStopped):
        logger.warning("vehicle stopped by %s: throttle set to neutral", exc.signal_name)
        return 128 + exc.signum
    if isinstance(exc, KeyboardInterrupt):
        logger.info("vehicle stopped by Ctrl-C: throttle set to neutral" if driving else "stopped by Ctrl-C")
        return 130
    logger.error("vehicle stopped because %s; throttle set to neutral", exc, exc_info=exc.__cause__)
    return 1


if __name__ == "__main__":
    sys.exit(main())
