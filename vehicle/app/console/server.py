"""The trainer console's web server: the page, the JSON API, live job events, and the job queue.

One aiohttp application per car, listening on CONSOLE_HOST:CONSOLE_PORT (loopback by default).
Off loopback every API request needs the car's pairing token (WEB_TOKEN's rules, as the driver
page): the page URL carries it once (``/?token=...``), the server answers with a same-site,
HTTP-only cookie, and the page's requests carry the cookie. Requests that change something must
come from the console's own origin (a page on another site cannot drive the API).

Live job events reach the browsers as Server-Sent Events (``/api/events``); trainings and
evaluations run in worker processes (:mod:`vehicle.app.console.jobs`), never in this process.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import sys
import threading
import time
from datetime import datetime
from pathlib import Path
from typing import Any

from training.model_db import ModelDB
from vehicle.app.console.api import Api, ApiError, json_response
from vehicle.app.console.cars import CarsApi
from vehicle.app.console.datasets import DatasetStore
from vehicle.app.console.jobs import JobQueue
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

STATIC_DIR = Path(__file__).with_name("static")
COOKIE = "vehicle_console_token"
#: seconds between keep-alive comments on an idle event stream
KEEPALIVE_S = 15.0


#: the lock file (in the car's models/.jobs) a running console holds
CONSOLE_LOCK = "console.lock"


class ConsoleBusyError(VehicleError):
    """Another console serves this car already."""


class ConsoleApp:
    """The console of one car.

    Args:
        cfg: the car's config (paths, defaults of the training form, evaluation tracks).
        host: interface to bind. Default CONSOLE_HOST.
        port: TCP port; 0 picks a free one (:attr:`port` once started). Default CONSOLE_PORT.
        token: pairing token every API request must carry (None: none needed, loopback only).
        myconfig: the override file the workers load instead of ``myconfig.py``.
    """

    def __init__(self, cfg: Any, *, host: str | None = None, port: int | None = None, token: str | None = None,
                 myconfig: str | None = None) -> None:
        self.cfg = cfg
        self.host = cfg.CONSOLE_HOST if host is None else host
        self.port = cfg.CONSOLE_PORT if port is None else port
        if not 0 <= self.port <= 65535:
            raise ValueError(f"port must be in [0, 65535], got {self.port}")
        self.token = token
        self.db = ModelDB.for_models_dir(cfg.path("MODELS_PATH"))
        self.db.list()  # creates or upgrades the database before anything else uses it
        self.datasets = DatasetStore(cfg, self.db)
        self.jobs = JobQueue(self.db.db_path, Path(cfg.CAR_PATH), myconfig)
        self.datasets.busy = self.jobs.busy_paths
        self.api = Api(self)
        self.cars = CarsApi(self)
        self.loop: asyncio.AbstractEventLoop | None = None
        self._types: list[dict[str, Any]] | None = None
        self._types_lock: asyncio.Lock | None = None
        self._stop: asyncio.Event | None = None
        self._stop_requested = threading.Event()
        self._streams: set[asyncio.Task[Any]] = set()
        self._describe: Any = None
        self._warm: asyncio.Task[Any] | None = None
        self._runner: Any = None
        self._thread: threading.Thread | None = None
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._hosts: frozenset[str] | None = None  # Host header names served without a token
        self._car_lock: int | None = None  # fd holding the car's console lock while serving
        from parts.web.pairing import FailureGuard

        self._guard = FailureGuard("console")  # slows and logs wrong tokens, per client address

    # -- helpers used by the API --------------------------------------------------------------------
    async def model_types(self) -> list[dict[str, Any]]:
        """The registered model types (asked once of a worker process: torch stays out of here)."""
        if self._types is not None:
            return self._types
        assert self._types_lock is not None  # noqa: S101 - set in start()
        async with self._types_lock:
            if self._types is None:
                proc = await asyncio.create_subprocess_exec(
                    sys.executable, "-m", "vehicle.app.console.worker", "describe",
                    stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
                self._describe = proc
                try:
                    out, err = await proc.communicate()
                finally:
                    if proc.returncode is None:  # cancelled: the console is closing
                        with contextlib.suppress(ProcessLookupError):
                            proc.kill()
                        await proc.wait()
                try:
                    self._types = json.loads(out.decode().strip().splitlines()[-1])["model_types"]
                except (ValueError, IndexError, KeyError):
                    logger.error("could not list the model types: %s", err.decode(errors="replace")[-2000:])
                    return []
        return self._types

    def free_model_name(self) -> str:
        """``pilot_YY-MM-DD_N`` with the first N free in the model database and the models folder."""
        day = datetime.now().strftime("%y-%m-%d")
        models = self.cfg.path("MODELS_PATH")
        taken = set(self.db.names())
        for job in self.jobs.list():
            full = self.jobs.get(job["id"])
            if full is not None and full.kind == "train":
                taken.add(full.params.get("model_name"))
        n = 1
        while f"pilot_{day}_{n}" in taken or (models / f"pilot_{day}_{n}.pt").exists():
            n += 1
        return f"pilot_{day}_{n}"

    # -- the application ----------------------------------------------------------------------------
    def _allowed_host(self, request: Any) -> bool:
        """DNS rebinding guard: on loopback without a token, only loopback host names are served."""
        from parts.web.pairing import allowed_hosts, host_allowed

        if self.token is not None:
            return True  # a token is required: a rebound page has no cookie for this origin
        if self._hosts is None:
            self._hosts = allowed_hosts(self.host)
        return host_allowed(request.host, self._hosts)

    @staticmethod
    def _given(request: Any) -> str | None:
        """The token a request carries: by the cookie, a header or the URL."""
        return request.cookies.get(COOKIE) or request.headers.get("X-Vehicle-Token") or request.query.get("token")

    def _token_ok(self, request: Any) -> bool:
        """The driver page's rule (parts.web.pairing.token_ok), the token carried by the cookie, a
        header or the URL. A wrong token (not a missing one) counts against the client."""
        from parts.web.pairing import token_ok

        given = self._given(request)
        ok = token_ok(self.token, {"token": given})
        if self.token is not None and given:
            client = request.remote or "?"
            if ok:
                self._guard.succeeded(client)
            else:
                self._guard.failed(client)
        return ok

    def _locked_out(self, request: Any) -> Any:
        """A 429 answer while this client must wait after wrong tokens, else None. The right token
        never waits (a guesser behind the same NAT must not keep the user out)."""
        from aiohttp import web

        from parts.web.pairing import token_ok

        if self.token is None:
            return None
        seconds = self._guard.refusal_s(request.remote or "?", token_ok(self.token, {"token": self._given(request)}))
        if not seconds:
            return None
        return web.json_response({"error": f"too many wrong pairing tokens from this address: wait {seconds} s, "
                                           "then open the URL printed when the console started"},
                                 status=429, headers={"Retry-After": str(seconds), "Cache-Control": "no-store"})

    def _same_origin(self, request: Any) -> bool:
        origin = request.headers.get("Origin")
        if origin is None:
            return True  # not a browser page (curl, scripts): the token rule still holds
        return origin in (f"http://{request.host}", f"https://{request.host}")

    def _middleware(self) -> Any:
        from aiohttp import web

        @web.middleware
        async def guard(request: Any, handler: Any) -> Any:
            if not self._allowed_host(request):
                return web.Response(status=421, text="unexpected Host header: open the console at "
                                    f"http://localhost:{self.port}/")
            path = request.path
            if path.startswith("/api/") or path == "/":
                refused = self._locked_out(request)
                if refused is not None:
                    return refused
            if path.startswith("/api/"):
                if not self._token_ok(request):
                    return json_response({"error": "pairing token missing or wrong: open the URL printed when "
                                                   "the console started"}, 401)
                if request.method not in ("GET", "HEAD", "OPTIONS") and not self._same_origin(request):
                    return json_response({"error": "requests from other sites are refused"}, 403)
                try:
                    return await handler(request)
                except ApiError as exc:
                    body: dict[str, Any] = {"error": exc.message}
                    if exc.field:
                        body["field"] = exc.field
                    if exc.errors:
                        body["errors"] = exc.errors
                    return json_response(body, exc.status)
            return await handler(request)

        return guard

    def build(self) -> Any:
        """The aiohttp application."""
        from aiohttp import web

        app = web.Application(middlewares=[self._middleware()], client_max_size=1024 * 1024)
        app.router.add_get("/", self._index)
        app.router.add_get("/static/{path:.*}", self._static)
        app.router.add_get("/api/events", self._events)
        for method, path, handler in [*self.api.routes(), *self.cars.routes()]:
            app.router.add_route(method, path, handler)
        return app

    async def _index(self, request: Any) -> Any:
        from aiohttp import web

        if self.token is not None and not self._token_ok(request):
            return web.Response(status=401, content_type="text/html", text=(
                "<!doctype html><meta charset=utf-8><title>Trainer console</title><p>This console needs the "
                "car's pairing token: open the URL printed (or shown as a QR code) when it started."))
        given = request.query.get("token")
        if self.token is not None and given is not None:
            # keep the token in a cookie and out of the address bar, history and shared screenshots
            found = web.HTTPSeeOther("/")
            found.set_cookie(COOKIE, given, httponly=True, samesite="Strict", path="/")
            return found
        return web.FileResponse(STATIC_DIR / "index.html",
                                headers={"Cache-Control": "no-cache", "Content-Type": "text/html"})

    async def _static(self, request: Any) -> Any:
        from aiohttp import web

        from parts.web.server import _CONTENT_TYPES, static_file

        path = static_file(STATIC_DIR, request.match_info["path"])
        if path is None:
            raise web.HTTPNotFound(text="not found")
        ctype = _CONTENT_TYPES.get(path.suffix, "application/octet-stream")
        return web.FileResponse(path, headers={"Cache-Control": "no-cache", "Content-Type": ctype})

    async def _events(self, request: Any) -> Any:
        from aiohttp import web

        resp = web.StreamResponse(headers={"Content-Type": "text/event-stream", "Cache-Control": "no-store",
                                           "X-Accel-Buffering": "no"})
        await resp.prepare(request)
        queue = self.jobs.listen()
        task = asyncio.current_task()
        if task is not None:
            self._streams.add(task)
        try:
            hello = {"event": "hello", "jobs": self.jobs.list(), "time": time.time()}
            await resp.write(f"data: {json.dumps(hello, default=str)}\n\n".encode())
            while True:
                try:
                    message = await asyncio.wait_for(queue.get(), KEEPALIVE_S)
                except TimeoutError:
                    await resp.write(b": keep-alive\n\n")
                    continue
                if message.get("event") == "overflow":
                    break  # too slow: the browser reconnects and reloads the state
                await resp.write(f"data: {json.dumps(message, default=str)}\n\n".encode())
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        finally:
            self.jobs.unlisten(queue)
            if task is not None:
                self._streams.discard(task)
        return resp

    # -- running ------------------------------------------------------------------------------------
    async def start(self) -> None:
        """Start the job queue and listen."""
        from aiohttp import web

        self.loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        self._types_lock = asyncio.Lock()
        self._hold_car()
        try:
            await self.jobs.start()
        except BaseException:
            self._release_car()
            raise
        self._runner = web.AppRunner(self.build(), access_log=None, handle_signals=False, shutdown_timeout=2.0)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port)
        try:
            await site.start()
        except OSError as exc:
            await self._runner.cleanup()
            await self.jobs.close()
            self._release_car()
            from parts.web.server import listen_advice

            raise OSError(exc.errno, f"the console cannot listen on {self.host}:{self.port}: " + listen_advice(
                exc, self.host, self.port, port_fix="pass --port or set CONSOLE_PORT in myconfig.py",
                host_fix="pass --host or set CONSOLE_HOST in myconfig.py")) from exc
        self.port = self._runner.addresses[0][1]
        os.ftruncate(self._car_lock, 0)  # who holds the car, for a second console's message
        os.pwrite(self._car_lock, f"{os.getpid()} http://{self.host}:{self.port}/".encode(), 0)
        self._warm = asyncio.create_task(self.model_types())  # the model type list, in the background

    async def serve_until_stopped(self) -> None:
        """Serve until :meth:`stop`; then stop the running job cleanly and close."""
        assert self._stop is not None  # noqa: S101 - set by start()
        try:
            if not self._stop_requested.is_set():
                await self._stop.wait()
        finally:
            for task in list(self._streams):
                task.cancel()
            if self._warm is not None and not self._warm.done():
                self._warm.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await self._warm
            await self.cars.close()
            await self.jobs.close()
            await self._runner.cleanup()
            self._release_car()

    def _hold_car(self) -> None:
        """Take the car's console lock (one console per car: two would run two job queues on one
        table and mark each other's jobs interrupted); released on close, or by the kernel when
        the process dies."""
        import fcntl

        path = self.jobs.jobs_dir / CONSOLE_LOCK
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").split()
            os.close(fd)
            where = f" (process {holder[0]}, {holder[1]})" if len(holder) == 2 else ""
            raise ConsoleBusyError(f"a trainer console of {self.cfg.CAR_PATH} is already running{where}: open "
                                   "that one, or stop it (Ctrl-C) before starting another") from None
        self._car_lock = fd

    def _release_car(self) -> None:
        if self._car_lock is not None:
            os.close(self._car_lock)  # closing releases the lock
            self._car_lock = None

    def stop(self) -> None:
        """Ask the server to close (thread-safe)."""
        self._stop_requested.set()
        loop, stop = self.loop, self._stop
        if loop is not None and stop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(stop.set)

    async def run(self) -> None:
        """Start and serve until stopped."""
        await self.start()
        await self.serve_until_stopped()

    # -- in a thread (tests, embedding) -----------------------------------------------------------
    def start_in_thread(self, timeout: float = 30.0) -> ConsoleApp:
        """Serve from a thread of its own; returns once listening (raises what start() raised)."""

        def main() -> None:
            async def go() -> None:
                try:
                    await self.start()
                except BaseException as exc:
                    self._error = exc
                    self._started.set()
                    return
                self._started.set()
                await self.serve_until_stopped()

            asyncio.run(go())

        self._thread = threading.Thread(target=main, name="console", daemon=True)
        self._thread.start()
        if not self._started.wait(timeout):
            raise TimeoutError(f"the console did not start within {timeout} s")
        if self._error is not None:
            raise self._error
        return self

    def close(self, timeout: float = 60.0) -> None:
        """Stop the thread started by :meth:`start_in_thread` and wait for it."""
        self.stop()
        if self._thread is not None:
            self._thread.join(timeout)
