"""Fixtures for the web controller tests: a real server on 127.0.0.1 (ephemeral port), a real
python-socketio client, a raw protocol client, a fake camera, the loop side driven by the test, and
real cars (a Vehicle in a thread) for the browser tests."""

from __future__ import annotations

import asyncio
import re
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fixtures.load import scaled

from parts.web.controller import WebController

pytest.importorskip("socketio")
pytest.importorskip("aiohttp")


def make_frame(i: int, h: int = 120, w: int = 160) -> np.ndarray:
    """A test frame: a white column that moves with ``i`` on a dark gradient."""
    img = np.zeros((h, w, 3), np.uint8)
    img[:, :, 2] = np.linspace(0, 120, w, dtype=np.uint8)
    img[:, i % w] = 255
    return img


class LoopSide:
    """Plays the drive loop: calls run_threaded with telemetry and returns the outputs by key."""

    def __init__(self, part: WebController) -> None:
        self.part = part
        self.telemetry: dict[str, Any] = {k: None for k in WebController.INPUTS}
        self.telemetry["pilot/model"] = "a.pt"  # a car with a pilot (step(pilot__model=None): without)
        self.i = 0

    def step(self, **telemetry: Any) -> dict[str, Any]:
        self.telemetry.update({k.replace("__", "/"): v for k, v in telemetry.items()})
        if self.telemetry.get("cam/image_array") is None:
            self.telemetry["cam/image_array"] = make_frame(self.i)
        self.i += 1
        out = self.part.run_threaded(*(self.telemetry[k] for k in WebController.INPUTS))
        result = dict(zip(WebController.OUTPUTS, out, strict=True))
        # feed back what a car's memory would hold next loop
        self.telemetry["user/mode"] = result["user/mode"]
        self.telemetry["recording"] = result["recording"]
        self.telemetry["estop"] = result["estop"]
        self.telemetry["cam/image_array"] = None
        return result

    async def until(self, cond: Callable[[dict[str, Any]], bool], timeout: float = 5.0,
                    **telemetry: Any) -> dict[str, Any]:
        """Step every 10 ms until ``cond(outputs)`` holds; fail after ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while True:
            out = self.step(**telemetry)
            if cond(out):
                return out
            if time.monotonic() > end:
                raise AssertionError(f"condition not met within {timeout} s; last outputs {out}")
            await asyncio.sleep(0.01)


class Client:
    """A python-socketio AsyncClient that records what the server sends."""

    def __init__(self, ack_frames: bool = True) -> None:
        import socketio

        self.sio = socketio.AsyncClient(reconnection=False)
        self.hello: asyncio.Future[dict[str, Any]] | None = None
        self.states: list[dict[str, Any]] = []
        self.frames: list[bytes] = []
        self.roles: list[dict[str, Any]] = []
        self.ack_frames = ack_frames
        self._never: asyncio.Future[None] | None = None
        self.sio.on("hello", self._on_hello)
        self.sio.on("state", self.states.append)
        self.sio.on("roles", self.roles.append)
        self.sio.on("frame", self._on_frame)
        self.connect_errors: list[Any] = []
        self.sio.on("connect_error", self.connect_errors.append)

    def _on_hello(self, data: dict[str, Any]) -> None:
        if self.hello is not None and not self.hello.done():
            self.hello.set_result(data)

    async def _on_frame(self, data: bytes) -> bool:
        self.frames.append(data)
        if not self.ack_frames:  # a stalled viewer: never acknowledge
            self._never = asyncio.get_running_loop().create_future()
            await self._never
        return True

    async def connect(self, port: int, token: str | None = None,
                      headers: dict[str, str] | None = None) -> dict[str, Any]:
        self.hello = asyncio.get_running_loop().create_future()
        try:
            await self.sio.connect(f"http://127.0.0.1:{port}", transports=["websocket"],
                                   auth={"token": token} if token else None, wait_timeout=5,
                                   headers=headers or {})
        except Exception:
            http = getattr(self.sio.eio, "http", None)
            if http is not None and not http.closed:
                await http.close()  # the client leaves its session open after a refusal
            raise
        return await asyncio.wait_for(self.hello, 5)

    async def call(self, event: str, data: Any = None) -> Any:
        return await self.sio.call(event, data, timeout=5)

    async def close(self) -> None:
        if self._never is not None and not self._never.done():
            self._never.cancel()
        await self.sio.disconnect()


@pytest.fixture
def models_dir(tmp_path: Path) -> Path:
    d = tmp_path / "models"
    d.mkdir()
    (d / "a.pt").write_bytes(b"not a real model")
    (d / "b.pt").write_bytes(b"not a real model")
    (d / "notes.txt").write_text("not listed")
    return d


@pytest.fixture
def web_factory(models_dir: Path) -> Iterator[Callable[..., WebController]]:
    """Start WebControllers on free ports; all are shut down after the test."""
    started: list[WebController] = []

    def make(**kwargs: Any) -> WebController:
        kwargs.setdefault("port", 0)
        kwargs.setdefault("deadman_s", 0.3)
        kwargs.setdefault("models_dir", models_dir)
        part = WebController(**kwargs).start()
        started.append(part)
        return part

    yield make
    for part in started:
        part.shutdown()
        assert not part.running


@pytest.fixture
def web(web_factory: Callable[..., WebController]) -> WebController:
    return web_factory()


@pytest.fixture
def loop_side(web: WebController) -> LoopSide:
    return LoopSide(web)


def run(coro: Any) -> Any:
    """Run a test coroutine (no pytest-asyncio needed)."""
    return asyncio.run(asyncio.wait_for(coro, scaled(30)))  # a guard that grows with the machine's load


@pytest.fixture
def arun() -> Callable[[Any], Any]:
    """Run a test coroutine: ``arun(main())``."""
    return run


@pytest.fixture
def client_cls() -> type[Client]:
    """The recording Socket.IO client class: ``c = client_cls(); await c.connect(port)``."""
    return Client


class RawSocketIO:
    """A Socket.IO v5 client over Engine.IO v4 WebSocket written from the protocol, that sends
    WebSocket messages exactly as given (hostile ones too). On the wire, ``42<id>[event, data]`` is
    an Engine.IO MESSAGE (``4``) holding a Socket.IO EVENT (``2``) with an acknowledgement id,
    answered by ``43<id>[reply]`` (MESSAGE, ACK)."""

    def __init__(self) -> None:
        self.http: Any = None
        self.ws: Any = None
        self.events: list[str] = []

    async def connect(self, port: int) -> dict[str, Any]:
        import json

        import aiohttp

        self.http = aiohttp.ClientSession()
        self.ws = await self.http.ws_connect(f"http://127.0.0.1:{port}/socket.io/?EIO=4&transport=websocket")
        opened = await self._text(engineio=True)
        assert opened.startswith("0"), opened  # Engine.IO OPEN with the session's settings
        await self.ws.send_str("40")  # MESSAGE: Socket.IO CONNECT to the main namespace
        while True:
            text = await self._text()
            if text.startswith("0"):  # Socket.IO CONNECT answered: {"sid": ...}
                return json.loads(text[1:])
            self.events.append(text)

    async def _text(self, timeout: float = 5.0, engineio: bool = False) -> str:
        """The next Socket.IO packet (``engineio``: the next Engine.IO packet as it came)."""
        import aiohttp

        while True:
            msg = await asyncio.wait_for(self.ws.receive(), timeout)
            if msg.type != aiohttp.WSMsgType.TEXT:
                raise ConnectionError(f"connection closed ({msg.type.name})")
            if msg.data == "2":  # Engine.IO PING: answer PONG
                await self.ws.send_str("3")
                continue
            if engineio:
                return msg.data
            if msg.data.startswith("4"):  # Engine.IO MESSAGE: a Socket.IO packet follows
                return msg.data[1:]

    async def send(self, message: str) -> None:
        """Send one WebSocket message as given (e.g. ``42["drive",{...}]``)."""
        await self.ws.send_str(message)

    async def call(self, message: str, timeout: float = 5.0) -> Any:
        """Send an event message with an ack id and return the acknowledgement's first value."""
        import json
        import re

        ack_id = re.match(r"42(\d+)", message).group(1)
        await self.send(message)
        while True:
            text = await self._text(timeout)
            if text.startswith(f"3{ack_id}["):
                return json.loads(text[len(ack_id) + 1:])[0]
            if not text.startswith("3"):
                self.events.append(text)  # events (hello, state, frame) until the acknowledgement

    @property
    def closed(self) -> bool:
        return self.ws is None or self.ws.closed

    async def close(self) -> None:
        if self.ws is not None:
            await self.ws.close()
        if self.http is not None:
            await self.http.close()


@pytest.fixture
def raw_client() -> type[RawSocketIO]:
    """The raw protocol client class: ``c = raw_client(); await c.connect(port)``."""
    return RawSocketIO


# -- real cars for the browser tests ---------------------------------------------------------------
class FakeCamera:
    """A camera part: a bright column moving over a dark frame."""

    OUTPUTS = ("cam/image_array",)

    def __init__(self) -> None:
        self.i = 0

    def run(self) -> np.ndarray:
        self.i += 1
        img = np.full((120, 160, 3), 30, np.uint8)
        img[:, self.i % 160] = 255
        return img


class Car:
    """A real Vehicle running in a thread at 40 Hz (real time), as a context manager or with
    :meth:`start` / :meth:`stop`. On stop the browser's pages (if given) are closed first."""

    def __init__(self, V: Any, web: WebController, browser: Any = None) -> None:
        self.V, self.web, self.browser = V, web, browser
        self.errors: list[BaseException] = []
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.stopped = False

    def _run(self) -> None:
        try:
            self.V.start(rate_hz=40)
        except BaseException as exc:
            self.errors.append(exc)

    def start(self) -> Car:
        self.thread.start()
        end = time.monotonic() + 10
        while self.web.port == 0 and time.monotonic() < end:
            time.sleep(0.01)
        return self

    def stop(self) -> None:
        if self.stopped:
            return
        self.stopped = True
        if self.browser is not None:
            for context in self.browser.contexts:
                context.close()
        self.V.stop()
        self.thread.join(10)
        assert not self.errors, self.errors

    def __enter__(self) -> Car:
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def until(self, cond: Callable[[Any], bool], timeout: float = 5.0, what: str = "") -> None:
        """Wait until ``cond(vehicle memory)`` holds; fail after ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while not cond(self.V.mem):
            if time.monotonic() > end:
                raise AssertionError(f"vehicle memory condition not met: {what}; "
                                     f"user/angle={self.V.mem['user/angle']} "
                                     f"user/throttle={self.V.mem['user/throttle']}")
            time.sleep(0.01)


def build_car(car_path: Path, browser: Any = None, *, sim: bool = False, model: Path | None = None,
              tub: bool = False, path_follow: bool = False, **settings: Any) -> Car:
    """The car as manage.py drive assembles it (not started): the simulator or a fake camera, the
    web page, a pilot when ``model`` is given, the path-follow parts with ``path_follow`` (in the
    simulator: its simulated sensors, as the path_follow template's ``drive --sim``), the drive
    mode, a tub writer with ``tub``."""
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.config import Config

    settings = {"WEB_CONTROL_PORT": 0, "WEB_MAX_THROTTLE": 1.0, "PILOT_BACKEND": "torch", **settings}
    cfg = Config.defaults(CAR_PATH=str(car_path), **settings)
    if path_follow:
        from vehicle.app.path_sim import sensor_config

        cfg = sensor_config(cfg, cfg.PATH_LOCALIZER)
    V = Vehicle()
    if sim:
        assembly.add_simulator(V, cfg)
    else:
        V.add(FakeCamera())
    web = assembly.add_controller(V, cfg)
    if model is not None:
        assembly.add_pilot(V, cfg, model)
    if path_follow:
        assembly.add_path_follow(V, cfg)
    assembly.add_drive_mode(V, cfg)
    assembly.add_speed_limit(V, cfg)
    if tub:
        assembly.add_tub_writer(V, cfg)
    return Car(V, web, browser)


@pytest.fixture
def make_car(tmp_path: Path) -> Iterator[Callable[..., Car]]:
    """``make_car(sim=False, model=None, tub=False, path_follow=False, **settings)``: a started car (see
    :func:`build_car`), stopped after the test."""
    cars: list[Car] = []

    def make(**kwargs: Any) -> Car:
        car = build_car(tmp_path, **kwargs).start()
        cars.append(car)
        return car

    yield make
    for car in cars:
        car.stop()


#: viewports of the browser tests, CSS pixels
DESKTOP = {"width": 1280, "height": 800}


@pytest.fixture
def open_page(new_page: Callable[..., Any]) -> Callable[..., Any]:
    """``open_page(url, viewport=DESKTOP, touch=False, role="driver", init_script=None,
    route_socket=None)``: a page in its own browser context (a phone's with ``touch``), connected
    with that role."""

    def open_(url: str, viewport: dict[str, int] | None = None, touch: bool = False,
              role: str | None = "driver", init_script: str | None = None,
              route_socket: Callable[[Any], None] | None = None) -> Any:
        page = new_page(device="phone" if touch else "desktop", viewport=viewport or DESKTOP)
        if init_script:
            page.add_init_script(init_script)
        if route_socket:  # sees (and may hold) every WebSocket message between page and car
            page.route_web_socket(re.compile(r".*/socket\.io/.*"), route_socket)
        page.goto(url)
        if role:
            page.wait_for_function(f"window.webStats && webStats.connected && webStats.role === '{role}'")
        return page

    return open_



@pytest.fixture
def fake_car() -> Callable[..., Car]:
    """:func:`build_car` (``fake_car(tmp_path, browser, **settings)``, a context manager that
    starts the car and stops it, its pages closed first)."""
    return build_car
