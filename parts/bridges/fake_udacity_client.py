"""A faithful fake of the Udacity simulator's network side, at the websocket frame level.

Written from the protocol facts in docs/simulators.md (Udacity self-driving-car-sim, Term 1 v2:
``CommandServer.cs`` on "SocketIO for Unity" 1.0.1), never from our server, so that it fails where
the real simulator fails:

- connects to ``ws://HOST:PORT/socket.io/?EIO=4&transport=websocket`` (websocket only) and speaks
  Engine.IO v3 / Socket.IO v2: it **never sends** ``40`` and ignores ``40``, ``40{...}``, ``41``,
  ``6``;
- sends ``42["telemetry",{...}]`` twice right after the server's OPEN, then exactly one per
  received ``steer`` or ``manual`` (lockstep, no timer);
- telemetry values are all strings formatted like C#'s ``N4`` (4 decimals, in the simulator's
  locale: ``"0,1234"`` in comma mode): ``steering_angle`` in degrees (±25), ``throttle``,
  ``speed`` in mph (≤ 30.2), ``image`` a base64 JPEG of 320×160 RGB at quality 75; optional
  extra keys of research forks (``cte``, ``lapNumber``, ...);
- while the user holds W/S (:meth:`hold_manual`) it sends ``42["telemetry",null]`` and still
  expects ``manual`` or ``steer`` back;
- ``steer`` values must be JSON strings: a number makes C#'s ``float.Parse(null)`` throw, the
  exception is swallowed and no telemetry comes back (the chain stalls, counted in ``stalls``);
  in comma mode a ``"0.1"`` is read with '.' as the thousands separator (as ``float.Parse`` does
  in de/fr/it locales), so it becomes 1;
- steering is clamped to [-1, 1] (×25° reported next), throttle < 0 brakes/reverses;
- heartbeat: answers a server ``2`` with ``3``, sends its own ``2`` every 25 s, never drops the
  connection for a missing PONG;
- when the connection fails or closes it reconnects after 5 ms, like ``RunSocketThread``.

The car behind it is a small kinematic model on a straight road; the camera image shows the road
shifted by the car's lateral offset and heading, so a pilot's steering changes what it sees.
"""

from __future__ import annotations

import base64
import contextlib
import json
import logging
import math
import select
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from parts.bridges.fake_road import road_view

logger = logging.getLogger(__name__)

MAX_STEER_DEG = 25.0  # m_MaximumSteerAngle
TOP_SPEED_MPH = 30.2  # m_Topspeed 30 -> about 30.2 reported
MPH_PER_MS = 2.23693629  # what CurrentSpeed multiplies velocity.magnitude by
IMAGE_W, IMAGE_H = 320, 160
JPEG_QUALITY = 75  # Unity's EncodeToJPG default
URL_QUERY = "EIO=4&transport=websocket"  # hard-coded in SocketIOComponent.cs


@dataclass
class CarModel:
    """A small kinematic car on a straight road (SI units inside, mph and degrees outside)."""

    lateral: float = 0.0  # m, positive = right of the road centre
    heading: float = 0.0  # rad relative to the road, positive = turned right
    speed: float = 0.0  # m/s
    steer_deg: float = 0.0  # last applied steering, degrees
    throttle: float = 0.0  # last applied throttle in [-1, 1]
    wheelbase: float = 2.6  # m
    accel: float = 6.0  # m/s^2 at full throttle
    brake: float = 10.0  # m/s^2 at full brake
    drag: float = 0.15  # 1/s

    def apply(self, steering: float, throttle: float, dt: float) -> None:
        """Integrate ``dt`` seconds under normalised steering and throttle (clamped as the sim does)."""
        steering = min(1.0, max(-1.0, steering))
        self.steer_deg = steering * MAX_STEER_DEG
        self.throttle = min(1.0, max(-1.0, throttle))
        accel = max(0.0, self.throttle) * self.accel - max(0.0, -self.throttle) * self.brake
        top = TOP_SPEED_MPH / MPH_PER_MS
        self.speed = min(top, max(0.0, self.speed + (accel - self.drag * self.speed) * dt))
        self.heading += self.speed * math.tan(math.radians(self.steer_deg)) / self.wheelbase * dt
        self.heading = max(-1.2, min(1.2, self.heading))
        self.lateral += self.speed * math.sin(self.heading) * dt

    def image(self) -> np.ndarray:
        """A 320x160 RGB view of the road from the car (the road is 4 m wide)."""
        return road_view(IMAGE_W, IMAGE_H, self.lateral / 2.0, self.heading)


def n4(value: float, comma: bool = False) -> str:
    """C#'s ``ToString("N4")`` for the simulator's small values, in an en or a de/fr/it locale."""
    text = f"{value:,.4f}"  # N4 has group separators; they never show below 1000
    if comma:
        text = text.replace(",", "\0").replace(".", ",").replace("\0", ".")
    return text


def parse_like_csharp(text: str, comma: bool = False) -> float:
    """``float.Parse(text)`` in the simulator's current culture (no InvariantCulture).

    Raises ValueError where C# throws. In a comma locale '.' is the group separator, which
    ``float.Parse`` accepts anywhere in the integer part: ``"0.1"`` is read as 1.
    """
    t = text.strip()
    if comma:
        t = t.replace(".", "").replace(",", ".")
    else:
        t = t.replace(",", "")
    return float(t)


class FakeUdacityClient:
    """The Udacity simulator in autonomous mode, as seen on the wire (a thread).

    Args:
        port, host: where the drive server listens (the real simulator: 127.0.0.1:4567).
        comma_decimals: the simulator runs in a comma-decimal locale (de, fr, it ...).
        extra: fork telemetry keys and their values (strings sent as they are, numbers as N4),
            e.g. ``{"cte": 0.5, "lapNumber": 1}``; a callable value is called with the CarModel.
        dt: seconds of simulated driving per steer received (Unity frames between telemetries).
        ping_interval_s: the client's own PING period (25 s in the simulator).
        reconnect_delay_s: pause before reconnecting (5 ms in the simulator).
        keep_images: how many sent JPEGs to keep in :attr:`sent_images` (for checking a pilot).
        frame_time_s: real seconds between a ``steer``/``manual`` and the telemetry it triggers
            (Unity renders the next frame first); 0 answers at once.
    """

    def __init__(self, port: int = 4567, host: str = "127.0.0.1", *, comma_decimals: bool = False,
                 extra: dict[str, Any] | None = None, dt: float = 0.05, ping_interval_s: float = 25.0,
                 reconnect_delay_s: float = 0.005, keep_images: int = 200, frame_time_s: float = 0.0) -> None:
        self.host, self.port = host, port
        self.target = f"/socket.io/?{URL_QUERY}"
        self.comma = comma_decimals
        self.extra = dict(extra or {})
        self.dt = dt
        self.ping_interval_s = ping_interval_s
        self.reconnect_delay_s = reconnect_delay_s
        self.frame_time_s = frame_time_s
        self._due: deque[float] = deque()  # when the telemetries being rendered go out
        self.car = CarModel()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._manual = False
        # what happened, for tests
        self.connect_attempts = 0
        self.handshake_failures: list[str] = []  # "HTTP 400", "refused" ...
        self.opens = 0  # Engine.IO OPEN packets received
        self.telemetry_sent = 0
        self.null_telemetry_sent = 0
        self.steers: list[tuple[float, float]] = []  # (steering, throttle) as parsed by the "sim"
        self.raw_steers: list[dict[str, Any]] = []
        self.manuals = 0
        self.stalls = 0  # steer messages with a non-string value: no reply (the chain died)
        self.pings_answered = 0
        self.pings_sent = 0
        self.frames_received: list[str] = []  # every text frame from the server
        self.sent_images: deque[bytes] = deque(maxlen=keep_images)
        self.sent_fields: deque[dict[str, str]] = deque(maxlen=keep_images)  # telemetry without the image
        self.round_trips: list[float] = []  # seconds from a telemetry to the steer/manual answering it
        self._in_flight: deque[float] = deque()  # send times of unanswered telemetries, oldest first

    # -- control ----------------------------------------------------------------------------------
    def start(self) -> FakeUdacityClient:
        """Start connecting (in a thread); returns self."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="FakeUdacityClient", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Close the connection and end the thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)

    def __enter__(self) -> FakeUdacityClient:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def hold_manual(self, held: bool = True) -> None:
        """Hold W or S (manual override): telemetry is sent as ``null`` while held."""
        with self._lock:
            self._manual = held

    def wait_for(self, predicate: Any, timeout: float = 10.0) -> bool:
        """Poll ``predicate(self)`` until it is true or ``timeout`` seconds pass."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate(self):
                return True
            time.sleep(0.005)
        return bool(predicate(self))

    # -- the socket thread ------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.is_set():
            self.connect_attempts += 1
            try:
                ws = WebSocketClient(self.host, self.port, self.target)
            except HandshakeRejected as exc:
                self.handshake_failures.append(f"HTTP {exc.status_code}")
                self._stop.wait(self.reconnect_delay_s)
                continue
            except OSError as exc:
                self.handshake_failures.append(type(exc).__name__)
                self._stop.wait(self.reconnect_delay_s)
                continue
            try:
                self._session(ws)
            finally:
                ws.close()
            self._stop.wait(self.reconnect_delay_s)

    @property
    def in_flight(self) -> int:
        """Telemetries sent and not answered yet (0: the simulator waits for nothing, or renders)."""
        return len(self._in_flight)

    def _session(self, ws: WebSocketClient) -> None:
        next_ping = time.monotonic() + self.ping_interval_s
        self._due.clear()
        while not self._stop.is_set():
            try:
                while self._due and self._due[0] <= time.monotonic():
                    self._due.popleft()
                    self._send_telemetry(ws)
                frame = ws.receive(timeout=0.005 if self._due else 0.05)
                if time.monotonic() >= next_ping:
                    ws.send("2")  # the client's own heartbeat; a missing PONG never closes it
                    self.pings_sent += 1
                    next_ping = time.monotonic() + self.ping_interval_s
                if frame is None:
                    continue
                self.frames_received.append(frame)
                self._on_frame(ws, frame)
            except (WebSocketClosed, OSError):
                return

    def _on_frame(self, ws: WebSocketClient, frame: str) -> None:
        kind, body = frame[:1], frame[1:]
        if kind == "0":  # OPEN: "open" is raised twice (OnOpen and HandleOpen) -> two telemetries
            self.opens += 1
            self._send_telemetry(ws)
            self._send_telemetry(ws)
        elif kind == "2":
            ws.send("3")
            self.pings_answered += 1
        elif kind == "4" and body[:1] == "2" and body[1:2] == "[":  # EVENT on '/', no ack id
            try:
                event = json.loads(body[1:])
            except json.JSONDecodeError:
                return
            if not isinstance(event, list) or not event:
                return
            name, data = event[0], event[1] if len(event) > 1 else None
            if name == "steer":
                self._on_steer(ws, data)
            elif name == "manual":
                self.manuals += 1
                self._answered()
                self._next_telemetry(ws)
        # '3' PONG, '6' NOOP, '40', '40{..}', '41', ACKs, namespaced events: ignored

    def _on_steer(self, ws: WebSocketClient, data: Any) -> None:
        fields = data if isinstance(data, dict) else {}
        self.raw_steers.append(dict(fields))
        values = [fields.get("steering_angle"), fields.get("throttle")]
        # JSONObject sets .str only for JSON strings: float.Parse(null) throws, nothing is sent
        if not all(isinstance(v, str) for v in values):
            self.stalls += 1
            return
        try:
            steering, throttle = (parse_like_csharp(v, self.comma) for v in values)
        except ValueError:
            self.stalls += 1
            return
        self.steers.append((steering, throttle))
        self._answered()
        self.car.apply(steering, throttle, self.dt)
        self._next_telemetry(ws)

    def _next_telemetry(self, ws: WebSocketClient) -> None:
        """The telemetry an answer triggers: now, or after ``frame_time_s``."""
        if self.frame_time_s > 0:
            self._due.append(time.monotonic() + self.frame_time_s)
        else:
            self._send_telemetry(ws)

    def _answered(self) -> None:
        """An answer came: the oldest telemetry in flight is answered (the server answers in order)."""
        if self._in_flight:
            self.round_trips.append(time.perf_counter() - self._in_flight.popleft())

    def _send_telemetry(self, ws: WebSocketClient) -> None:
        with self._lock:
            manual = self._manual
        if manual:
            ws.send('42["telemetry",null]')
            self._in_flight.append(time.perf_counter())
            self.null_telemetry_sent += 1
            return
        from parts.tub.codec import encode_image

        jpeg, _ = encode_image(self.car.image(), "image_array", JPEG_QUALITY)
        self.sent_images.append(jpeg)
        car = self.car
        fields: dict[str, str] = {
            "steering_angle": n4(car.steer_deg, self.comma),
            "throttle": n4(car.throttle, self.comma),
            "speed": n4(car.speed * MPH_PER_MS, self.comma),
            "image": base64.b64encode(jpeg).decode("ascii"),
        }
        for key, value in self.extra.items():
            value = value(car) if callable(value) else value
            fields[key] = value if isinstance(value, str) else n4(float(value), self.comma)
        ws.send("42" + json.dumps(["telemetry", fields], separators=(",", ":")))
        self._in_flight.append(time.perf_counter())
        self.sent_fields.append({k: v for k, v in fields.items() if k != "image"})
        self.telemetry_sent += 1


class HandshakeRejected(OSError):
    """The server answered the websocket handshake with an HTTP error status."""

    def __init__(self, status_code: int) -> None:
        super().__init__(f"websocket handshake rejected with HTTP {status_code}")
        self.status_code = status_code


class WebSocketClosed(OSError):
    """The server closed the websocket."""


class WebSocketClient:
    """A blocking websocket client on wsproto, used by one thread (the simulator's socket thread).

    Frames that arrive in the same TCP segment as the ``101`` response (python-engineio sends
    OPEN at once) are kept, as websocket-sharp keeps them.
    """

    def __init__(self, host: str, port: int, target: str, timeout: float = 5.0) -> None:
        from wsproto import ConnectionType, WSConnection
        from wsproto.events import AcceptConnection, RejectConnection, Request

        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.ws = WSConnection(ConnectionType.CLIENT)
        self._texts: deque[str] = deque()
        self._partial: list[str] = []
        self._closed = False
        try:
            self.sock.sendall(self.ws.send(Request(host=f"{host}:{port}", target=target)))
            while True:
                data = self.sock.recv(65536)
                if not data:
                    raise WebSocketClosed("connection closed during the websocket handshake")
                self.ws.receive_data(data)
                for event in self.ws.events():
                    if isinstance(event, RejectConnection):
                        raise HandshakeRejected(event.status_code)
                    if isinstance(event, AcceptConnection):
                        self._handle(self.ws.events())  # frames that came with the 101
                        return
        except BaseException:
            self.sock.close()
            raise

    def _handle(self, events: Any) -> None:
        from wsproto.events import CloseConnection, Ping, TextMessage

        for event in events:
            if isinstance(event, TextMessage):
                self._partial.append(event.data)
                if event.message_finished:
                    self._texts.append("".join(self._partial))
                    self._partial = []
            elif isinstance(event, Ping):
                self.sock.sendall(self.ws.send(event.response()))
            elif isinstance(event, CloseConnection):
                with contextlib.suppress(Exception):
                    self.sock.sendall(self.ws.send(event.response()))
                self._closed = True
            # binary messages are ignored: the simulator's decoder handles text frames only

    def receive(self, timeout: float) -> str | None:
        """The next text message, or None after ``timeout`` seconds without one."""
        if self._texts:
            return self._texts.popleft()
        if self._closed:
            raise WebSocketClosed("the server closed the websocket")
        ready, _, _ = select.select([self.sock], [], [], timeout)
        if ready:
            data = self.sock.recv(65536)
            if not data:
                raise WebSocketClosed("the server closed the connection")
            self.ws.receive_data(data)
            self._handle(self.ws.events())
        return self._texts.popleft() if self._texts else None

    def send(self, text: str) -> None:
        """Send one text frame."""
        from wsproto.events import Message

        self.sock.sendall(self.ws.send(Message(data=text)))

    def close(self) -> None:
        """Close the websocket (best effort) and the socket."""
        from wsproto.connection import ConnectionState
        from wsproto.events import CloseConnection

        with contextlib.suppress(Exception):
            if self.ws.state == ConnectionState.OPEN:
                self.sock.sendall(self.ws.send(CloseConnection(code=1000)))
        self.sock.close()
