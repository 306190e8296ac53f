"""``vehicle createcar``: make a car folder from a template."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    """Add the createcar subcommand."""
    from vehicle.createcar import DEFAULT_TEMPLATE, templates

    p = sub.add_parser("createcar", help="create a car folder (manage.py, myconfig.py, data/, models/)",
                       description="Create a car folder from a template. Existing files are kept "
                       "unless --overwrite; myconfig.py is never overwritten.",
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--path", default="~/mycar", help="folder of the new car")
    p.add_argument("--template", default=DEFAULT_TEMPLATE, choices=templates(), help="car template")
    p.add_argument("--overwrite", action="store_true", help="replace manage.py (never myconfig.py)")
    p.set_defaults(func=_createcar)


def _createcar(args: argparse.Namespace) -> int:
    from vehicle.createcar import create_car

    result = create_car(args.path, args.template, args.overwrite)
    for name in result.written:
        print(f"wrote {result.path / name}")  # noqa: T201 - CLI output
    for name in result.kept:
        why = "never overwritten" if name == "myconfig.py" else "exists; use --overwrite to replace"
        print(f"kept  {result.path / name} ({why})")  # noqa: T201
    print(f"car ready: cd {result.path} && python manage.py drive")  # noqa: T201
    return 0
