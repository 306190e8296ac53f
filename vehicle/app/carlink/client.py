"""A client of a car's laptop link (:mod:`parts.web.carlink`), on the standard library's HTTP.

A car is named by the URL it printed at start, token included (``http://192.168.1.20:8887/?token=...``),
or by its address with the token given apart. Every failure is a :class:`CarLinkError` whose one
line says what to do.
"""

from __future__ import annotations

import http.client
import json
import logging
import re
import socket
import urllib.parse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from vehicle.errors import UserError

logger = logging.getLogger(__name__)

#: seconds a request waits for the car (a switch waits for the model to load: longer)
TIMEOUT_S = 10.0
SWITCH_TIMEOUT_S = 75.0
#: bytes sent per write of a model upload
CHUNK = 1 << 16


class CarLinkError(UserError):
    """The car cannot be reached or refused a request; the message says why and what to do."""

    def __init__(self, message: str, status: int | None = None) -> None:
        super().__init__(message)
        self.status = status


@dataclass(frozen=True)
class CarAddress:
    """Where a car's web server is, and its pairing token (None: the car needs none)."""

    host: str
    port: int
    token: str | None = None

    @property
    def url(self) -> str:
        """``http://host:port/`` (no token: safe to show and log)."""
        shown = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{shown}:{self.port}/"


def parse_address(text: str, token: str | None = None) -> CarAddress:
    """A car from the URL it printed (``http://HOST:PORT/?token=T``), ``HOST:PORT`` or ``HOST``
    (port 8887); ``token`` overrides the URL's. UserError for anything else."""
    text = (text or "").strip()
    if not text:
        raise CarLinkError("give the car's address: the URL it printed at start, e.g. http://192.168.1.20:8887/?token=...")
    if "://" not in text:
        text = f"http://{text}"
    parts = urllib.parse.urlsplit(text)
    if parts.scheme != "http" or not parts.hostname:
        raise CarLinkError(f"{text[:80]!r} is not a car's address: use http://HOST:PORT/ as the car printed it")
    try:
        port = parts.port or 8887
    except ValueError:
        raise CarLinkError(f"{text[:80]!r}: the port must be a number from 1 to 65535") from None
    query = urllib.parse.parse_qs(parts.query)
    given = token if token else (query.get("token") or [None])[0]
    return CarAddress(parts.hostname, port, given or None)


class CarClient:
    """Requests to one car (see :mod:`parts.web.carlink` for the routes)."""

    def __init__(self, address: CarAddress, timeout: float = TIMEOUT_S) -> None:
        self.address, self.timeout = address, timeout

    def _connection(self, timeout: float | None = None) -> http.client.HTTPConnection:
        return http.client.HTTPConnection(self.address.host, self.address.port, timeout=timeout or self.timeout)

    def _headers(self) -> dict[str, str]:
        # a car that needs no token (loopback) still wants the header: it keeps other sites' pages out
        return {"Authorization": f"Bearer {self.address.token or '-'}", "Accept": "application/json"}

    def request(self, method: str, path: str, body: Any = None, timeout: float | None = None) -> dict[str, Any]:
        """``method path`` with a JSON body; the car's JSON answer (CarLinkError for an error)."""
        headers = self._headers()
        data = None
        if body is not None:
            data = json.dumps(body).encode()
            headers["Content-Type"] = "application/json"
        conn = self._connection(timeout)
        try:
            try:
                conn.request(method, path, body=data, headers=headers)
                resp = conn.getresponse()
                raw = resp.read()
            except (OSError, http.client.HTTPException) as exc:
                raise self._unreachable(exc) from exc
            return self._answer(resp.status, raw)
        finally:
            conn.close()

    def _unreachable(self, exc: BaseException) -> CarLinkError:
        if isinstance(exc, socket.timeout | TimeoutError):
            why = "it did not answer in time"
        elif isinstance(exc, ConnectionRefusedError):
            why = "nothing listens there (is `manage.py drive` running, with WEB_HOST = \"0.0.0.0\"?)"
        else:
            why = str(exc) or type(exc).__name__
        return CarLinkError(f"cannot reach the car at {self.address.url}: {why}")

    def _answer(self, status: int, raw: bytes) -> dict[str, Any]:
        try:
            data = json.loads(raw) if raw else {}
        except ValueError:
            data = {}
        if not isinstance(data, dict):
            data = {}
        if status >= 400:
            error = data.get("error") or f"HTTP {status}"
            if status == 404 and not data:
                error = "it has no laptop link (an older version, or CAR_LINK = False in its myconfig.py)"
            raise CarLinkError(f"the car at {self.address.url} refused: {error}", status)
        return data

    # -- the routes ------------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        """Mode, records, loop rate and overruns, battery, pilot (GET /car/status)."""
        return self.request("GET", "/car/status")

    def tubs(self) -> list[dict[str, Any]]:
        """The car's tubs (GET /car/tubs)."""
        return list(self.request("GET", "/car/tubs").get("tubs", []))

    def models(self) -> list[dict[str, Any]]:
        """The car's model files (GET /car/models)."""
        return list(self.request("GET", "/car/models").get("models", []))

    def push(self, path: Path, name: str | None = None,
             progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
        """Upload the model file ``path`` as ``name`` (default its file name)."""
        path = Path(path)
        name = name or path.name
        if not re.match(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}\.pt$", name):
            raise CarLinkError(f"{name!r}: a model pushed to a car is a .pt file named with letters, digits, "
                               "'.', '_', '-'")
        try:
            size = path.stat().st_size
            f = open(path, "rb")  # noqa: SIM115 - closed below, after the request
        except OSError as exc:
            raise CarLinkError(f"cannot read the model {path}: {exc.strerror or exc}") from exc
        conn = self._connection(max(self.timeout, 60.0))
        try:
            headers = {**self._headers(), "Content-Type": "application/octet-stream", "Content-Length": str(size)}
            try:
                conn.putrequest("PUT", f"/car/models/{urllib.parse.quote(name)}")
                for key, value in headers.items():
                    conn.putheader(key, value)
                conn.endheaders()
                sent = 0
                while chunk := f.read(CHUNK):
                    conn.send(chunk)
                    sent += len(chunk)
                    if progress is not None:
                        progress(sent, size)
                resp = conn.getresponse()
                raw = resp.read()
            except (OSError, http.client.HTTPException) as exc:
                if isinstance(exc, BrokenPipeError | ConnectionResetError):  # the car refused mid-way: its answer
                    try:
                        resp = conn.getresponse()
                        return self._answer(resp.status, resp.read())
                    except (OSError, http.client.HTTPException):
                        pass
                raise self._unreachable(exc) from exc
            return self._answer(resp.status, raw)
        finally:
            f.close()
            conn.close()

    def use(self, name: str) -> dict[str, Any]:
        """Switch the car's pilot to its model file ``name`` (POST /car/pilot); waits for the load."""
        return self.request("POST", "/car/pilot", {"model": name}, timeout=SWITCH_TIMEOUT_S)

    def open_records(self, tub: str, start: int) -> tuple[http.client.HTTPConnection, Any]:
        """The streamed records of ``tub`` from ``start`` (connection and response, to close)."""
        conn = self._connection(max(self.timeout, 30.0))
        try:
            conn.request("GET", f"/car/tubs/{urllib.parse.quote(tub)}/records?start={int(start)}",
                         headers=self._headers())
            resp = conn.getresponse()
        except (OSError, http.client.HTTPException) as exc:
            conn.close()
            raise self._unreachable(exc) from exc
        if resp.status != 200:
            raw = resp.read()
            conn.close()
            self._answer(resp.status, raw)
        return conn, resp
