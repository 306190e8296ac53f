"""Serve Socket.IO v2 / Engine.IO v3 clients that connect with ``EIO=4`` on python-socketio 5.

The Udacity simulator (and every Unity app built on "SocketIO for Unity" 1.0.1) opens
``ws://host:4567/socket.io/?EIO=4&transport=websocket`` but speaks Socket.IO v2: it never sends
the namespace CONNECT packet ``40`` and expects the server to join it to ``/`` by itself, as
python-socketio 4 did. python-engineio 4 accepts the handshake (the URL says 4), but
python-socketio 5 then drops every event of a socket that never joined ``/`` ("... is not
connected to namespace /"): the car never moves, and nothing says why.

:func:`legacy_server` returns a python-socketio ``AsyncServer`` whose subclass joins each new
Engine.IO connection to ``/`` at once (the Socket.IO v2 behaviour), and ignores a later ``40`` for
``/`` from a client that sends one anyway. It overrides private methods of python-socketio
(``_handle_eio_connect``, ``_handle_connect``; ``_handle_eio_message`` so that a packet that is
not JSON, or is nested too deeply for the parser, costs one log line, not a traceback each), so
:func:`check_support` verifies their signatures before a server is made and the ``web`` extra
pins the minor versions this was tested with (see ``SUPPORTED`` and pyproject.toml).
tests/parts/bridges/test_bridge_engineio3.py proves both sides: the stock server stays silent
against the faithful fake client, this one answers.

python-socketio is imported when a server is made, never at import time.
"""

from __future__ import annotations

import inspect
import logging
from importlib import metadata
from typing import Any

from parts.bridges.errors import BridgeError

logger = logging.getLogger(__name__)

#: distribution -> (lowest, highest) (major, minor) this layer was tested with; keep in step with
#: the pins of the ``web`` extra in pyproject.toml
SUPPORTED: dict[str, tuple[tuple[int, int], tuple[int, int]]] = {
    "python-socketio": ((5, 11), (5, 18)),
    "python-engineio": ((4, 9), (4, 15)),
}
#: the private methods overridden below and the parameters they must have
_PRIVATE_API: dict[str, tuple[str, ...]] = {
    "_handle_eio_connect": ("self", "eio_sid", "environ"),
    "_handle_connect": ("self", "eio_sid", "namespace", "data"),
    "_handle_eio_message": ("self", "eio_sid", "data"),
}
#: what else parts.bridges.udacity_sim calls below python-socketio's documented surface: (module,
#: class, method) -> parameters. It closes a simulator's websocket through the Engine.IO server
#: (a Socket.IO v2 client ignores the namespace DISCONNECT).
_INTERNAL_API: dict[tuple[str, str, str], tuple[str, ...]] = {
    ("socketio", "AsyncManager", "eio_sid_from_sid"): ("self", "sid", "namespace"),
    ("engineio", "AsyncServer", "disconnect"): ("self", "sid"),
}
INSTALL_HINT = "pip install 'vehicle-rc[web]' (python-socketio>=5.11,<5.19 and python-engineio>=4.9,<4.16)"

_server_class: type | None = None
_warned_untested = False


def _version(dist: str) -> tuple[int, int] | None:
    try:
        text = metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None
    parts = text.split(".")
    try:
        return int(parts[0]), int(parts[1])
    except (IndexError, ValueError):
        return None


def _installed(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "(version unknown)"


def check_support() -> None:
    """Raise :class:`BridgeError` unless python-socketio has the internals this layer overrides.

    A version outside :data:`SUPPORTED` whose internals still match is used with one warning.
    """
    global _warned_untested
    try:
        import aiohttp.web  # the server's HTTP side: a missing one fails here, not in start()
        import engineio
        import socketio
    except ImportError as exc:
        raise BridgeError(f"the Udacity simulator bridge needs python-socketio and aiohttp ({exc.name or exc} is "
                          f"missing): {INSTALL_HINT}") from None
    if not hasattr(aiohttp.web.BaseRunner, "addresses"):  # how the bridge learns the port it got for port 0
        raise BridgeError(f"aiohttp {_installed('aiohttp')} has no BaseRunner.addresses: {INSTALL_HINT}")
    modules = {"socketio": socketio, "engineio": engineio}
    wanted = {("socketio", "AsyncServer", name): params for name, params in _PRIVATE_API.items()} | _INTERNAL_API
    for (module, cls, name), params in wanted.items():
        method = getattr(getattr(modules[module], cls, None), name, None)
        found = tuple(inspect.signature(method).parameters) if callable(method) else None
        if found != params:
            dist = f"python-{module}"
            raise BridgeError(
                f"{dist} {_installed(dist)} changed {cls}.{name} (parameters {found}, expected {params}), "
                f"which the Udacity bridge relies on: {INSTALL_HINT}")
    untested = []
    for dist, (low, high) in SUPPORTED.items():
        version = _version(dist)
        if version is None or not low <= version <= high:
            untested.append(f"{dist} {'.'.join(map(str, version)) if version else 'unknown'}")
    if untested and not _warned_untested:
        _warned_untested = True
        logger.warning("Udacity bridge: %s not tested with this compatibility layer (tested: %s); "
                       "if the simulator connects but the car does not move: %s", ", ".join(untested),
                       ", ".join(f"{d} {lo[0]}.{lo[1]}-{hi[0]}.{hi[1]}" for d, (lo, hi) in SUPPORTED.items()),
                       INSTALL_HINT)


def legacy_server_class() -> type:
    """The ``socketio.AsyncServer`` subclass that joins new connections to ``/`` implicitly."""
    global _server_class
    if _server_class is not None:
        return _server_class
    check_support()
    import socketio

    class LegacyAutoConnectServer(socketio.AsyncServer):  # type: ignore[misc]  # untyped base
        """AsyncServer that treats every Engine.IO connection as joined to ``/`` (Socket.IO v2)."""

        async def _handle_eio_connect(self, eio_sid: str, environ: dict[str, Any]) -> Any:
            result = await super()._handle_eio_connect(eio_sid, environ)
            # Socket.IO v2 servers joined '/' here; v2 clients never send the CONNECT packet.
            await super()._handle_connect(eio_sid, "/", None)
            return result

        async def _handle_connect(self, eio_sid: str, namespace: str | None, data: Any) -> Any:
            if (namespace or "/") == "/":
                sid = self.manager.sid_from_eio_sid(eio_sid, "/")
                if sid is not None and self.manager.is_connected(sid, "/"):
                    return None  # joined implicitly already; a v3+ client's own '40' changes nothing
            return await super()._handle_connect(eio_sid, namespace, data)

        async def _handle_eio_message(self, eio_sid: str, data: Any) -> Any:
            try:
                return await super()._handle_eio_message(eio_sid, data)
            except (ValueError, RecursionError) as exc:  # json.loads of the packet: the peer's junk
                level = logging.DEBUG if getattr(self, "_junk_reported", False) else logging.WARNING
                self._junk_reported = True
                logger.log(level, "Socket.IO: skipped an unreadable packet (%s): %.60r", type(exc).__name__,
                           data if isinstance(data, str) else type(data).__name__)
                return None

    _server_class = LegacyAutoConnectServer
    return _server_class


def report_unreadable_frames(sio: Any, report: Any) -> bool:
    """Have ``report(why)`` called when a peer's websocket frame cannot be read (over
    ``max_http_buffer_size``, a protocol error): python-engineio closes the connection then without
    a word. Wraps the aiohttp driver's websocket (a private part of python-engineio, checked here:
    False and nothing done when it changed)."""
    drivers = getattr(getattr(sio, "eio", None), "_async", None)
    base = drivers.get("websocket") if isinstance(drivers, dict) else None
    if base is None or not inspect.iscoroutinefunction(getattr(base, "wait", None)):
        return False
    limit = getattr(sio.eio, "max_http_buffer_size", None)

    class ReportingWebSocket(base):  # type: ignore[misc, valid-type]  # untyped base
        async def wait(self) -> Any:
            msg = await self._sock.receive()
            if not isinstance(msg.data, bytes | str):
                code = getattr(msg.data, "code", None)
                too_big = code == 1009 or "too big" in str(msg.data).lower()
                if too_big:
                    report(f"a message was too large (over {limit} bytes)")
                elif msg.data is not None:
                    report(f"an unreadable websocket frame ({type(msg.data).__name__})")
                raise OSError()
            return msg.data

    sio.eio._async = dict(drivers, websocket=ReportingWebSocket)
    return True


def legacy_server(**kwargs: Any) -> Any:
    """A python-socketio ``AsyncServer`` (same keyword arguments) that serves Socket.IO v2 clients.

    Raises:
        BridgeError: python-socketio is missing or its internals changed (the message says what to
            install).
    """
    return legacy_server_class()(**kwargs)
