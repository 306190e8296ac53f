"""The web controller's server: python-socketio on aiohttp, run in its own event loop.

Everything here runs in the web thread. It talks to the drive loop only through the lock-protected
:class:`~parts.web.state.ControlState` and :class:`LatestFrame`. python-socketio and aiohttp are
imported when the server starts, never at import time.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import os
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from parts.web import protocol
from parts.web.limits import HARD_LIMIT_BYTES, REFUSED_EVENT, BoundedLog, make_bounded_packet
from parts.web.pairing import FailureGuard, allowed_hosts, host_allowed, token_ok
from parts.web.pathview import PathSender, PathSlot
from parts.web.state import ControlState
from vehicle.errors import VehicleError

if TYPE_CHECKING:
    from parts.web.carlink import CarLink

logger = logging.getLogger(__name__)


class ListenError(VehicleError, OSError):
    """The web server cannot bind its address (port taken, address not on this machine);
    the message names the address and the setting to change."""


def listen_advice(exc: OSError, host: str, port: int, *, port_fix: str, host_fix: str) -> str:
    """Why a server cannot bind ``host:port`` (``exc`` from binding) and which setting to change,
    for a one-line error: ``port_fix`` when the port is the problem, ``host_fix`` for the address."""
    if exc.errno == errno.EADDRINUSE:
        return f"port {port} is in use by another program (or car); {port_fix}"
    if exc.errno == errno.EADDRNOTAVAIL:
        return f"{host} is not an address of this machine; {host_fix}"
    if exc.errno == errno.EACCES:
        return f"port {port} needs administrator rights; {port_fix}"
    reason = os.strerror(exc.errno).lower() if exc.errno else str(exc)
    return f"{reason}; {port_fix}"


STATIC_DIR = Path(__file__).with_name("static")
#: seconds the connections get to close at shutdown (a client that does not answer is cut off)
SHUTDOWN_S = 0.5
#: seconds a browser has to acknowledge a frame before the next one is sent anyway
FRAME_ACK_TIMEOUT = 2.0
_CONTENT_TYPES = {".html": "text/html", ".js": "text/javascript", ".css": "text/css",
                  ".png": "image/png", ".svg": "image/svg+xml", ".ico": "image/x-icon"}


class LatestFrame:
    """The newest camera frame, JPEG-encoded at most once per frame, shared by every viewer.

    The loop thread calls :meth:`put` (a copy, so a camera that reuses its buffer cannot tear the
    image); the server thread calls :meth:`jpeg`. Only the latest frame is kept: a viewer that is
    slow skips frames instead of queueing stale ones.
    """

    def __init__(self, quality: int = 80) -> None:
        if not 1 <= quality <= 100:
            raise ValueError(f"JPEG quality must be in [1, 100], got {quality!r}")
        self.quality = quality
        self._lock = threading.Lock()
        self._image: np.ndarray | None = None
        self._version = 0
        self._jpeg: bytes | None = None
        self._jpeg_version = -1

    @property
    def version(self) -> int:
        """Counter of frames put so far."""
        with self._lock:
            return self._version

    def put(self, image: np.ndarray) -> None:
        """Store a HxWx3 uint8 RGB (or HxW grey) frame."""
        if not (isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim in (2, 3)):
            raise TypeError("camera frame must be a HxWx3 uint8 RGB numpy array, got "
                            f"{type(image).__name__} {getattr(image, 'dtype', '')}"
                            f"{getattr(image, 'shape', '')}")
        with self._lock:
            self._image = image.copy()
            self._version += 1

    def jpeg(self) -> tuple[bytes | None, int]:
        """The latest frame as JPEG bytes and its version (None before the first frame)."""
        import cv2

        with self._lock:
            image, version = self._image, self._version
            if version == self._jpeg_version:
                return self._jpeg, version
        if image is None:
            return None, version
        bgr = cv2.cvtColor(image, cv2.COLOR_RGB2BGR) if image.ndim == 3 else image
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, self.quality])
        if not ok:
            raise RuntimeError(f"JPEG encoding failed for a frame of shape {image.shape}")
        data = buf.tobytes()
        with self._lock:
            if version >= self._jpeg_version:
                self._jpeg, self._jpeg_version = data, version
        return data, version


#: model files a pilot loads: the model file, and its ONNX and TorchScript exports
MODEL_SUFFIXES = (".pt", ".onnx", ".ts")


def list_models(models_dir: Path | None) -> list[str]:
    """Names of the model files (``*.pt``, ``*.onnx``, ``*.ts``) directly in ``models_dir``, hidden
    ones left out (sorted; [] if absent)."""
    if models_dir is None or not models_dir.is_dir():
        return []
    return sorted(p.name for p in models_dir.iterdir()
                  if p.suffix in MODEL_SUFFIXES and not p.name.startswith(".") and p.is_file())


def static_file(root: Path, request_path: str) -> Path | None:
    """The file a request path names inside ``root``, or None when it names nothing there.

    The path is resolved (``..``, symlinks) and must stay inside ``root``: no request can read a
    file outside the served folder.
    """
    if "\x00" in request_path or "\\" in request_path:
        return None
    parts = [p for p in request_path.split("/") if p not in ("", ".")]
    if not parts or any(p == ".." or p.startswith(".") for p in parts):
        return None
    base = root.resolve()
    candidate = base.joinpath(*parts).resolve()
    if not candidate.is_relative_to(base) or not candidate.is_file():
        return None
    return candidate


class WebServer:
    """Serve the page and the Socket.IO API until :meth:`stop` is called.

    Args:
        state: the control slot shared with the loop.
        frames: the latest camera frame.
        host: interface to bind. Default ``127.0.0.1`` (this machine only).
        port: TCP port; 0 picks a free one (see :attr:`port` once started). Default 8887.
        token: token every Socket.IO connection must present (None = none needed).
        models_dir: folder listed by the model picker (None = no picker).
        max_speed_limit: largest speed limit a browser may set, m/s. Default 5.0.
        telemetry_hz: how often the page gets the state. Default 20.
        static_dir: folder the page is served from. Default the package's ``static``.
        extra_hosts: host names besides IP addresses, ``localhost``, the machine's name and
            ``host`` that a request may name (WEB_ALLOWED_HOSTS). Any other Host is refused with
            403: a page of another site made to resolve to this machine (DNS rebinding) gets
            nothing.
        paths: the latest path of a path-following car, sent as the ``path`` event on connect and
            when it changes (:class:`~parts.web.pathview.PathSender`). Default: an empty slot.
        link: the laptop link's routes (tubs, models, pilot switch; :mod:`parts.web.carlink`),
            behind the same Host check and pairing token. Default None: not served.
    """

    def __init__(self, state: ControlState, frames: LatestFrame, *, host: str = "127.0.0.1",
                 port: int = 8887, token: str | None = None, models_dir: Path | None = None,
                 max_speed_limit: float = 5.0, telemetry_hz: float = 20.0,
                 static_dir: Path = STATIC_DIR, extra_hosts: tuple[str, ...] = (),
                 paths: PathSlot | None = None, link: CarLink | None = None) -> None:
        if not 0 <= port <= 65535:
            raise ValueError(f"port must be in [0, 65535], got {port}")
        if not telemetry_hz > 0:
            raise ValueError(f"telemetry_hz must be > 0, got {telemetry_hz}")
        self.state, self.frames = state, frames
        self.host, self.port, self.token = host, port, token
        self.models_dir, self.max_speed_limit = models_dir, max_speed_limit
        self.telemetry_hz, self.static_dir = telemetry_hz, static_dir
        self.paths = PathSender(paths if paths is not None else PathSlot())
        self.allowed_hosts = allowed_hosts(host, extra_hosts)
        self._refused_hosts: set[str] = set()  # each logged once
        # what clients can make the server log: rejections, refused connections, library errors
        self.log = BoundedLog(logger, "rejected messages and refused connections")
        self.guard = FailureGuard("web")  # slows and logs wrong pairing tokens, per client address
        self.link = link
        self._library_log = BoundedLog(logging.getLogger(f"{__name__}.socketio"), "Socket.IO lines",
                                       demote_info=True)
        self.loop: asyncio.AbstractEventLoop | None = None
        self.rejected = 0  # messages refused as malformed, out of range or not allowed
        self._stop: asyncio.Event | None = None
        self._stop_requested = threading.Event()
        self._frame_event: asyncio.Event | None = None
        self._senders: dict[str, asyncio.Task[None]] = {}
        self._sio: Any = None

    # -- called from other threads ----------------------------------------------------------------
    @property
    def has_viewers(self) -> bool:
        """Whether any browser is connected (frames are only copied and encoded then)."""
        return bool(self._senders)

    def notify_frame(self) -> None:
        """Wake the frame senders (thread-safe; a no-op until the server runs)."""
        loop = self.loop
        if loop is not None and self._senders and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # loop closed between the check and the call
                loop.call_soon_threadsafe(self._wake_senders)

    def stop(self) -> None:
        """Ask the server to close (thread-safe)."""
        self._stop_requested.set()
        loop, stop = self.loop, self._stop
        if loop is not None and stop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(stop.set)

    # -- the web thread ---------------------------------------------------------------------------
    async def start(self) -> Any:
        """Bind and start serving; returns the aiohttp runner (see :meth:`serve_until_stopped`)."""
        import socketio
        from aiohttp import web

        self.loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        self._frame_event = asyncio.Event()
        # messages up to HARD_LIMIT_BYTES are read and those above MAX_MESSAGE_BYTES refused with an
        # error reply (BoundedPacket); Engine.IO closes the connection of a larger one
        sio = socketio.AsyncServer(async_mode="aiohttp", transports=["websocket"],
                                   max_http_buffer_size=HARD_LIMIT_BYTES, serializer=make_bounded_packet(),
                                   logger=self._library_log, engineio_logger=self._library_log,
                                   ping_interval=5, ping_timeout=5)
        self._sio = sio
        self._register(sio)

        @web.middleware
        async def check_host(request: Any, handler: Any) -> Any:
            return await self._check_host(request, handler)

        app = web.Application(client_max_size=HARD_LIMIT_BYTES, middlewares=[check_host])
        app.router.add_get("/", self._index)
        app.router.add_get("/static/{path:.*}", self._static)
        app.router.add_get("/favicon.ico", self._favicon)  # what browsers ask for without a <link>
        if self.link is not None:
            self.link.add_routes(app, self)
        sio.attach(app)
        runner = web.AppRunner(app, access_log=None, handle_signals=False, shutdown_timeout=SHUTDOWN_S)
        await runner.setup()
        site = web.TCPSite(runner, self.host, self.port)
        try:
            await site.start()
        except OSError as exc:
            await runner.cleanup()
            error = ListenError(f"web controller cannot listen on {self.host}:{self.port}: " + listen_advice(
                exc, self.host, self.port, port_fix="set WEB_CONTROL_PORT to a free port in myconfig.py",
                host_fix="set WEB_HOST in myconfig.py to one of its addresses (\"0.0.0.0\": all of them)"))
            error.errno = exc.errno
            raise error from exc
        self.port = runner.addresses[0][1]
        return runner

    async def serve_until_stopped(self, runner: Any) -> None:
        """Send telemetry until :meth:`stop`, then disconnect everyone and close."""
        assert self._stop is not None  # set by start()  # noqa: S101
        telemetry = asyncio.create_task(self._telemetry())
        try:
            if not self._stop_requested.is_set():
                await self._stop.wait()
        finally:
            telemetry.cancel()
            for task in list(self._senders.values()):
                task.cancel()
            await asyncio.gather(telemetry, *self._senders.values(), return_exceptions=True)
            for log in (self.log, self._library_log):
                log.flush(force=True)
            self._senders.clear()
            # close every connection ourselves (Socket.IO's shutdown() leaves them open, and the
            # web server would wait for each browser to leave), then end engine.io's tasks
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._sio.eio.disconnect(), SHUTDOWN_S)
            await self._sio.shutdown()
            await runner.cleanup()

    def _wake_senders(self) -> None:
        event, self._frame_event = self._frame_event, asyncio.Event()
        if event is not None:
            event.set()

    async def _check_host(self, request: Any, handler: Any) -> Any:
        """aiohttp middleware: answer only requests that name this car in their Host header."""
        from aiohttp import web

        host = request.headers.get("Host", "")
        if host_allowed(host, self.allowed_hosts):
            return await handler(request)
        shown = host[:80]
        if len(self._refused_hosts) < 100 and shown not in self._refused_hosts:
            self._refused_hosts.add(shown)
            logger.warning("web: refused a request for host name %r from %s: not this car's (a page "
                           "of another site, DNS rebinding?); add the name to WEB_ALLOWED_HOSTS if "
                           "it is yours", shown, request.remote)
        return web.Response(status=403, text=f"host name {shown!r} is not this car's; open the "
                            "page by the address the car printed at start (or add the name to "
                            "WEB_ALLOWED_HOSTS in myconfig.py)\n")

    async def _index(self, request: Any) -> Any:
        from aiohttp import web

        if self.token is not None:  # while an address must wait, its page without the right token too
            wait = self.guard.refusal_s(request.remote or "?", token_ok(self.token, dict(request.query)))
            if wait:
                return web.Response(status=429, headers={"Retry-After": str(wait), "Cache-Control": "no-store"},
                                    text=f"too many wrong pairing tokens from this address: wait {wait} s, then "
                                         "open the URL printed when the car started\n")
        return web.FileResponse(self.static_dir / "index.html",
                                headers={"Cache-Control": "no-cache", "Content-Type": "text/html"})

    async def _favicon(self, request: Any) -> Any:
        from aiohttp import web

        return web.FileResponse(self.static_dir / "favicon.svg",
                                headers={"Cache-Control": "max-age=86400", "Content-Type": "image/svg+xml"})

    async def _static(self, request: Any) -> Any:
        from aiohttp import web

        path = static_file(self.static_dir, request.match_info["path"])
        if path is None:
            raise web.HTTPNotFound(text="not found")
        ctype = _CONTENT_TYPES.get(path.suffix, "application/octet-stream")
        return web.FileResponse(path, headers={"Cache-Control": "no-cache", "Content-Type": ctype})

    def _models(self) -> list[str]:
        return list_models(self.models_dir)

    def _hello(self, sid: str, role: str) -> dict[str, Any]:
        return {"sid": sid, "role": role, "deadman_s": self.state.deadman_s,
                "modes": protocol.MODE_LABELS, "models": self._models(),
                "max_speed_limit": self.max_speed_limit, "state": self.state.snapshot()}

    def _reject(self, sid: str, error: str) -> dict[str, Any]:
        self.rejected += 1
        self.log.info("web: rejected a message from %s: %s", sid, error)
        return {"ok": False, "error": error}

    def _register(self, sio: Any) -> None:
        """The Socket.IO handlers (each returns the acknowledgement the client receives)."""
        handlers = {"connect": self._on_connect, "disconnect": self._on_disconnect, "drive": self._on_drive,
                    "set": self._on_set, "estop": self._on_estop, "take_control": self._on_take_control,
                    "models": self._on_models, "behavior": self._on_behavior,
                    "path_command": self._on_path_command, REFUSED_EVENT: self._on_refused,
                    "*": self._on_unknown}  # "*": any other event
        for event, handler in handlers.items():
            sio.on(event, handler)

    async def _on_connect(self, sid: str, environ: dict[str, Any], auth: Any = None) -> None:
        import socketio  # the server runs it: imported with the server

        client = environ.get("REMOTE_ADDR", "?")
        right = token_ok(self.token, auth)
        wait = self.guard.refusal_s(client, right) if self.token is not None else 0
        if wait:
            raise socketio.exceptions.ConnectionRefusedError(
                f"too many wrong pairing tokens from this address: wait {wait} s")
        if not right:
            if isinstance(auth, dict) and auth.get("token"):
                self.guard.failed(client)  # a wrong token (a missing one is no guess): slowed, logged
            raise socketio.exceptions.ConnectionRefusedError(
                "pairing token missing or wrong: open the URL printed when the car started")
        self.guard.succeeded(client)
        role = self.state.connect(sid)
        self._senders[sid] = asyncio.create_task(self._send_frames(sid))
        await self._sio.emit("hello", self._hello(sid, role), to=sid)
        path = self.paths.for_new(sid)
        if path is not None:
            await self._sio.emit("path", path, to=sid)
        logger.info("web: %s connected as %s", environ.get("REMOTE_ADDR", "?"), role)

    async def _on_disconnect(self, sid: str, reason: Any = None) -> None:
        self.paths.forget(sid)
        task = self._senders.pop(sid, None)
        if task is not None:
            task.cancel()
        if self.state.disconnect(sid):
            logger.info("web: the driving browser left: car stopped")
            await self._sio.emit("roles", {"driver": None})

    async def _on_drive(self, sid: str, data: Any = None) -> dict[str, Any]:
        if not self.state.is_driver(sid):
            return self._reject(sid, "drive: this browser watches; press 'Take control' to drive")
        try:
            angle, throttle = protocol.parse_drive(data)
        except protocol.ProtocolError as exc:
            return self._reject(sid, str(exc))
        self.state.drive(angle, throttle)
        return {"ok": True}

    async def _on_set(self, sid: str, data: Any = None) -> dict[str, Any]:
        if not self.state.is_driver(sid):
            return self._reject(sid, "set: this browser watches; press 'Take control' first")
        try:
            settings = protocol.parse_settings(data, models=self._models(),
                                               max_speed_limit=self.max_speed_limit)
        except protocol.ProtocolError as exc:
            return self._reject(sid, str(exc))
        refused = self.state.refusal(settings)
        if refused:
            return self._reject(sid, refused)
        model_path = None
        if "model" in settings and self.models_dir is not None:
            model_path = str((self.models_dir / settings["model"]).resolve())
        self.state.apply(settings, model_path)
        return {"ok": True}

    async def _on_estop(self, sid: str, data: Any = None) -> dict[str, Any]:
        try:
            on = protocol.parse_estop(data)
        except protocol.ProtocolError as exc:
            return self._reject(sid, str(exc))
        # anyone watching may stop the car; only the driver may release the stop
        if not on and not self.state.is_driver(sid):
            return self._reject(sid, "estop: only the driving browser can release the stop")
        self.state.set_estop(on)
        if on:
            logger.warning("web: emergency stop latched by %s", sid)
        return {"ok": True}

    async def _on_take_control(self, sid: str, data: Any = None) -> dict[str, Any]:
        previous = self.state.take_control(sid)
        await self._sio.emit("roles", {"driver": sid})
        logger.info("web: %s takes control (previous driver: %s)", sid, previous)
        return {"ok": True, "role": "driver"}

    async def _on_models(self, sid: str, data: Any = None) -> dict[str, Any]:
        return {"ok": True, "models": self._models()}

    async def _on_behavior(self, sid: str, data: Any = None) -> dict[str, Any]:
        if not self.state.is_driver(sid):
            return self._reject(sid, "behavior: this browser watches; press 'Take control' first")
        try:
            step = protocol.parse_behavior(data)
        except protocol.ProtocolError as exc:
            return self._reject(sid, str(exc))
        self.state.step_behavior(step)
        return {"ok": True}

    async def _on_path_command(self, sid: str, data: Any = None) -> dict[str, Any]:
        if not self.state.is_driver(sid):
            return self._reject(sid, "path_command: this browser watches; press 'Take control' first")
        try:
            command = protocol.parse_path_command(data)
        except protocol.ProtocolError as exc:
            return self._reject(sid, str(exc))
        refused = self.state.path_command(command)
        if refused:
            return self._reject(sid, refused)
        logger.info("web: path command %r from %s", command, sid)
        return {"ok": True}

    async def _on_refused(self, sid: str, data: Any = None) -> dict[str, Any]:
        return self._reject(sid, protocol.short(data, 200) if not isinstance(data, str) else data[:200])

    async def _on_unknown(self, event: str, sid: str, data: Any = None) -> dict[str, Any]:
        return self._reject(sid, f"unknown event {protocol.short(event)}; the page sends drive, set, "
                            "estop, take_control, models, behavior, path_command")

    async def _telemetry(self) -> None:
        period = 1.0 / self.telemetry_hz
        loop = asyncio.get_running_loop()
        while True:
            if self._senders:
                await self._sio.emit("state", self.state.snapshot())
                path, sids = self.paths.due(list(self._senders), loop.time())  # changed, at most 2/s
                for sid in sids:
                    await self._sio.emit("path", path, to=sid)
            self.log.flush()
            self._library_log.flush()
            await asyncio.sleep(period)

    async def _send_frames(self, sid: str) -> None:
        """Send each new frame to one browser, waiting for its acknowledgement before the next:
        at most one frame is in flight per browser, and a slow one gets the latest, not a queue."""
        import socketio

        seen = -1
        while True:
            event = self._frame_event
            if self.frames.version == seen and event is not None:
                await event.wait()
                continue
            data, version = self.frames.jpeg()
            seen = version
            if data is None:
                continue
            try:
                await self._sio.call("frame", data, to=sid, timeout=FRAME_ACK_TIMEOUT)
            except socketio.exceptions.TimeoutError:
                logger.debug("web: %s did not acknowledge a frame within %.1f s", sid,
                              FRAME_ACK_TIMEOUT)
            except (socketio.exceptions.SocketIOError, KeyError, ValueError):
                return  # the browser disconnected
