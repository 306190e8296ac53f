"""The one way a ``vehicle`` command finds the settings of the car it works on.

Every command that reads a car's settings takes ``--car DIR`` and ``--myconfig FILE`` (added by
:func:`add_car_options`) and calls :func:`load_for_command`, so the rules are the same everywhere:

- ``--car DIR`` names the car folder (default: the current folder); it must exist.
- ``--myconfig FILE`` selects another override file; it must exist. With ``--car`` a relative path
  is taken in the car folder; without, the file's own folder is the car folder (as
  ``manage.py --myconfig`` and DonkeyCar do).
- Without ``--myconfig``, ``<car>/myconfig.py`` is used when it exists, else the defaults (a
  command run outside any car folder works with the package defaults, ``CAR_PATH`` = the folder).
- An invalid override file is an error (one line: file, line, setting). A command that exists to
  repair a car's settings (``vehicle calibrate``) catches it and says it uses the defaults.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from vehicle.config import Config, load_config
from vehicle.errors import UserError


def add_car_options(parser: argparse.ArgumentParser, *, suppress: bool = False) -> None:
    """Add ``--car DIR`` and ``--myconfig FILE`` to ``parser``.

    With ``suppress`` the options get no default, so a parent parser and a subcommand can both
    declare them without the subcommand resetting a value given before it.
    """
    default = argparse.SUPPRESS if suppress else None
    parser.add_argument("--car", metavar="DIR", default=default,
                        help="car folder whose settings to use (default: the current folder)")
    parser.add_argument("--myconfig", metavar="FILE", default=default,
                        help="override file to use instead of <car>/myconfig.py")


def car_folder(args: argparse.Namespace) -> Path:
    """The car folder of ``args`` (``--car``, default the current folder), which must exist."""
    car = Path(getattr(args, "car", None) or ".").expanduser()
    if not car.is_dir():
        raise UserError(f"--car {car}: no such folder; pass the folder that holds the car's myconfig.py")
    return car.resolve()


def load_for_command(args: argparse.Namespace) -> Config:
    """The settings a command runs with, by the rules of this module.

    Args:
        args: parsed options with ``car`` and ``myconfig`` (either may be absent).

    Raises:
        UserError: ``--car`` or ``--myconfig`` does not exist.
        ConfigError: the override file is invalid.
    """
    myconfig = getattr(args, "myconfig", None)
    if myconfig and not getattr(args, "car", None):
        path = Path(myconfig).expanduser()
        if not path.is_file():
            raise UserError(f"--myconfig {myconfig}: no such file; pass an existing override file")
        return load_config(path.resolve().name, car_path=path.resolve().parent)
    car = car_folder(args)
    if myconfig and not (car / myconfig).is_file():
        raise UserError(f"--myconfig {myconfig}: no such file in {car}; pass an existing override file")
    if not myconfig and not (car / "myconfig.py").is_file():
        return Config.defaults(CAR_PATH=str(car))
    return load_config(myconfig, car_path=car)
