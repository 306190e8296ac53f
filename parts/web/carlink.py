"""The car's side of the laptop link: its tubs, its models and its pilot, for the paired user only.

Routes added to the web page's server (:class:`parts.web.server.WebServer`), so the same Host check
(DNS rebinding) applies; each request must also carry the pairing token as ``Authorization:
Bearer TOKEN`` (any value when the car needs none, on loopback: a page of another site cannot
send that header without a CORS preflight, which this server never grants), and a browser
request from another origin is refused. Wrong tokens are slowed per client
(:class:`parts.web.pairing.FailureGuard`).

    GET  /car/status                   mode, records, loop rate and overruns, battery, pilot
    GET  /car/tubs                     the tubs with record counts and sizes
    GET  /car/tubs/NAME/records?start=N   a snapshot's records from N (parts.tub.transfer frames)
    GET  /car/models                   the model files
    PUT  /car/models/NAME.pt           upload a model (size limit, checked as `drive --model`, atomic)
    POST /car/pilot {"model": NAME}    switch the running pilot (user mode first; waits for the load)
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import logging
import os
import re
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from parts.web.pairing import token_ok
from vehicle.errors import VehicleError

if TYPE_CHECKING:
    from parts.web.server import WebServer

logger = logging.getLogger(__name__)

MODEL_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}\.pt$")
#: bytes read from the network before each write to disk
CHUNK = 1 << 16
#: bytes of pull frames gathered in the reading thread before each send
SEND_BATCH = 1 << 18
#: seconds a switch request waits for the pilot to load the model
SWITCH_WAIT_S = 60.0


class CarLink:
    """The laptop link's routes (see the module docstring).

    Args:
        data_dir: the car's DATA_PATH (None: no tubs are served).
        models_dir: the car's MODELS_PATH (None: no model can be pushed).
        name: the car's name shown by the console.
        max_model_bytes: largest model file accepted.
        check_model: raises ValueError (or a VehicleError) with the reason when a model file does
            not fit this car; the assembly sets it to ``manage.py drive --model``'s checks. None: only
            the safe loader's checks (:func:`parts.pilots.modelfile.read_meta`).
    """

    def __init__(self, data_dir: Path | None, models_dir: Path | None, *, name: str = "car",
                 max_model_bytes: int = 200 << 20, check_model: Callable[[Path], None] | None = None) -> None:
        if max_model_bytes <= 0:
            raise ValueError(f"max_model_bytes must be > 0, got {max_model_bytes}")
        self.data_dir, self.models_dir, self.name = data_dir, models_dir, name
        self.max_model_bytes = max_model_bytes
        self.check_model = check_model
        self.pulls = 0  # pulls served (for the log and tests)
        self._sizes: dict[Path, Any] = {}  # tub -> (its manifest's and images' mtimes, bytes): list_tubs
        self._server: WebServer | None = None

    def add_routes(self, app: Any, server: WebServer) -> None:
        """Add the routes to the aiohttp application of ``server``."""
        self._server = server
        for method, path, handler in (("GET", "/car/status", self.status), ("GET", "/car/tubs", self.tubs),
                                      ("GET", "/car/tubs/{name}/records", self.records),
                                      ("GET", "/car/models", self.models),
                                      ("PUT", "/car/models/{name}", self.upload),
                                      ("POST", "/car/pilot", self.switch)):
            app.router.add_route(method, path, self._guarded(handler))

    # -- who may ask ----------------------------------------------------------------------------------
    def _guarded(self, handler: Callable[[Any], Any]) -> Callable[[Any], Any]:
        async def guarded(request: Any) -> Any:
            refused = self._refusal(request)
            if refused is not None:
                return refused
            try:
                return await handler(request)
            except LinkError as exc:
                return _json({"ok": False, "error": str(exc)}, exc.status)

        return guarded

    def _refusal(self, request: Any) -> Any:
        """An error answer for a request that is not the paired user's, else None."""
        server = self._server
        assert server is not None  # noqa: S101 - set by add_routes
        origin = request.headers.get("Origin")
        if origin is not None and origin not in (f"http://{request.host}", f"https://{request.host}"):
            return _json({"ok": False, "error": "requests from other sites are refused"}, 403)
        auth = request.headers.get("Authorization", "")
        if not auth.startswith("Bearer "):
            return _json({"ok": False, "error": "send the car's pairing token (Authorization: Bearer TOKEN): "
                                                "the one in the URL the car printed at start"}, 401)
        if server.token is None:
            return None
        client = request.remote or "?"
        right = token_ok(server.token, {"token": auth[len("Bearer "):].strip()})
        wait = server.guard.refusal_s(client, right)
        if wait:
            return _json({"ok": False, "error": f"too many wrong pairing tokens from this address: wait {wait} s"},
                         429, {"Retry-After": str(wait)})
        if not right:
            server.guard.failed(client)
            return _json({"ok": False, "error": "pairing token wrong: use the one in the URL the car printed at "
                                                "start"}, 401)
        server.guard.succeeded(client)
        return None

    # -- status, tubs, models ---------------------------------------------------------------------------
    async def status(self, request: Any) -> Any:
        assert self._server is not None  # noqa: S101
        snap = self._server.state.snapshot()
        tel, cmd = snap["telemetry"], snap["command"]
        return _json({"ok": True, "name": self.name, "mode": tel["mode"] or cmd["mode"],
                      "recording": tel["recording"], "records": tel["num_records"], "estop": cmd["estop"],
                      "loop_rate_hz": tel["loop_rate_hz"], "loop_overruns": tel["loop_overruns"],
                      "battery_v": tel["battery_v"], "pilot": tel["pilot_model"], "pilot_error": tel["pilot_error"],
                      "notice": snap["notice"], "age_s": snap["age_s"], "loops": tel["loops"]})

    async def tubs(self, request: Any) -> Any:
        from parts.tub.transfer import list_tubs

        tubs = await asyncio.to_thread(list_tubs, self.data_dir, self._sizes) if self.data_dir is not None else []
        return _json({"ok": True, "tubs": tubs})

    async def models(self, request: Any) -> Any:
        from parts.web.server import list_models

        assert self._server is not None  # noqa: S101
        driving = self._server.state.snapshot()["telemetry"]["pilot_model"]
        out = []
        for name in list_models(self.models_dir):
            assert self.models_dir is not None  # noqa: S101 - list_models gives none without it
            with contextlib.suppress(OSError):
                out.append({"name": name, "bytes": (self.models_dir / name).stat().st_size,
                            "driving": name == driving})
        return _json({"ok": True, "models": out})

    # -- pulling a tub -----------------------------------------------------------------------------------
    async def records(self, request: Any) -> Any:
        from aiohttp import web

        from parts.tub.transfer import TransferError, snapshot, stream_records, tub_folder

        if self.data_dir is None:
            raise LinkError(404, "this car serves no tubs (no DATA_PATH)")
        try:
            start = int(request.query.get("start", "0"))
            if start < 0:
                raise ValueError
        except ValueError:
            raise LinkError(400, "start must be a whole number >= 0 (the index the laptop has up to)") from None
        try:
            snap = await asyncio.to_thread(snapshot, tub_folder(self.data_dir, request.match_info["name"]))
        except TransferError as exc:
            raise LinkError(404, str(exc)) from exc
        if start > snap.end:
            raise LinkError(409, f"the laptop has records up to {start} but the car's {snap.path.name} ends at "
                                 f"{snap.end}: it is another tub of the same name; pull into another folder")
        frames = stream_records(snap, start)

        def batch() -> bytes:  # file reads and CRCs off the server's event loop
            out, size = [], 0
            for frame in frames:
                out.append(frame)
                size += len(frame)
                if size >= SEND_BATCH:
                    break
            return b"".join(out)

        resp = web.StreamResponse(headers={"Content-Type": "application/octet-stream", "Cache-Control": "no-store"})
        await resp.prepare(request)
        self.pulls += 1
        logger.info("car link: %s pulls %s from record %d (snapshot of %d records)", request.remote,
                    snap.path.name, start, snap.end)
        try:
            while data := await asyncio.to_thread(batch):
                await resp.write(data)
            await resp.write_eof()
        except (ConnectionError, asyncio.CancelledError) as exc:  # the laptop left: it resumes next time
            logger.info("car link: %s left during the pull of %s", request.remote, snap.path.name)
            if isinstance(exc, asyncio.CancelledError):
                raise
        return resp

    # -- pushing a model ---------------------------------------------------------------------------------
    async def upload(self, request: Any) -> Any:
        name = request.match_info["name"]
        if self.models_dir is None:
            raise LinkError(404, "this car has no models folder (MODELS_PATH)")
        if not MODEL_NAME_RE.match(name):
            raise LinkError(400, f"{name[:60]!r} is not a model file name: letters, digits, '.', '_', '-', "
                                 "ending in .pt")
        if request.content_length is not None and request.content_length > self.max_model_bytes:
            raise LinkError(413, f"the model is {request.content_length / 1e6:.1f} MB, over this car's limit of "
                                 f"{self.max_model_bytes / 1e6:.1f} MB (CAR_MAX_MODEL_MB in its myconfig.py)")
        self.models_dir.mkdir(parents=True, exist_ok=True)
        tmp = self.models_dir / f".{name}.upload-{os.getpid()}-{id(request)}"
        try:
            digest = await self._receive(request, tmp)
            final = self.models_dir / name
            if final.exists():
                same = await asyncio.to_thread(_sha256, final) == digest
                if not same:
                    raise LinkError(409, f"the car has another {name} already: push this model under another name")
                return _json({"ok": True, "model": name, "bytes": final.stat().st_size, "new": False})
            await asyncio.to_thread(self._check, tmp, name)
            await asyncio.to_thread(_put_in_place, tmp, final)
        finally:
            tmp.unlink(missing_ok=True)
        logger.info("car link: %s pushed the model %s (%d bytes)", request.remote, name, final.stat().st_size)
        return _json({"ok": True, "model": name, "bytes": final.stat().st_size, "new": True}, 201)

    async def _receive(self, request: Any, tmp: Path) -> str:
        """Write the request body to ``tmp`` (refused over the size limit); returns its SHA-256."""
        digest, size = hashlib.sha256(), 0
        with open(tmp, "wb") as f:
            async for chunk in request.content.iter_chunked(CHUNK):
                size += len(chunk)
                if size > self.max_model_bytes:
                    raise LinkError(413, f"the model is over this car's limit of {self.max_model_bytes / 1e6:.1f} "
                                         "MB (CAR_MAX_MODEL_MB in its myconfig.py)")
                digest.update(chunk)
                f.write(chunk)
            f.flush()
            os.fsync(f.fileno())
        if size == 0:
            raise LinkError(400, "the model file is empty")
        return digest.hexdigest()

    def _check(self, path: Path, name: str) -> None:
        """LinkError 422 with the reason unless ``path`` is a model file that fits this car."""
        try:
            with zipfile.ZipFile(path) as zf:  # a zip bomb would expand far beyond what was sent
                expanded = sum(info.file_size for info in zf.infolist())
            if expanded > 4 * self.max_model_bytes:
                raise ValueError(f"its archive expands to {expanded / 1e6:.0f} MB: not a model file")
        except (zipfile.BadZipFile, OSError):
            pass  # the loader names what is wrong with it
        except ValueError as exc:
            raise LinkError(422, f"{name} refused: {exc}") from exc
        try:
            if self.check_model is not None:
                self.check_model(path)
            else:
                from parts.pilots.modelfile import read_meta

                read_meta(path)
        except ImportError as exc:
            raise LinkError(501, f"this car cannot load models ({exc}): pip install 'vehicle-rc[train]' "
                                 "on the car") from exc
        except (ValueError, OSError, VehicleError) as exc:  # ModelFileError, ModelMismatch, UserError
            reason = str(exc).replace(str(path), name).splitlines()[0]
            raise LinkError(422, f"{name} refused: {reason}") from exc

    # -- switching the pilot -------------------------------------------------------------------------------
    async def switch(self, request: Any) -> Any:
        assert self._server is not None  # noqa: S101
        try:
            body = await request.json()
        except ValueError:
            raise LinkError(400, 'send {"model": "NAME.pt"} as JSON') from None
        name = body.get("model") if isinstance(body, dict) else None
        if not isinstance(name, str) or not MODEL_NAME_RE.match(name):
            raise LinkError(400, 'send {"model": "NAME.pt"}: a model file name on the car (GET /car/models)')
        if self.models_dir is None or not (self.models_dir / name).is_file():
            raise LinkError(404, f"the car has no model {name}: push it first")
        state = self._server.state
        if state.snapshot()["telemetry"]["pilot_model"] == name:
            return _json({"ok": True, "model": name, "switched": False})
        path = str((self.models_dir / name).resolve())
        before = state.snapshot()
        # a car in a pilot mode drops to user mode for the switch (ControlState.switch_model)
        dropped = before["command"]["mode"] != "user" or (before["telemetry"]["mode"] or "user") != "user"
        refused = state.switch_model(path, name)
        if refused:
            raise LinkError(409, refused)
        logger.warning("car link: %s asked to switch the pilot to %s", request.remote, name)
        end = time.monotonic() + SWITCH_WAIT_S
        while time.monotonic() < end:
            await asyncio.sleep(0.05)
            tel = state.snapshot()["telemetry"]
            if tel["pilot_model"] == name:
                state.set_notice(f"The pilot is now {name}" + (" (the car was put in user mode for the switch)"
                                                                if dropped else "")
                                 + ": choose a pilot mode to let it drive.")
                return _json({"ok": True, "model": name, "switched": True})
            error = tel["pilot_error"] or ""
            if error.startswith(path):
                state.set_notice(f"Pilot switch to {name} failed; the car keeps its pilot"
                                 + (" (and stays in user mode)." if dropped else "."))
                raise LinkError(422, f"the car kept its pilot: {error.replace(path, name)}")
        raise LinkError(504, f"the car has not loaded {name} within {SWITCH_WAIT_S:.0f} s; see its page")


class LinkError(Exception):
    """An error answer: HTTP ``status`` and a one-line message."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def _json(data: dict[str, Any], status: int = 200, headers: dict[str, str] | None = None) -> Any:
    from aiohttp import web

    return web.json_response(data, status=status, headers={"Cache-Control": "no-store", **(headers or {})})


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(CHUNK):
            digest.update(chunk)
    return digest.hexdigest()


def _put_in_place(tmp: Path, final: Path) -> None:
    """Rename the checked upload into place, durably (the folder entry too)."""
    from parts.tub.format import fsync_dir

    os.replace(tmp, final)
    fsync_dir(final.parent)
