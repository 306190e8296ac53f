"""``vehicle createcar``: make a car folder from a template (manage.py, myconfig.py, data/, models/, logs/)."""

from __future__ import annotations

import argparse
import logging
import os
import stat
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from vehicle.errors import UserError

logger = logging.getLogger(__name__)

CAR_DIRS = ("data", "models", "logs")
DEFAULT_TEMPLATE = "simulator"


def templates() -> list[str]:
    """Names of the shipped templates (folders of the ``templates`` package with a manage.py)."""
    root = resources.files("templates")
    return sorted(p.name for p in root.iterdir() if p.is_dir() and (p / "manage.py").is_file())


@dataclass
class CreateResult:
    """What createcar did, file by file."""

    path: Path
    written: list[str] = field(default_factory=list)
    kept: list[str] = field(default_factory=list)


def create_car(path: str | os.PathLike[str], template: str = DEFAULT_TEMPLATE,
               overwrite: bool = False) -> CreateResult:
    """Write a car folder from ``template``.

    ``manage.py`` is replaced only with ``overwrite``; ``myconfig.py`` is never replaced, because
    it holds the user's settings (calibration values among them).

    Raises:
        UserError: unknown template, or the path exists and is not a folder.
    """
    names = templates()
    if template not in names:
        raise UserError(f"unknown template {template!r}; choose one of: {', '.join(names)}")
    car = Path(path).expanduser()
    if car.exists() and not car.is_dir():
        raise UserError(f"{car} exists and is not a folder; choose another --path")
    car.mkdir(parents=True, exist_ok=True)
    result = CreateResult(car.resolve())
    for d in CAR_DIRS:
        (car / d).mkdir(exist_ok=True)
    source = resources.files("templates") / template
    for name, replaceable in (("manage.py", True), ("myconfig.py", False)):
        target = car / name
        if target.exists() and not (overwrite and replaceable):
            result.kept.append(name)
            continue
        target.write_text((source / name).read_text())
        result.written.append(name)
    manage = car / "manage.py"
    manage.chmod(manage.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    return result


def register(sub: argparse._SubParsersAction) -> None:
    """Add the createcar subcommand."""
    p = sub.add_parser("createcar", help="create a car folder (manage.py, myconfig.py, data/, models/)",
                       description="Create a car folder from a template. Existing files are kept "
                       "unless --overwrite; myconfig.py is never overwritten.",
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--path", default="~/mycar", help="folder of the new car")
    p.add_argument("--template", default=DEFAULT_TEMPLATE, choices=templates(), help="car template")
    p.add_argument("--overwrite", action="store_true", help="replace manage.py (never myconfig.py)")
    p.set_defaults(func=_createcar)


def _createcar(args: argparse.Namespace) -> int:
    result = create_car(args.path, args.template, args.overwrite)
    for name in result.written:
        print(f"wrote {result.path / name}")  # noqa: T201 - CLI output
    for name in result.kept:
        why = "never overwritten" if name == "myconfig.py" else "exists; use --overwrite to replace"
        print(f"kept  {result.path / name} ({why})")  # noqa: T201
    print(f"car ready: cd {result.path} && python manage.py drive")  # noqa: T201
    return 0
