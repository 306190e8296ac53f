"""``vehicle car``: the laptop and the car: pull tubs, push pilots, switch the pilot, watch.

    vehicle car status URL [--json]           mode, records, loop rate, battery, pilot
    vehicle car tubs URL                      the car's tubs and what is new for this laptop
    vehicle car pull URL [--into data] [--tub NAME ...]
                                              copy the records this laptop lacks (resumable)
    vehicle car push URL MODEL [--name N] [--use]
                                              send a model file (and switch the pilot to it)
    vehicle car use URL NAME                  switch the pilot to a model on the car
    vehicle car discover                      cars announcing themselves on the LAN (zeroconf)

URL is what the car printed at start, token included: http://192.168.1.20:8887/?token=...
(or give the token with --token, or in VEHICLE_CAR_TOKEN). A switch puts a car that a pilot
drives in user mode first; its page says so. See docs/laptop-and-car.md.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from vehicle.errors import UserError

#: the environment variable a script may give the token in (kept out of the process list)
TOKEN_ENV = "VEHICLE_CAR_TOKEN"


def _out(text: str) -> None:
    print(text)  # noqa: T201 - the command's own output


def register(subparsers: Any) -> None:
    """Add the ``car`` command and its subcommands."""
    parser = subparsers.add_parser("car", help="pull tubs from a car, push pilots to it, watch it",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="car_command", metavar="SUBCOMMAND", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("url", help="the URL the car printed (http://HOST:PORT/?token=...)")
    common.add_argument("--token", help=f"the car's pairing token, if not in the URL (or {TOKEN_ENV})")

    p = sub.add_parser("status", parents=[common], help="the car's mode, records, loop rate, battery and pilot")
    p.add_argument("--json", action="store_true", help="print the status as JSON")
    p.set_defaults(func=_cmd_status)

    p = sub.add_parser("tubs", parents=[common], help="the car's tubs and how many records this laptop lacks")
    p.add_argument("--into", default="data", help="the laptop folder pulls go to")
    p.set_defaults(func=_cmd_tubs)

    p = sub.add_parser("pull", parents=[common], help="copy the car's new records (resumable, verified)")
    p.add_argument("--into", default="data", help="the laptop folder of tubs (each car tub T goes to CAR_T)")
    p.add_argument("--tub", action="append", metavar="NAME", help="only this car tub (repeatable)")
    p.set_defaults(func=_cmd_pull)

    p = sub.add_parser("push", parents=[common], help="send a model file to the car (checked there)")
    p.add_argument("model", help="the model file (or the name of one in ./models)")
    p.add_argument("--name", help="its file name on the car (default: the file's name)")
    p.add_argument("--use", action="store_true", help="then switch the car's pilot to it")
    p.set_defaults(func=_cmd_push)

    p = sub.add_parser("use", parents=[common], help="switch the car's pilot to one of its model files")
    p.add_argument("name", help="the model file on the car, e.g. pilot_26-12-05_1.pt")
    p.set_defaults(func=_cmd_use)

    p = sub.add_parser("discover", help="cars announcing themselves on the local network (zeroconf)")
    p.add_argument("--timeout", type=float, default=2.0, help="seconds to listen")
    p.set_defaults(func=_cmd_discover)


def _client(args: argparse.Namespace) -> Any:
    from vehicle.app.carlink.client import CarClient, parse_address

    return CarClient(parse_address(args.url, args.token or os.environ.get(TOKEN_ENV)))


def format_status(s: dict[str, Any]) -> str:
    """One line per fact of a car's status (what ``vehicle car status`` prints)."""
    rate = s.get("loop_rate_hz")
    lines = [f"car       {s.get('name')}",
             f"mode      {s.get('mode')}" + (" (emergency stop latched)" if s.get("estop") else ""),
             f"records   {s.get('records') if s.get('records') is not None else '-'}"
             + (" (recording)" if s.get("recording") else ""),
             f"loop      {rate:.1f} Hz, {s.get('loop_overruns') or 0} overruns" if isinstance(rate, int | float)
             else "loop      -",
             f"battery   {s['battery_v']:.2f} V" if isinstance(s.get("battery_v"), int | float) else "battery   -",
             f"pilot     {s.get('pilot') or '-'}" + (f" (last switch failed: {s['pilot_error']})"
                                                    if s.get("pilot_error") else "")]
    if s.get("notice"):
        lines.append(f"notice    {s['notice']}")
    return "\n".join(lines)


def _cmd_status(args: argparse.Namespace) -> int:
    status = _client(args).status()
    _out(json.dumps(status, indent=2) if args.json else format_status(status))
    return 0


def _cmd_tubs(args: argparse.Namespace) -> int:
    from vehicle.app.carlink.pull import plan

    client = _client(args)
    car = str(client.status().get("name"))
    rows = [("TUB", "RECORDS", "MB", "NEW FOR THIS LAPTOP", "LAPTOP FOLDER")]
    for p in plan(client, Path(args.into), car):
        rows.append((p.name, str(p.records), f"{p.bytes / 1e6:.1f}", str(p.new), str(p.target)))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    _out("\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows))
    return 0


def _cmd_pull(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from vehicle.app.carlink.pull import pull_all

    client = _client(args)
    bar = tqdm(desc="pull", unit="rec", disable=not sys.stderr.isatty())

    def progress(p: dict[str, Any]) -> None:
        bar.total = p["total"]
        bar.set_postfix_str(p["tub"], refresh=False)
        bar.update(p["done"] - bar.n)

    try:
        reports = pull_all(client, Path(args.into), args.tub, progress)
    finally:
        bar.close()
    if not reports:
        _out("nothing new on the car")
    for r in reports:
        skipped = ", ".join(f"{n} {why}" for why, n in r.skipped.items())
        _out(f"{r.tub}: {r.received} records pulled" + (f" ({skipped})" if skipped else "")
             + (" (new tub)" if r.created else ""))
    return 0


def _model_file(text: str) -> Path:
    path = Path(text)
    if path.is_file():
        return path
    inside = Path("models") / (text if text.endswith(".pt") else f"{text}.pt")
    if inside.is_file():
        return inside
    raise UserError(f"no model file {text!r} (nor {inside}): give the path of a .pt file")


def _cmd_push(args: argparse.Namespace) -> int:
    client = _client(args)
    path = _model_file(args.model)
    answer = client.push(path, args.name)
    name = answer.get("model", args.name or path.name)
    _out(f"{name}: on the car ({answer.get('bytes', 0) / 1e6:.1f} MB)" + ("" if answer.get("new") else
                                                                           ", the same file was there already"))
    if args.use:
        return _switch(client, name)
    return 0


def _cmd_use(args: argparse.Namespace) -> int:
    return _switch(_client(args), args.name)


def _switch(client: Any, name: str) -> int:
    started = time.monotonic()
    answer = client.use(name)
    if not answer.get("switched"):
        _out(f"the car already drives {name}")
    else:
        _out(f"the car's pilot is now {name} (loaded in {time.monotonic() - started:.1f} s); the car is in user "
             "mode: choose a pilot mode on its page to let it drive")
    return 0


def _cmd_discover(args: argparse.Namespace) -> int:
    from vehicle.app.carlink.discovery import discover

    cars = discover(args.timeout)
    if not cars:
        _out("no car announced itself (zeroconf blocked on this network, or cars with WEB_HOST on loopback): "
             "give the car's address instead")
    for car in cars:
        _out(f"{car['name']}  {car['url']}")
    return 0
