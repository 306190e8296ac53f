"""The Donkey simulator as a car: we are the TCP JSON client of the simulator (or of
``vehicle sim serve``).

>>> sim = DonkeySim("127.0.0.1", 9091, scene="generated_track")
>>> V.add(sim, inputs=list(DonkeySim.INPUTS), outputs=list(DonkeySim.OUTPUTS),
...       threaded=True)                                  # doctest: +SKIP

On start the part connects (retrying for ``connect_timeout_s``: the simulator may still be
starting), follows the simulator's session sequence (``scene_selection_ready`` ->
``get_scene_names`` -> ``load_scene`` -> ``car_loaded``), holds the car with the hand brake, then
sends ``car_config`` (body, colour, name: DonkeyCar's ``GYM_CONF``) and ``cam_config`` (the camera
size; every field the simulator reads, "0" for "keep the default", as gym-donkeycar sends it).
Configuration messages go out 0.1 s apart and every message in its own ``send``: the simulator reads
each TCP chunk as one message.

``synchronous=True`` asks for step mode only where it steps: ``vehicle sim serve`` says so in its
``protocol_version`` reply. The Donkey simulator's ``step_mode`` synchronous only pauses it (Unity
``Time.timeScale = 0``: telemetry stops for good), so against it the part says so in one line and
stays in real time (:attr:`DonkeySim.synchronous` is then False).

Threaded (a drive loop): the simulator pushes telemetry at its own rate (20 Hz); the part keeps the
latest and never blocks; each loop's ``angle``/``throttle`` goes out as one ``control`` (a one-slot
mailbox: an unsent command is replaced by a newer one). When the loop gives no command for
``command_timeout_s`` (it is stuck) the car gets one braking neutral ``control``, as an actuator
watchdog would. Non-threaded (:meth:`DonkeySim.run`, used by evaluation): each call sends the
command and waits for the next telemetry, so in step mode every call is one simulation step, as
fast as both sides can go.

A rising ``sim/reset`` sends ``reset_car``. A lost connection marks the camera stale (``cam/ok``
False, so the camera watchdog takes the pilot out), says so once and never blocks the loop; the
next :meth:`start` connects again. Shutdown sends a neutral, braking ``control`` and
``exit_scene``.

Outputs: ``cam/image_array`` (RGB, image_w x image_h; a simulator that sends another size is told
in one log line and its frames are resized), ``cam/timestamp``, ``cam/ok``, ``cam/frame_id``
(counts telemetry frames), ``sim/speed`` and ``enc/speed`` (the simulator's speed), ``sim/cte``
(the simulator's, positive = right of the path as everywhere in this project), ``sim/hit``
(obstacle name or "none"; a hit is kept until the loop has seen it), ``sim/off_track`` (the end of a
gym-donkeycar episode, decided in its order: |cte| > 2 max_cte is a spawn glitch and ends nothing,
|cte| > max_cte, a hit; a ``missed_checkpoint`` or ``DQ`` of a race holds it until the next reset),
``sim/lap`` (laps completed since the part connected; a reset keeps the count), ``sim/lap_time``
(from ``collision_with_starting_line``, gym-donkeycar's rule), ``sim/progress`` (activeNode /
totalNodes), ``sim/pos`` ((pos_x, pos_z), the ground plane), ``sim/time`` and ``sim/extra`` (every
other telemetry field: gyro, accel, vel, pitch/yaw/roll, lidar ...).
"""

from __future__ import annotations

import collections
import contextlib
import logging
import selectors
import socket
import threading
import time
from dataclasses import dataclass
from typing import Any, ClassVar, Final

import numpy as np

from parts.bridges import donkey_protocol as proto
from parts.bridges.errors import BridgeError
from parts.bridges.frames import decode_frame
from vehicle.config import ConfigError
from vehicle.part import ThreadedPart

logger = logging.getLogger(__name__)

CONFIG_GAP_S: Final = 0.1  # what gym-donkeycar sleeps after each configuration message
#: telemetry fields with an output of their own (everything else goes to sim/extra)
_OWN_FIELDS: Final = frozenset({"msg_type", "image", "imageb", "image_b", "speed", "cte", "hit", "time",
                                "pos_x", "pos_y", "pos_z"})


@dataclass(frozen=True)
class CarLook:
    """How the car looks in the simulator (DonkeyCar's ``GYM_CONF``)."""

    body_style: str = "donkey"
    body_rgb: tuple[int, int, int] = (128, 128, 128)
    car_name: str = ""
    font_size: int = 100
    # race scenes: who drives (racer_info)
    racer_name: str = ""
    country: str = ""
    bio: str = ""
    guid: str = ""

    def __post_init__(self) -> None:
        if self.body_style not in proto.CAR_BODIES:
            raise ValueError(f"body_style must be one of {proto.CAR_BODIES}, got {self.body_style!r}")
        rgb = tuple(self.body_rgb)
        if len(rgb) != 3 or not all(isinstance(c, int) and 0 <= c <= 255 for c in rgb):
            raise ValueError(f"body_rgb must be three ints 0-255, got {self.body_rgb!r}")
        object.__setattr__(self, "body_rgb", rgb)
        if not isinstance(self.font_size, int) or self.font_size <= 0:
            raise ValueError(f"font_size must be a positive int, got {self.font_size!r}")
        for name in ("car_name", "racer_name", "country", "bio", "guid"):
            if not isinstance(getattr(self, name), str):
                raise ValueError(f"{name} must be a string, got {getattr(self, name)!r}")

    def message(self) -> bytes:
        """The ``car_config`` message."""
        r, g, b = self.body_rgb
        return proto.client_message("car_config", body_style=self.body_style, body_r=r, body_g=g, body_b=b,
                                    car_name=self.car_name, font_size=self.font_size)

    def racer_message(self) -> bytes:
        """The ``racer_info`` message (race scenes ask for it with ``need_car_config``)."""
        return proto.client_message("racer_info", racer_name=self.racer_name or self.car_name or "vehicle-rc",
                                    car_name=self.car_name, bio=self.bio, country=self.country, guid=self.guid)


@dataclass
class _Laps:
    """gym-donkeycar's lap rule: the first crossing starts the clock, the next on the same line
    completes a lap."""

    count: int = 0
    last_time: float | None = None
    _start: float | None = None
    _index: Any = None

    def restart(self) -> None:
        """The car was put back (reset_car): the next crossing starts the clock again; laps
        completed so far still count."""
        self._start = self._index = None

    def crossing(self, index: Any, stamp: float) -> bool:
        """A ``collision_with_starting_line``; True when it completed a lap. Once the clock runs,
        a crossing of another line (``starting_line_index``) is ignored, as gym-donkeycar does."""
        if self._start is None:
            self._start, self._index = stamp, index
            return False
        if index != self._index:
            return False
        self.last_time = stamp - self._start
        self.count += 1
        self._start = stamp
        return True


class DonkeySim(ThreadedPart):
    """The Donkey simulator as a car part (see the module docstring).

    Args:
        host, port: the simulator (often another machine). Default 127.0.0.1:9091.
        scene: scene name or gym id to load (``generated_track``, ``donkey-warren-track-v0`` ...).
        image_w, image_h: camera size asked with ``cam_config`` (DonkeyCar: 160x120).
        look: body, colour and name of the car.
        max_cte: |cte| (simulator units) beyond which the car is off the track (gym: 8); frames
            beyond twice this are ignored (spawn glitches), as gym-donkeycar does. None: hits only.
        synchronous: step the simulation once per control (``time_step`` s) where the server can
            (``vehicle sim serve``); real time elsewhere (see the module docstring).
        time_step: simulated seconds per step in synchronous mode.
        timeout_s: no telemetry for this long means a stale camera. Default 1.
        command_timeout_s: threaded use: no command from the loop for this long makes the part send
            one braking neutral ``control``. Default 0.5; keep it above two loop periods.
        connect_timeout_s: how long start() keeps trying to connect. Default 10.
        load_timeout_s: how long start() waits for the scene to load. Default 60.
        send_gap_s: least time between two messages in real-time mode (the simulator must read
            them as separate chunks). Default 0.02.
        exit_scene: send ``exit_scene`` on shutdown (back to the menu). Default True.
    """

    #: memory keys the part reads, in this order: the commands of the previous loop, and a reset
    #: request that a car may not have
    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle", "sim/reset")
    FEEDBACK: ClassVar[tuple[str, ...]] = ("angle", "throttle")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("sim/reset",)
    #: memory keys the part writes, in this order
    OUTPUTS: ClassVar[tuple[str, ...]] = (
        "cam/image_array", "cam/timestamp", "cam/ok", "cam/frame_id", "sim/speed", "enc/speed", "sim/cte", "sim/hit",
        "sim/off_track",
        "sim/lap", "sim/lap_time", "sim/progress", "sim/pos", "sim/time", "sim/extra")

    @classmethod
    def from_config(cls, cfg: Any, **options: Any) -> DonkeySim:
        """SIM_TYPE = "donkey": connected to SIM_HOST:SIM_PORT when started, in DONKEY_GYM_ENV_NAME,
        with GYM_CONF's car look; ``options`` go to the part (``synchronous=True``: step mode)."""
        conf = dict(cfg.GYM_CONF)
        known = ("body_style", "body_rgb", "car_name", "font_size", "racer_name", "country", "bio", "guid")
        unknown = sorted(set(conf) - set(known))
        if unknown:
            raise ConfigError(f"GYM_CONF has unknown keys {unknown}: use {', '.join(known)}")
        try:
            look = CarLook(**{k: tuple(v) if k == "body_rgb" else v for k, v in conf.items()})
            return cls(cfg.SIM_HOST, cfg.SIM_PORT, scene=cfg.DONKEY_GYM_ENV_NAME, image_w=cfg.IMAGE_W,
                       image_h=cfg.IMAGE_H, look=look, max_cte=cfg.DONKEY_MAX_CTE, timeout_s=cfg.SIM_TIMEOUT_S,
                       connect_timeout_s=cfg.SIM_CONNECT_TIMEOUT_S,
                       # a stuck loop brakes the car after 3 loop periods (>= 0.5 s), like the Udacity bridge
                       command_timeout_s=max(0.5, 3.0 / cfg.DRIVE_LOOP_HZ), **options)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"{exc} (check SIM_PORT, GYM_CONF, DONKEY_MAX_CTE, SIM_TIMEOUT_S and "
                              "SIM_CONNECT_TIMEOUT_S in myconfig.py)") from exc

    def __init__(self, host: str = "127.0.0.1", port: int = proto.DEFAULT_PORT, *, scene: str = "generated_track",
                 image_w: int = 160, image_h: int = 120, look: CarLook | None = None,
                 max_cte: float | None = 8.0, synchronous: bool = False, time_step: float = 0.05,
                 timeout_s: float = 1.0, connect_timeout_s: float = 10.0, load_timeout_s: float = 60.0,
                 send_gap_s: float = 0.02, exit_scene: bool = True, command_timeout_s: float = 0.5) -> None:
        super().__init__()
        if not isinstance(port, int) or isinstance(port, bool) or not 0 < port <= 65535:
            raise ValueError(f"DonkeySim: port must be 1..65535, got {port!r}")
        if image_w <= 0 or image_h <= 0:
            raise ValueError(f"DonkeySim: camera size {image_w}x{image_h} must be positive")
        for name, value in (("timeout_s", timeout_s), ("connect_timeout_s", connect_timeout_s),
                            ("load_timeout_s", load_timeout_s), ("time_step", time_step),
                            ("command_timeout_s", command_timeout_s)):
            if not value > 0:
                raise ValueError(f"DonkeySim: {name} must be > 0 seconds, got {value!r}")
        if max_cte is not None and not max_cte > 0:
            raise ValueError(f"DonkeySim: max_cte must be > 0 or None, got {max_cte!r}")
        if send_gap_s < 0:
            raise ValueError(f"DonkeySim: send_gap_s must be >= 0 seconds, got {send_gap_s!r}")
        self.name = "DonkeySim"
        self.host, self.port = host, port
        self.scene = proto.scene_for(scene)
        self.image_w, self.image_h = int(image_w), int(image_h)
        self.look = look or CarLook()
        self.max_cte = max_cte
        self.step_mode_asked = bool(synchronous)
        self.time_step = float(time_step)
        self.command_timeout_s = float(command_timeout_s)
        self.timeout_s = float(timeout_s)
        self.connect_timeout_s = float(connect_timeout_s)
        self.load_timeout_s = float(load_timeout_s)
        self.send_gap_s = float(send_gap_s)
        self.send_exit_scene = exit_scene
        self.join_timeout = 3.0
        self._init_session()

    def _init_session(self) -> None:
        """State of one connection (a new start() after a loss starts from here)."""
        self._ready = threading.Event()
        self.synchronous = False  # True once the server has said it steps (see _handshake)
        self._sock: socket.socket | None = None
        self._wake_r: socket.socket | None = None
        self._wake_w: socket.socket | None = None
        self._stream = proto.JsonStream()
        self._io = threading.Lock()  # guards the mailbox below (loop thread <-> client thread)
        self._control: bytes | None = None
        self._outbox: collections.deque[bytes] = collections.deque()
        self._last_send = 0.0
        self._last_was_control = False  # what the previous send was (synchronous spacing)
        self._last_command: float | None = None  # monotonic time of the loop's latest command
        self._watchdog_fired = False
        self._race_over: str | None = None  # "missed_checkpoint" / "DQ" until the next reset
        self._size_reported = False
        self._bad_frame_reported: set[str] = set()
        self._neutral = False
        self._reset_input = False
        self._sent_by_commands = False  # SendCommands sends the loop's command at the end of the loop
        self._lost = False
        self._hit_unseen: str | None = None
        self._laps = _Laps()
        self.scene_names: list[str] = []
        self.telemetry_count = 0
        self.controls_sent = 0
        self._stale_reported = False

    # -- lifecycle --------------------------------------------------------------------------------
    def start(self) -> DonkeySim:
        """Connect, load the scene and configure the car; returns when telemetry can flow.

        A part whose connection was lost connects again.

        Raises:
            BridgeError: the simulator cannot be reached, lacks the scene, or does not load it.
        """
        if self._thread is not None:
            if self._thread.is_alive() or not self._lost:
                return self
            # the connection was lost: this start is a new session
            self._thread = None
            self.stop_event = threading.Event()
            self._opened = self._closed = False
            self.error = None
            self._init_session()
        super().start()
        self._ready.wait()
        if self.error is not None:
            error = self.error
            self.shutdown()
            raise error
        logger.info("Donkey simulator at %s:%d: driving in scene %s%s", self.host, self.port, self.scene,
                    " (synchronous steps)" if self.synchronous else "")
        return self

    def open(self) -> None:
        """In the client thread: connect and run the session sequence (errors go to start())."""
        try:
            self._connect()
            self._handshake()
        except Exception as exc:  # reported by start() as one line, no traceback
            self.error = exc if isinstance(exc, BridgeError) else BridgeError(
                f"Donkey simulator at {self.host}:{self.port}: {exc}")
            self.stop_event.set()
        finally:
            self._ready.set()

    def poll(self) -> Any:
        """In the client thread: read telemetry, send what is waiting; never longer than 50 ms."""
        sock = self._sock
        if sock is None or self.stop_event.is_set():
            self.stop_event.set()
            return self.NOTHING
        try:
            self._pump(timeout=self._next_send_delay())
            self._watchdog()
            self._flush()
        except OSError as exc:
            self._connection_lost(exc)
        return self.NOTHING

    def close(self) -> None:
        """Brake, leave the scene and close (after the client thread has stopped)."""
        sock, self._sock = self._sock, None
        if sock is not None and not self._lost and self._ready.is_set() and self.error is None:
            try:
                sock.settimeout(1.0)
                self._sleep_gap(CONFIG_GAP_S)
                sock.sendall(_control(0.0, 0.0, 1.0))
                if self.send_exit_scene:
                    time.sleep(CONFIG_GAP_S)
                    sock.sendall(proto.client_message("exit_scene"))
            except OSError as exc:
                logger.warning("Donkey simulator: could not say goodbye (%s)", exc)
        for s in (sock, self._wake_r, self._wake_w):
            if s is not None:
                s.close()
        logger.info("Donkey simulator: %d telemetry messages, %d controls sent, %d laps",
                    self.telemetry_count, self.controls_sent, self._laps.count)

    def neutral(self) -> None:
        """Steering 0, throttle 0, hand brake; later commands of this session are ignored."""
        with self._io:
            self._neutral = True
            self._control = _control(0.0, 0.0, 1.0)
        self._wake()

    # -- the loop's side --------------------------------------------------------------------------
    def run_threaded(self, angle: Any = None, throttle: Any = None, reset: Any = None) -> tuple[Any, ...]:
        """Send the loop's command (and a reset on a rising ``sim/reset``); return the latest telemetry.

        The command is the previous loop's (an input read as feedback), unless
        :class:`parts.bridges.commands.SendCommands` at the end of the loop sent it already.
        """
        self._command(None if self._sent_by_commands else (angle, throttle), reset)
        return self._outputs()

    def command(self, angle: Any, throttle: Any) -> None:
        """Send this loop's command now (called by SendCommands at the end of the loop)."""
        self._sent_by_commands = True
        self._command((angle, throttle), None)

    def run(self, angle: Any = None, throttle: Any = None, reset: Any = None) -> tuple[Any, ...]:
        """Lockstep use: send the command, wait for the next telemetry (at most timeout_s), return it."""
        self.start()
        with self._fresh:
            seen = self._version
        self._command((angle, throttle), reset)
        with self._fresh:
            self._fresh.wait_for(lambda: self._version != seen or self.stop_event.is_set(), self.timeout_s)
        return self._outputs()

    def _command(self, command: tuple[Any, Any] | None, reset: Any) -> None:
        """Queue a control (when ``command`` is given) and a reset on a rising ``reset``."""
        message = None if command is None else _control(_finite(command[0]), _finite(command[1]), 0.0)
        rising = bool(reset) and not self._reset_input
        if reset is not None:
            self._reset_input = bool(reset)
        with self._io:
            if self._neutral or self._lost:
                return
            self._last_command = time.monotonic()  # the loop is alive (even when SendCommands sends)
            self._watchdog_fired = False
            if rising:
                self._outbox.append(proto.client_message("reset_car"))
                self._laps.restart()
                self._race_over = None  # gym-donkeycar clears missed_checkpoint and DQ on reset
            if message is not None:
                self._control = message
        self._wake()

    def _outputs(self) -> tuple[Any, ...]:
        record: dict[str, Any] | None = self.latest()
        age = self.age()
        ok = record is not None and age is not None and age <= self.timeout_s and not self._lost
        if not ok and record is not None and not self._stale_reported and not self._lost:
            self._stale_reported = True
            logger.warning("Donkey simulator: no telemetry for %.1f s (SIM_TIMEOUT_S = %.1f): camera marked stale, "
                           "pilot disengaged; is the simulator paused or busy loading?", age or 0.0, self.timeout_s)
        elif ok:
            self._stale_reported = False
        if record is None:
            return (None, None, False, 0) + (None,) * (len(self.OUTPUTS) - 4)
        with self._io:
            hit, self._hit_unseen = self._hit_unseen, None
            race_over = self._race_over
        hit = hit or record["hit"]
        cte = record["cte"]
        off = race_over is not None or _episode_over(cte, hit, self.max_cte)
        return (record["image"], record["timestamp"], ok, record["frame"], record["speed"], record["speed"], cte, hit,
                off, record["lap"], record["lap_time"], record["progress"], record["pos"], record["time"],
                record["extra"])

    # -- the client thread ------------------------------------------------------------------------
    def _connect(self) -> None:
        deadline = time.monotonic() + self.connect_timeout_s
        last_error: OSError | None = None
        while not self.stop_event.is_set():
            try:
                sock = socket.create_connection((self.host, self.port), timeout=2.0)
                break
            except OSError as exc:
                last_error = exc
                if time.monotonic() >= deadline:
                    raise BridgeError(
                        f"cannot reach the Donkey simulator at {self.host}:{self.port} "
                        f"({exc.strerror or exc}) within {self.connect_timeout_s:.0f} s: start it (or "
                        "`vehicle sim serve`) and check SIM_HOST / SIM_PORT") from None
                self.stop_event.wait(0.25)
        else:
            raise BridgeError(f"stopped before connecting to {self.host}:{self.port} ({last_error})")
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # one message, one segment
        sock.settimeout(2.0)  # sendall never hangs the client thread for long
        self._sock = sock
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)

    def _handshake(self) -> None:
        first = self._wait_for({"scene_selection_ready", "car_loaded"}, 2.0, required=False)
        if first is None or first.get("msg_type") == "scene_selection_ready":
            # (older builds may say nothing in the menu: ask anyway)
            self._send_now(proto.client_message("get_scene_names"))
            names = self._wait_for({"scene_names"}, 10.0, what="the list of scenes")
            self.scene_names = [str(n) for n in names.get("scene_names") or []]
            if self.scene not in self.scene_names:
                raise BridgeError(f"the Donkey simulator at {self.host}:{self.port} has no scene {self.scene!r}; "
                                  f"choose one of {', '.join(self.scene_names) or '(none offered)'} "
                                  "(DONKEY_GYM_ENV_NAME, or --scenes of `vehicle sim eval`)")
            self._send_now(proto.client_message("load_scene", scene_name=self.scene))
            self._wait_for({"car_loaded"}, self.load_timeout_s, what=f"scene {self.scene!r} to load")
        else:
            logger.info("Donkey simulator already shows a scene: driving in it (DONKEY_GYM_ENV_NAME not applied)")
        self._send_now(_control(0.0, 0.0, 1.0))  # hand brake while configuring, as gym-donkeycar does
        self._send_now(self.look.message())
        self._send_now(self._cam_config())
        if self.step_mode_asked and self._server_steps():
            self._send_now(proto.client_message("step_mode", step_mode="synchronous", time_step=self.time_step))
            self.synchronous = True
            self._drain_realtime_telemetry()
        self._sleep_gap(CONFIG_GAP_S)  # the first control too keeps the configuration's spacing

    def _drain_realtime_telemetry(self, quiet_s: float = 0.2, longest_s: float = 3.0) -> None:
        """Read until telemetry has stopped for ``quiet_s``: the frames pushed before synchronous
        mode took effect must not be taken for the answers to the first controls."""
        end = time.monotonic() + longest_s
        quiet_since = time.monotonic()
        while time.monotonic() < end and time.monotonic() - quiet_since < quiet_s:
            if any(m.get("msg_type") == "telemetry" for m in self._read(0.05)):
                quiet_since = time.monotonic()

    def _cam_config(self) -> bytes:
        """``cam_config`` with every field the simulator parses: it reads them all unconditionally
        (``TcpCarHandler.ParseCamConfig``: one missing field and nothing is applied) and keeps its
        default for a "0"; ``rot_y``/``rot_z`` only newer builds read."""
        return proto.client_message("cam_config", fov="0", fish_eye_x="0", fish_eye_y="0", img_w=self.image_w,
                                    img_h=self.image_h, img_d="3", img_enc="JPG", offset_x="0", offset_y="0",
                                    offset_z="0", rot_x="0", rot_y="0", rot_z="0")

    def _server_steps(self) -> bool:
        """Whether the server steps once per control in ``step_mode`` synchronous: only a server
        that says so in its ``protocol_version`` reply (``vehicle sim serve``); the Donkey simulator
        would pause for good. Says in one line why the evaluation runs in real time otherwise."""
        self._send_now(proto.client_message("get_protocol_version"))
        reply = self._wait_for({"protocol_version"}, 2.0, required=False)
        capabilities = reply.get("capabilities") if reply is not None else None
        if isinstance(capabilities, list) and proto.STEP_MODE_CAPABILITY in capabilities:
            return True
        logger.warning("Donkey simulator at %s:%d: its step_mode pauses the simulation instead of stepping it "
                       "(only `vehicle sim serve` steps per control): driving in real time", self.host, self.port)
        return False

    def _wait_for(self, kinds: set[str], timeout: float, *, what: str = "",
                  required: bool = True) -> dict[str, Any] | None:
        deadline = time.monotonic() + timeout
        while not self.stop_event.is_set():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            for msg in self._read(min(remaining, 0.1)):
                if msg.get("msg_type") in kinds:
                    return msg
        if required:
            raise BridgeError(f"the Donkey simulator at {self.host}:{self.port} did not send {what} within "
                              f"{timeout:.0f} s: is it the Donkey simulator (or `vehicle sim serve`) on that port?")
        return None

    def _read(self, timeout: float) -> list[dict[str, Any]]:
        """Messages that arrive within ``timeout`` s; telemetry and events are handled on the way."""
        sock = self._sock
        assert sock is not None
        with selectors.DefaultSelector() as sel:
            sel.register(sock, selectors.EVENT_READ)
            if not sel.select(timeout):
                return []
        data = sock.recv(1 << 18)
        if not data:
            raise ConnectionResetError("the simulator closed the connection")
        messages = self._stream.feed(data)
        for msg in messages:
            self._dispatch(msg)
        return messages

    def _pump(self, timeout: float) -> None:
        sock, wake = self._sock, self._wake_r
        assert sock is not None and wake is not None
        with selectors.DefaultSelector() as sel:
            sel.register(sock, selectors.EVENT_READ, "sock")
            sel.register(wake, selectors.EVENT_READ, "wake")
            for key, _ in sel.select(timeout):
                if key.data == "wake":
                    try:
                        while wake.recv(4096):
                            pass
                    except BlockingIOError:
                        pass
                else:
                    data = sock.recv(1 << 18)
                    if not data:
                        raise ConnectionResetError("the simulator closed the connection")
                    for msg in self._stream.feed(data):
                        self._dispatch(msg)

    def _next_send_delay(self) -> float:
        with self._io:
            waiting = self._next_is_control()
        if waiting is None:
            return 0.05
        return max(0.0, min(0.05, self._last_send + self._gap(waiting) - time.monotonic()))

    def _next_is_control(self) -> bool | None:
        """What goes out next (under ``_io``): None nothing, False a configuration or reset message
        (the outbox comes first), True a control."""
        if self._outbox:
            return False
        return True if self._control is not None else None

    def _gap(self, is_control: bool) -> float:
        """Least time between the previous send and the next: ``send_gap_s``, except between two
        controls in synchronous mode (the previous one was answered before the loop made this
        one). A reset or configuration message always keeps the gap on both sides: the simulator
        reads each TCP chunk as one message."""
        if self.synchronous and self._ready.is_set() and is_control and self._last_was_control:
            return 0.0
        return self.send_gap_s

    def _flush(self) -> None:
        """Send one waiting message if the gap since the last one has passed (outbox first)."""
        with self._io:
            is_control = self._next_is_control()
            if is_control is None or time.monotonic() - self._last_send < self._gap(is_control):
                return
            if is_control:
                data, self._control = self._control, None
            else:
                data = self._outbox.popleft()
        assert data is not None
        self._send(data)
        self._last_was_control = is_control
        self.controls_sent += int(is_control)

    def _watchdog(self) -> None:
        """Threaded use: a loop that gave no command for ``command_timeout_s`` gets the car one
        braking neutral control (not in step mode: the simulation waits for the loop there)."""
        if self.synchronous or not self._ready.is_set():
            return
        with self._io:
            last = self._last_command
            if (last is None or self._watchdog_fired or self._neutral
                    or time.monotonic() - last <= self.command_timeout_s):
                return
            self._watchdog_fired = True
            self._control = _control(0.0, 0.0, 1.0)
        logger.warning("Donkey simulator: the drive loop gave no command for %.2f s: braked the car (steering 0, "
                       "throttle 0)", self.command_timeout_s)

    def _send(self, data: bytes) -> None:
        sock = self._sock
        assert sock is not None
        sock.sendall(data)
        self._last_send = time.monotonic()

    def _send_now(self, data: bytes) -> None:
        """A configuration message, 0.1 s after the previous one (messages must not share a chunk)."""
        self._sleep_gap(CONFIG_GAP_S)
        self._send(data)

    def _sleep_gap(self, gap: float) -> None:
        wait = self._last_send + gap - time.monotonic()
        while wait > 0 and not self.stop_event.is_set():
            if self._sock is not None and self._ready.is_set() is False:
                self._read(wait)  # keep reading while waiting (telemetry may already flow)
            else:
                time.sleep(wait)
            wait = self._last_send + gap - time.monotonic()

    def _wake(self) -> None:
        w = self._wake_w
        if w is not None:
            with contextlib.suppress(OSError):  # already woken (buffer full), or closed
                w.send(b"x")

    def _dispatch(self, msg: dict[str, Any]) -> None:
        kind = msg.get("msg_type")
        if kind == "telemetry":
            self._on_telemetry(msg)
        elif kind == "collision_with_starting_line":
            stamp = proto.number(msg.get("timeStamp"))
            if stamp is None:
                return
            with self._io:  # restart() runs on the loop thread
                lap = self._laps.crossing(msg.get("starting_line_index"), stamp)
                count, lap_time = self._laps.count, self._laps.last_time
            if lap:
                logger.info("Donkey simulator: lap %d in %.2f s", count, lap_time or 0.0)
        elif kind == "need_car_config":
            with self._io:
                self._outbox.append(self.look.racer_message())
                self._outbox.append(self.look.message())
        elif kind in ("DQ", "missed_checkpoint"):
            with self._io:  # the episode is over until the next reset, as in gym-donkeycar
                self._race_over = kind
            logger.info("Donkey simulator: %s %s", kind, {k: v for k, v in msg.items() if k != "msg_type"})
        elif kind in ("race_start", "race_stop", "cross_start"):
            logger.info("Donkey simulator: %s %s", kind, {k: v for k, v in msg.items() if k != "msg_type"})
        # scene_selection_ready, scene_names, car_loaded, protocol_version, ping, node_position: the
        # handshake reads what it needs; the rest needs no answer

    def _on_telemetry(self, msg: dict[str, Any]) -> None:
        image = self._frame(msg.get("image"))
        if image is None:
            return
        self.telemetry_count += 1
        hit = msg.get("hit")
        hit = hit if isinstance(hit, str) and hit else "none"
        if hit != "none":
            with self._io:
                self._hit_unseen = hit
        cte = proto.number(msg.get("cte"))
        nodes = proto.number(msg.get("totalNodes"))
        node = proto.number(msg.get("activeNode"))
        pos_x, pos_z = proto.number(msg.get("pos_x")), proto.number(msg.get("pos_z"))
        extra = {k: v for k, v in msg.items() if k not in _OWN_FIELDS}
        with self._io:
            laps, lap_time = self._laps.count, self._laps.last_time
        self.publish({
            "image": image, "timestamp": time.time(), "frame": self.telemetry_count,
            "speed": proto.number(msg.get("speed")),
            "cte": cte, "hit": hit, "lap": laps, "lap_time": lap_time,
            "progress": node / nodes if nodes and node is not None else None,
            "pos": (pos_x, pos_z) if pos_x is not None and pos_z is not None else None,
            "time": proto.number(msg.get("time")), "extra": extra})

    def _frame(self, encoded: Any) -> np.ndarray | None:
        """The telemetry's camera frame at image_w x image_h; None (said once per reason) when it
        is no usable image. A frame of another size is resized, and the first one is reported."""
        from parts.cameras.base import fit_frame

        try:
            image = decode_frame(encoded)
        except ValueError as exc:
            if str(exc) not in self._bad_frame_reported:
                self._bad_frame_reported.add(str(exc))
                logger.error("Donkey simulator: telemetry frame skipped: %s", exc)
            return None
        height, width = image.shape[:2]
        if (width, height) != (self.image_w, self.image_h) and not self._size_reported:
            self._size_reported = True
            logger.warning("Donkey simulator sends %dx%d frames, not the %dx%d asked with cam_config (IMAGE_W, "
                           "IMAGE_H): frames are resized, the aspect ratio may change; does this build apply "
                           "cam_config?", width, height, self.image_w, self.image_h)
        return fit_frame(image, self.image_w, self.image_h)

    def _connection_lost(self, exc: BaseException) -> None:
        if not self._lost:
            self._lost = True
            logger.error("lost the connection to the Donkey simulator at %s:%d (%s): the simulated car gets no "
                         "more commands; camera marked stale. Restart the drive to reconnect.",
                         self.host, self.port, exc)
        self.stop_event.set()


def _finite(value: Any) -> float:
    """A command value; 0 for None, junk or non-finite numbers."""
    number = proto.number(value)
    return 0.0 if number is None else number


def _control(steering: float, throttle: float, brake: float) -> bytes:
    return proto.client_message("control", steering=min(1.0, max(-1.0, steering)),
                                throttle=min(1.0, max(-1.0, throttle)), brake=brake)


def _episode_over(cte: float | None, hit: str, max_cte: float | None) -> bool:
    """gym-donkeycar's ``determine_episode_over`` for one telemetry, in its order: |cte| beyond
    twice max_cte is a spawn glitch and ends nothing (not even a hit), then |cte| > max_cte, then a
    hit. ``max_cte`` None: hits only; a telemetry without ``cte``: hits only."""
    if max_cte is not None and cte is not None:
        if abs(cte) > 2 * max_cte:
            return False
        if abs(cte) > max_cte:
            return True
    return hit != "none"
