"""A faithful fake of the Donkey simulator (tawnkramer/sdsandbox) on its TCP JSON protocol.

Written from the protocol reference (shared/reference/protocols.md §3, §3.6 and §4.1) and the
simulator source it describes (``TcpCarHandler.cs``, ``JsonTcpClient.cs``, ``CarPath.cs``,
``Lines.cs``, ``CameraSensor.cs``), never from our client or server:

- a TCP server (port 9091 by default; 0 picks a free one), several clients, one car each;
- every message it sends is JSON + ``"\\n"`` with JSON numbers; client messages come without a
  newline, every value a string parsed with the invariant culture. A value that is not a JSON
  string fails as in the simulator: its JSONObject sets ``.str`` only for strings, so
  ``float.Parse(null)`` throws and the message does nothing (a ``control`` is caught and logged,
  a ``cam_config`` or ``step_mode`` aborts); so does a missing field (``ParseCamConfig`` reads fov,
  offsets, rot_x, fish-eye, img_w/h/d and img_enc unconditionally; rot_y/rot_z only if present);
- menu: ``scene_selection_ready`` on connect, ``get_scene_names`` -> ``scene_names``,
  ``load_scene`` -> ``car_loaded``, ``get_protocol_version`` -> ``"2"``, race variant
  ``need_car_config`` (answered by ``racer_info`` + ``car_config``);
- after ``car_loaded`` it pushes ``telemetry`` at 20 Hz whatever the client does, with
  ``time`` increasing: steering, throttle, speed, a JPEG camera frame (160x120, or ``cam_config``'s
  ``img_w``/``img_h``; ``img_d`` 1 makes it grey), ``hit`` (reported once, then ``"none"``),
  position, velocity, IMU, ``cte`` and ``activeNode``/``totalNodes``. ``cte`` has
  ``CarPath.GetCrossTrackErr``'s sign: the segment direction is ``a - b`` (``Line3d.m_dir``, against
  the driving direction), the error vector points from the path to the car, and the sign is
  negative when ``cross(m_dir, err).y > 0``; in Unity's left-handed frame (y up) that makes it
  **positive right of the path**;
- ``control`` steers a small car model (steering clamped to [-1, 1] x 16 deg, throttle [-1, 1],
  brake [0, 1]); the reported steering is the applied, normalised one;
- ``reset_car`` puts the car back before the start line, controls zeroed, at the next physics
  step (``FixedUpdate``); ``exit_scene`` goes back to the menu; ``quit_app`` closes; ``car_config``,
  ``cam_config_b``, ``lidar_config``, ``racer_info`` are accepted and kept;
- ``step_mode`` (older builds: ``settings``) ``synchronous`` sets Unity's ``Time.timeScale`` to 0:
  the whole simulator stops (no physics step, no telemetry, for every car) and nothing restarts it
  (a later ``asynchronous`` only clears a flag), exactly as ``OnStepModeRecv`` does;
- ``collision_with_starting_line`` each time the car crosses the start line (the car spawns just
  before it), ``hit`` on a scripted crash (:meth:`FakeDonkeySim.crash`) or at a wall beyond
  ``wall_cte``.

Fidelity knobs: ``strict`` (each received chunk must be exactly one JSON object, as
``JsonTcpClient.OnDataRecv`` assumes: coalesced messages are lost and counted), ``comma_floats``
(Unity on a comma-decimal locale writes ``"cte":1,25``), ``imageb`` (camera 2 as ``imageb``),
``latency_s``, ``drop_every`` (telemetry dropped), ``merge_every`` (two messages in one send),
``split_every`` (one message in two sends).

The track is a circle of radius 20 units, road half-width 4 (gym's ``max_cte`` 8 is off the road
by a margin); the car model is kinematic.
"""

from __future__ import annotations

import base64
import contextlib
import json
import logging
import math
import re
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

logger = logging.getLogger(__name__)

SCENES = ("generated_road", "warehouse", "sparkfun_avc", "generated_track", "mountain_track",
          "roboracingleague_1", "waveshare", "mini_monaco", "warren", "thunderhill", "circuit_launch")
TRACK_RADIUS = 20.0  # units
ROAD_HALF_WIDTH = 4.0  # units
TOTAL_NODES = 200
STEER_DEG = 16.0


@dataclass
class FakeCar:
    """One connection's car and what its client sent."""

    s: float = -1.0  # distance along the track from the start line (spawns just before it)
    right: float = 0.0  # lateral offset, positive = right of the path
    heading: float = 0.0  # relative to the path, rad, positive = turned right
    speed: float = 0.0
    steering: float = 0.0  # applied, normalised
    throttle: float = 0.0
    brake: float = 0.0
    time: float = 0.0  # Time.timeSinceLevelLoad
    laps_crossed: int = 0
    reset_pending: bool = False  # reset_car waits for the next physics step
    pending_hit: str = "none"
    at_wall: bool = False
    img_w: int = 160
    img_h: int = 120
    img_d: int = 3
    img_enc: str = "JPG"
    scene: str | None = None
    step_mode: str = "asynchronous"
    received: list[dict[str, Any]] = field(default_factory=list)
    parse_failures: int = 0
    rejected: list[str] = field(default_factory=list)  # msg_types whose handler threw (bad or missing field)
    telemetry_sent: int = 0
    closed: bool = False

    def reset(self) -> None:
        """``reset_car``: back before the start line, standing, controls zero."""
        self.s, self.right, self.heading, self.speed = -1.0, 0.0, 0.0, 0.0
        self.steering = self.throttle = self.brake = 0.0
        self.laps_crossed = 0
        self.at_wall = False

    def step(self, dt: float, wall_cte: float) -> list[float]:
        """Advance ``dt`` seconds; returns the times at which the start line was crossed."""
        accel = 8.0 * self.throttle - 15.0 * self.brake * (1 if self.speed > 0 else 0) - 0.5 * self.speed
        self.speed = max(-3.0, min(15.0, self.speed + accel * dt))
        turn = self.speed * math.tan(math.radians(self.steering * STEER_DEG)) / 1.5
        self.heading += (turn + self.speed / TRACK_RADIUS) * dt  # the road bends left
        self.right += self.speed * math.sin(self.heading) * dt
        before = self.s
        self.s += self.speed * math.cos(self.heading) * dt
        self.time += dt
        length = 2 * math.pi * TRACK_RADIUS
        crossings = []
        if math.floor(self.s / length) > math.floor(before / length) and self.s > 0:
            crossings.append(self.time)
        wall = abs(self.right) > wall_cte
        if wall and not self.at_wall:
            self.pending_hit = "wall"
        self.at_wall = wall
        return crossings

    def telemetry(self, image: str, imageb: str | None) -> dict[str, Any]:
        """The telemetry fields of the current state."""
        length = 2 * math.pi * TRACK_RADIUS
        angle = (self.s % length) / TRACK_RADIUS  # polar angle of the path point
        radius = TRACK_RADIUS + self.right  # right of a left-bending circle = outside
        yaw = -math.degrees(angle) + math.degrees(self.heading)
        msg: dict[str, Any] = {
            "msg_type": "telemetry", "steering_angle": self.steering, "throttle": self.throttle,
            "speed": abs(self.speed), "image": image, "hit": self.pending_hit, "time": self.time,
            "accel_x": 0.0, "accel_y": 0.0, "accel_z": 0.0, "gyro_x": 0.0, "gyro_y": 0.0, "gyro_z": 0.0,
            "pitch": 0.0, "yaw": yaw % 360.0, "roll": 0.0,
            "cte": self.right,  # CarPath.GetCrossTrackErr: positive right of the path (module docstring)
            "activeNode": int((self.s % length) / length * TOTAL_NODES), "totalNodes": TOTAL_NODES,
            "pos_x": radius * math.cos(angle), "pos_y": 0.0, "pos_z": radius * math.sin(angle),
            "vel_x": -self.speed * math.sin(angle), "vel_y": 0.0, "vel_z": self.speed * math.cos(angle),
        }
        if imageb is not None:
            msg["imageb"] = imageb
        self.pending_hit = "none"
        return msg


class FakeDonkeySim:
    """The Donkey simulator as seen on the wire (threads; :meth:`start` / :meth:`stop`).

    Args:
        port, host: where to listen (0 = a free port, read :attr:`port`).
        telemetry_hz: telemetry rate after ``car_loaded`` (20 in the simulator).
        scenes: scene names offered.
        strict: parse each received chunk as exactly one message, as the real simulator does.
        race: send ``need_car_config`` after ``car_loaded`` (race scenes).
        comma_floats: write floats with decimal commas (Unity on a de/fr/it Windows).
        imageb: also send camera 2 as ``imageb``.
        latency_s: delay before each message is sent.
        drop_every, merge_every, split_every: drop every Nth telemetry; send every Nth message glued
            to the next in one ``send``; send every Nth message in two parts.
        wall_cte: |offset| at which the car hits a wall (``hit`` = "wall").
        time_scale: simulated seconds per real second (tests drive laps faster than real time).
    """

    def __init__(self, port: int = 9091, host: str = "127.0.0.1", *, telemetry_hz: float = 20.0,
                 scenes: tuple[str, ...] = SCENES, strict: bool = False, race: bool = False,
                 comma_floats: bool = False, imageb: bool = False, latency_s: float = 0.0,
                 drop_every: int = 0, merge_every: int = 0, split_every: int = 0, wall_cte: float = 12.0,
                 time_scale: float = 1.0) -> None:
        self.host, self.port = host, port
        self.period = 1.0 / telemetry_hz  # real seconds between telemetries
        self.dt = time_scale / telemetry_hz  # simulated seconds per telemetry
        self.scenes = scenes
        self.strict, self.race, self.comma_floats, self.imageb = strict, race, comma_floats, imageb
        self.latency_s = latency_s
        self.drop_every, self.merge_every, self.split_every = drop_every, merge_every, split_every
        self.wall_cte = wall_cte
        self.cars: list[FakeCar] = []
        self.time_scale_zero = False  # a step_mode synchronous stopped the whole simulator
        self._server: socket.socket | None = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._sockets: list[socket.socket] = []
        self._lock = threading.Lock()

    # -- control ----------------------------------------------------------------------------------
    def start(self) -> FakeDonkeySim:
        """Listen and accept clients in a thread; returns self."""
        server = socket.create_server((self.host, self.port))
        self.port = server.getsockname()[1]
        server.settimeout(0.1)
        self._server = server
        self._spawn(self._accept)
        return self

    def stop(self) -> None:
        """Close every connection and the listening socket."""
        self._stop.set()
        self.drop_clients()
        for thread in self._threads:
            thread.join(5)
        if self._server is not None:
            self._server.close()

    def __enter__(self) -> FakeDonkeySim:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def drop_clients(self) -> None:
        """Close every client connection (the simulator crashed or quit)."""
        with self._lock:
            sockets, self._sockets = list(self._sockets), []
        for sock in sockets:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()

    def crash(self, car: int = 0, obstacle: str = "cone") -> None:
        """Make car ``car`` hit ``obstacle``: its next telemetry reports it once."""
        self.cars[car].pending_hit = obstacle

    def messages(self, car: int = 0, msg_type: str | None = None) -> list[dict[str, Any]]:
        """What client ``car`` sent (all, or those of one type)."""
        received = list(self.cars[car].received)
        return [m for m in received if msg_type is None or m.get("msg_type") == msg_type]

    def wait_for(self, predicate: Any, timeout: float = 10.0) -> bool:
        """Poll ``predicate(self)`` until true or ``timeout`` seconds pass."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                if predicate(self):
                    return True
            except (IndexError, KeyError):
                pass
            time.sleep(0.005)
        return bool(predicate(self))

    # -- threads ----------------------------------------------------------------------------------
    def _spawn(self, target: Any, *args: Any) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True, name="FakeDonkeySim")
        self._threads.append(thread)
        thread.start()

    def _accept(self) -> None:
        assert self._server is not None
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            car = FakeCar()
            with self._lock:
                self.cars.append(car)
                self._sockets.append(conn)
            self._spawn(_Connection(self, conn, car).run)


class _Connection:
    """One client: a reader (this thread) and a telemetry pusher (another)."""

    def __init__(self, sim: FakeDonkeySim, sock: socket.socket, car: FakeCar) -> None:
        self.sim, self.sock, self.car = sim, sock, car
        self.send_lock = threading.Lock()
        self.sent = 0
        self.held: bytes | None = None  # a message waiting to be glued to the next one
        self.buffer = b""
        self.loaded = threading.Event()
        self.alive = True

    def run(self) -> None:
        self.send({"msg_type": "scene_selection_ready", "loaded": "1"})
        self.sim._spawn(self._push_telemetry)
        self.sock.settimeout(0.1)
        try:
            while self.alive and not self.sim._stop.is_set():
                try:
                    chunk = self.sock.recv(65536)
                except TimeoutError:
                    continue
                if not chunk:
                    break
                for msg in self._parse(chunk):
                    self.car.received.append(msg)
                    self._handle(msg)
        except OSError:
            pass
        finally:
            self.alive = False
            self.car.closed = True
            self.loaded.clear()
            self.sock.close()

    def _parse(self, chunk: bytes) -> list[dict[str, Any]]:
        if self.sim.strict:  # JsonTcpClient.OnDataRecv: one chunk is one message
            try:
                msg = json.loads(chunk.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError):
                self.car.parse_failures += 1
                return []
            return [msg] if isinstance(msg, dict) else []
        self.buffer += chunk
        text = self.buffer.decode("utf-8", errors="replace")
        decoder = json.JSONDecoder()
        out, pos = [], 0
        while True:
            start = text.find("{", pos)
            if start < 0:
                pos = len(text)
                break
            try:
                msg, end = decoder.raw_decode(text, start)
            except json.JSONDecodeError:
                pos = start
                break  # incomplete: wait for more
            out.append(msg)
            pos = end
        self.buffer = text[pos:].encode("utf-8")
        return [m for m in out if isinstance(m, dict)]

    def _handle(self, msg: dict[str, Any]) -> None:
        kind, car = msg.get("msg_type"), self.car
        if kind == "get_scene_names":
            self.send({"msg_type": "scene_names", "scene_names": list(self.sim.scenes)})
        elif kind == "load_scene" and car.scene is None:
            if msg.get("scene_name") in self.sim.scenes:
                car.scene = msg["scene_name"]
                car.reset()
                car.time = 0.0
                self.send({"msg_type": "car_loaded"})
                if self.sim.race:
                    self.send({"msg_type": "need_car_config"})
                self.loaded.set()
        elif kind == "get_protocol_version":
            self.send({"msg_type": "protocol_version", "version": "2"})
        elif kind == "control":
            try:  # OnControlsRecv catches the exception and logs it: the control does nothing
                steering, throttle, brake = (_invariant(msg, k) for k in ("steering", "throttle", "brake"))
            except ValueError:
                car.rejected.append(kind)
                return
            car.steering = _clamp(steering, -1.0, 1.0)
            car.throttle = _clamp(throttle, -1.0, 1.0)
            car.brake = _clamp(brake, 0.0, 1.0)
        elif kind == "reset_car":
            car.reset_pending = True  # bResetCar: applied in the next FixedUpdate
        elif kind == "exit_scene":
            self.loaded.clear()
            car.scene = None
            self.send({"msg_type": "scene_selection_ready", "loaded": "1"})
        elif kind == "quit_app":
            self.alive = False
        elif kind == "cam_config":
            self._cam_config(msg)
        elif kind in ("step_mode", "settings"):
            try:
                mode = _field(msg, "step_mode")
                _invariant(msg, "time_step")
            except ValueError:
                car.rejected.append(kind)
                return
            car.step_mode = mode
            if mode == "synchronous":
                self.sim.time_scale_zero = True  # Time.timeScale = 0: nothing steps any more
        # car_config, cam_config_b, lidar_config, racer_info: accepted, kept in received

    def _cam_config(self, msg: dict[str, Any]) -> None:
        """``ParseCamConfig`` + ``CameraSensor.SetConfig``: every field parsed first (one missing
        or non-string field throws and nothing is applied), then 0 keeps the current value."""
        car = self.car
        try:
            for key in ("fov", "offset_x", "offset_y", "offset_z", "rot_x", "fish_eye_x", "fish_eye_y"):
                _invariant(msg, key)
            for key in ("rot_y", "rot_z"):
                if key in msg:
                    _invariant(msg, key)
            width, height, depth = (_int_parse(msg, k) for k in ("img_w", "img_h", "img_d"))
            encoding = _field(msg, "img_enc")
        except ValueError:
            car.rejected.append("cam_config")
            return
        if depth != 0:
            car.img_d = depth
        if width != 0 and height != 0:
            car.img_w, car.img_h = width, height
        if len(encoding) == 3:
            car.img_enc = encoding

    def _push_telemetry(self) -> None:
        next_at = time.monotonic()
        index = 0
        while self.alive and not self.sim._stop.is_set():
            if not self.loaded.wait(0.05):
                next_at = time.monotonic()
                continue
            next_at += self.sim.period
            delay = next_at - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                next_at = time.monotonic()
            if not self.loaded.is_set() or self.sim.time_scale_zero:
                continue  # in the menu, or Time.timeScale = 0: no FixedUpdate, no telemetry
            car = self.car
            if car.reset_pending:
                car.reset_pending = False
                car.reset()
            for stamp in car.step(self.sim.dt, self.sim.wall_cte):
                car.laps_crossed += 1
                self.send({"msg_type": "collision_with_starting_line", "starting_line_index": 0,
                           "timeStamp": stamp})
            index += 1
            if self.sim.drop_every and index % self.sim.drop_every == 0:
                continue  # dropped: a hit waits for the next frame
            image = _jpeg(car)
            self.send(car.telemetry(image, image if self.sim.imageb else None))
            car.telemetry_sent += 1

    def send(self, msg: dict[str, Any]) -> None:
        text = json.dumps(msg, separators=(",", ":"))
        if self.sim.comma_floats:
            text = _comma_floats(text)
        data = (text + "\n").encode("utf-8")
        if self.sim.latency_s:
            time.sleep(self.sim.latency_s)
        with self.send_lock:
            self.sent += 1
            n = self.sent
            try:
                if self.sim.merge_every and n % self.sim.merge_every == 0 and self.held is None:
                    self.held = data  # goes out glued to the next message
                    return
                if self.held is not None:
                    data, self.held = self.held + data, None
                if self.sim.split_every and n % self.sim.split_every == 0 and len(data) > 2:
                    half = len(data) // 2
                    self.sock.sendall(data[:half])
                    time.sleep(0.01)
                    self.sock.sendall(data[half:])
                else:
                    self.sock.sendall(data)
            except OSError:
                self.alive = False


def _field(msg: dict[str, Any], key: str) -> str:
    """``json.GetField(key).str``: the text of a JSON string; ValueError where C# would throw (a
    missing field, or a number, whose ``.str`` is null)."""
    value = msg.get(key)
    if not isinstance(value, str):
        raise ValueError(f"{key}: {value!r} is not a JSON string")
    return value


def _invariant(msg: dict[str, Any], key: str) -> float:
    """``float.Parse(json.GetField(key).str, CultureInfo.InvariantCulture)``."""
    text = _field(msg, key).strip()
    if not re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", text):
        raise ValueError(f"{key}: {text!r} is not an invariant-culture number")
    return float(text)


def _int_parse(msg: dict[str, Any], key: str) -> int:
    """``int.Parse(json.GetField(key).str)``: digits with an optional sign, nothing else."""
    text = _field(msg, key).strip()
    if not re.fullmatch(r"[-+]?\d+", text):
        raise ValueError(f"{key}: {text!r} is not an integer")
    return int(text)


def _clamp(value: float, low: float, high: float) -> float:
    return min(high, max(low, value))


_FLOAT = re.compile(r'(?<=[:,\[])(-?\d+)\.(\d+(?:[eE][-+]?\d+)?)(?=[,}\]])')


def _comma_floats(text: str) -> str:
    """Unity's float formatting on a comma-decimal locale: ``1.25`` -> ``1,25`` outside strings."""
    parts = text.split('"')
    for i in range(0, len(parts), 2):  # even parts are outside strings
        parts[i] = _FLOAT.sub(r"\1,\2", parts[i])
    return '"'.join(parts)


def _jpeg(car: FakeCar) -> str:
    from parts.bridges.fake_road import road_view
    from parts.tub.codec import encode_image

    picture = road_view(car.img_w, car.img_h, car.right / ROAD_HALF_WIDTH, car.heading)
    if car.img_d == 1:  # CameraSensor: grey, still three channels
        picture = np.repeat(picture.mean(axis=2, keepdims=True).astype(np.uint8), 3, axis=2)
    data, _ = encode_image(picture, "image_array", 75)
    return base64.b64encode(data).decode("ascii")
