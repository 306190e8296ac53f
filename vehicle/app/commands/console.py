"""``vehicle console``: the trainer console in the browser (datasets, training, models, leaderboard).

    vehicle console [--car DIR] [--port 8890] [--host 127.0.0.1] [--open]
    python manage.py console            # in a car folder

Serves http://localhost:8890/ (CONSOLE_PORT) on this machine only by default (CONSOLE_HOST); on a
network interface every browser needs the car's pairing token (WEB_TOKEN, else a random one per
start), which the printed URL carries. Ctrl-C stops it; a running training stops cleanly and
keeps its best model so far.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
from typing import Any

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def add_console_arguments(parser: argparse.ArgumentParser) -> None:
    """The options shared by ``vehicle console`` and ``manage.py console``."""
    parser.add_argument("--host", help="interface to listen on (default CONSOLE_HOST, 127.0.0.1: this machine only)")
    parser.add_argument("--port", type=int, help="TCP port (default CONSOLE_PORT, 8890; 0 = any free port)")
    parser.add_argument("--open", action="store_true", help="open the console in this machine's web browser")


def register(subparsers: Any) -> None:
    """Add ``vehicle console``."""
    parser = subparsers.add_parser("console", help="the trainer console in the browser: datasets, training, "
                                   "models, leaderboard", description=__doc__,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
    add_car_options(parser)
    add_console_arguments(parser)
    parser.set_defaults(func=_cmd_console)


def _cmd_console(args: argparse.Namespace) -> int:
    return serve(load_for_command(args), args)


def serve(cfg: Any, args: argparse.Namespace) -> int:
    """Run the console of the car ``cfg`` until Ctrl-C or SIGTERM; returns the exit code (130 after
    Ctrl-C, 143 after SIGTERM, as every command)."""
    from parts.web.pairing import is_loopback, page_url, resolve_token, terminal_qr
    from vehicle.app.console.server import ConsoleApp

    host = args.host if args.host is not None else cfg.CONSOLE_HOST
    port = args.port if args.port is not None else cfg.CONSOLE_PORT
    try:
        token = resolve_token(host, cfg.WEB_TOKEN)
        app = ConsoleApp(cfg, host=host, port=port, token=token, myconfig=getattr(args, "myconfig", None))
    except ValueError as exc:
        raise UserError(str(exc)) from exc

    stopped_by: list[int] = []  # the signal that stopped the console: its exit code is 128 + N

    def stop(signum: int) -> None:
        stopped_by.append(signum)
        app.stop()

    async def main() -> None:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, stop, sig)
        try:
            await app.start()
        except OSError as exc:
            raise UserError(str(exc.strerror or exc)) from exc
        url = page_url(host, app.port, token)
        if is_loopback(host):
            logger.info("trainer console of %s: open %s (Ctrl-C stops)", cfg.CAR_PATH, url)
        else:
            logger.warning("trainer console reachable from the network (%s): pair a browser by opening\n%s",
                           host, url)
            qr = terminal_qr(url)
            if qr:
                logger.warning("or scan:\n%s", qr)
        if getattr(args, "open", False):
            import webbrowser

            webbrowser.open(url.replace("0.0.0.0", "localhost"))
        await app.serve_until_stopped()
        logger.info("console stopped")

    asyncio.run(main())
    return 128 + stopped_by[0] if stopped_by else 0  # 130 for Ctrl-C, as every command
