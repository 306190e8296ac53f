"""Our simulator served over the Donkey simulator's TCP JSON protocol (``vehicle sim serve``).

Any Donkey-simulator client drives the built-in simulator: gym-donkeycar environments, DonkeyCar's
``DonkeyGymEnv`` part, :class:`parts.bridges.donkey_client.DonkeySim`, racing clients. It runs
headless (no GPU, no display), with seeded tracks, and faster than real time when the client asks
for ``step_mode`` synchronous (one simulation step per ``control``, as fast as both sides go).

Each connection gets its own car and track, in its own thread. The session follows the simulator:
``scene_selection_ready`` on connect, ``get_scene_names`` -> ``scene_names``, ``load_scene`` ->
``car_loaded``, then ``telemetry`` at 20 Hz whatever the client does (real-time mode), or one per
``control`` (synchronous mode). Every message is JSON + ``"\\n"`` in its own ``send``; client
messages are read as a stream (split, packed, with or without newline). ``protocol_version`` says
``"2"`` like the simulator, plus ``"server": "vehicle-rc"`` and ``"capabilities": ["step_mode"]``
(fields other clients ignore), so a client knows that step mode steps here.

A client's messages are small: one over 64 KiB, more than ``max_errors`` unreadable ones, or more
than 64 KiB of text outside any message ends its session with one log line, as does sending no
message for ``hello_timeout_s`` after connecting (a Donkey client asks for the scenes at once) or
staying in the menu for ``idle_timeout_s`` without loading a scene (a connection that holds one of
``max_clients`` and does nothing). When every slot is taken, a new client takes the slot of the
peer that has sent nothing for the longest (at least ``SILENT_EVICT_AGE_S``), which is told why in
the log; refusals are logged once per ``REFUSED_LOG_S``. A camera asked with
``cam_config`` is clamped to 4096 pixels a side and 4 Mpx. A session that fails for any other
reason logs one line and ends; the others go on.

Scenes: every scene name of the Donkey simulator builds is offered, mapped in order onto the served
track seeds (so any gym ``donkey-<scene>-v0`` id loads a track), plus ``track_<seed>`` for each
served seed; ``track_<N>`` also loads any other seed, and ``regen_road`` with ``rand_seed`` moves the
car to that seed's track.

What the telemetry holds (our units, not the simulator's /8 scaling): ``speed`` m/s, ``pos_*`` and
``vel_*`` in metres and m/s on the ground plane x/z (y up), ``cte`` in metres with the simulator's
sign (positive right of the centre line, as ``CarPath.GetCrossTrackErr`` computes it),
``activeNode``/``totalNodes`` over the centre-line
samples, ``hit`` = ``"off_track"`` once when the car leaves the road (so gym episodes end there
even with their default ``max_cte`` of 8), and ``collision_with_starting_line`` when the car first
drives off the start line after a (re)load or reset, and after every lap.
"""

from __future__ import annotations

import base64
import contextlib
import logging
import math
import re
import selectors
import socket
import threading
import time
from collections.abc import Sequence
from typing import Any, Final

from parts.bridges import donkey_protocol as proto
from parts.bridges.errors import BridgeError

logger = logging.getLogger(__name__)

_TRACK_SCENE = re.compile(r"^track_(-?\d+)$")
#: longest client message a session reads (client messages are a few hundred bytes)
MAX_CLIENT_MESSAGE_BYTES: Final = 64 * 1024
#: text outside any message a session skips before it ends (whitespace aside)
MAX_JUNK_BYTES: Final = 64 * 1024
#: seconds a peer must have been silent before a new client may take its slot (a real client
#: speaks within milliseconds of connecting)
SILENT_EVICT_AGE_S = 0.5
#: seconds between two log lines about refused connections
REFUSED_LOG_S: Final = 10.0
#: simulated seconds a synchronous step may last (a client's ``time_step`` is clamped to them)
MIN_TIME_STEP: Final = 0.001
MAX_TIME_STEP: Final = 0.2
_WORLD_LOCK = threading.Lock()  # parts.sim's world cache is shared by every session
BRAKE_HOLD_SPEED: Final = 0.05  # m/s below which the hand brake holds the car still


def scene_names(seeds: Sequence[int]) -> list[str]:
    """The scene list a server of ``seeds`` offers."""
    return list(proto.SCENE_NAMES) + [f"track_{s}" for s in seeds]


def seed_for_scene(name: str, seeds: Sequence[int]) -> int | None:
    """The track seed a scene name loads, or None for an unknown scene."""
    if name in proto.SCENE_NAMES:
        return int(seeds[proto.SCENE_NAMES.index(name) % len(seeds)])
    match = _TRACK_SCENE.match(name)
    return int(match.group(1)) if match else None


class DonkeyServer:
    """The built-in simulator behind a Donkey-protocol TCP server.

    Args:
        host: interface to listen on. Default ``"127.0.0.1"``; ``"0.0.0.0"`` for clients on other
            machines (the simulator itself listens on every interface).
        port: TCP port; default 9091, 0 = a free one (read :attr:`port` after :meth:`start`).
        seeds: track seeds served (``--tracks``).
        cfg: a Config for the car, camera and track settings (SIM_*); default: package defaults.
        telemetry_hz: telemetry rate in real-time mode (20 like the simulator).
        off_track_hit: report ``hit = "off_track"`` once when the car leaves the road.
        jpeg_quality: JPEG quality of the camera frames (75 like Unity's default).
        max_clients: connections served at once; more are refused with a log line.
        idle_timeout_s: a client that loads no scene for this long after connecting (or after
            ``exit_scene``) is disconnected, so that idle connections do not hold the slots.
        hello_timeout_s: a peer that sends no message for this long after connecting is
            disconnected (5 s: a Donkey client asks for the scenes at once).
        max_errors: unreadable messages a session accepts before it ends.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = proto.DEFAULT_PORT, *, seeds: Sequence[int] = (1,),
                 cfg: Any = None, telemetry_hz: float = float(proto.TELEMETRY_HZ), off_track_hit: bool = True,
                 jpeg_quality: int = 75, max_clients: int = 16, idle_timeout_s: float = 30.0,
                 max_errors: int = 10, hello_timeout_s: float = 5.0) -> None:
        seeds = [seeds] if isinstance(seeds, int) else list(seeds)
        if not seeds or not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds):
            raise ValueError(f"track seeds must be a non-empty list of ints, got {seeds!r}")
        if not telemetry_hz > 0:
            raise ValueError(f"telemetry_hz must be > 0, got {telemetry_hz!r}")
        if not 1 <= jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality must be 1..100, got {jpeg_quality!r}")
        if not idle_timeout_s > 0 or not hello_timeout_s > 0:
            raise ValueError(f"idle_timeout_s and hello_timeout_s must be > 0, got {idle_timeout_s!r}, "
                             f"{hello_timeout_s!r}")
        if max_errors < 0:
            raise ValueError(f"max_errors must be >= 0, got {max_errors!r}")
        if cfg is None:
            from vehicle.config import Config

            cfg = Config.defaults()
        self.host, self.port = host, port
        self.seeds = [int(s) for s in seeds]
        self.cfg = cfg
        self.period = 1.0 / telemetry_hz
        self.off_track_hit = off_track_hit
        self.jpeg_quality = jpeg_quality
        self.max_clients = max_clients
        self.idle_timeout_s = float(idle_timeout_s)
        self.hello_timeout_s = float(hello_timeout_s)
        self.refused = 0  # connections refused because every slot was taken
        self._refused_logged_at = -REFUSED_LOG_S
        self._refused_unlogged = 0
        self.max_errors = max_errors
        self.sessions: list[Session] = []
        self._listener: socket.socket | None = None
        self._stop = threading.Event()
        self._accept_thread: threading.Thread | None = None
        self._lock = threading.Lock()

    # -- lifecycle --------------------------------------------------------------------------------
    def start(self) -> DonkeyServer:
        """Draw the served tracks, listen and accept clients in a thread; returns self.

        Raises:
            BridgeError: the port cannot be bound.
        """
        from parts.sim.simulator import load_world, world_params
        from parts.sim.themes import theme_list

        theme = theme_list(self.cfg.SIM_THEME)[0]  # a scene's SimCar drives one track: the first theme
        for seed in self.seeds[:6]:  # a fraction of a second each: now, not when the first client loads a scene
            with _WORLD_LOCK:
                load_world(seed, theme=theme, **world_params(self.cfg))
        try:
            listener = socket.create_server((self.host, self.port), reuse_port=False)
        except OSError as exc:
            raise BridgeError(f"cannot listen on {self.host}:{self.port} ({exc.strerror or exc}): another "
                              "simulator may be running there; stop it or pass --port") from None
        listener.settimeout(0.2)
        self.port = listener.getsockname()[1]
        self._listener = listener
        self._accept_thread = threading.Thread(target=self._accept, name="DonkeyServer", daemon=True)
        self._accept_thread.start()
        logger.info("Donkey-protocol simulator on %s:%d, tracks %s", self.host, self.port,
                    ",".join(map(str, self.seeds)))
        return self

    def serve_forever(self) -> None:
        """Block until :meth:`stop` (or Ctrl-C, which the caller handles)."""
        while not self._stop.wait(0.5):
            pass

    def stop(self) -> None:
        """Close every session and the listening socket."""
        self._stop.set()
        with self._lock:
            sessions = list(self.sessions)
        for session in sessions:
            session.close()
        if self._accept_thread is not None:
            self._accept_thread.join(2.0)
        if self._listener is not None:
            self._listener.close()
        for session in sessions:
            session.join(2.0)

    def __enter__(self) -> DonkeyServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _accept(self) -> None:
        listener = self._listener
        assert listener is not None
        while not self._stop.is_set():
            try:
                conn, address = listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            with self._lock:
                self.sessions = [s for s in self.sessions if s.alive]
                full = len(self.sessions) >= self.max_clients
                if full:  # the slot of the peer silent the longest, if any
                    now = time.monotonic()
                    silent = [s for s in self.sessions if not s.spoke and now - s.connected_at >= SILENT_EVICT_AGE_S]
                    if silent:
                        oldest = min(silent, key=lambda s: s.connected_at)
                        oldest.end("sent no message since it connected, and its slot was needed by a new client")
                        self.sessions.remove(oldest)
                        full = False
                if not full:
                    session = Session(self, conn, address)
                    self.sessions.append(session)
            if full:
                self._refuse(conn, address)
                continue
            session.start()


    def _refuse(self, conn: socket.socket, address: Any) -> None:
        """Close a connection no slot is free for; one log line per REFUSED_LOG_S at most."""
        conn.close()
        self.refused += 1
        self._refused_unlogged += 1
        now = time.monotonic()
        if now - self._refused_logged_at >= REFUSED_LOG_S:
            logger.warning("Donkey server: refused %d connection%s (the last from %s:%d): already %d clients "
                           "(max; --max-clients)", self._refused_unlogged, "" if self._refused_unlogged == 1 else "s",
                           *address[:2], self.max_clients)
            self._refused_logged_at, self._refused_unlogged = now, 0


class Session:
    """One client connection: its car, its track, its thread."""

    def __init__(self, server: DonkeyServer, sock: socket.socket, address: Any) -> None:
        self.server = server
        self.sock = sock
        self.address = f"{address[0]}:{address[1]}"
        self.stream = proto.JsonStream(max_message=MAX_CLIENT_MESSAGE_BYTES)
        self.sim: Any = None  # the SimCar once a scene is loaded
        self.scene: str | None = None
        self.synchronous = False
        self.time_step = server.period
        self.steering = self.throttle = self.brake = 0.0
        self.camera_size: tuple[int, int] | None = None  # (w, h) asked with cam_config
        self.level_time = 0.0  # simulated seconds since the scene (re)loaded
        self.steps = 0
        self.resets = 0
        self.telemetry_sent = 0
        self._restart_pending = True  # send collision_with_starting_line when the car moves off the line
        self._was_off = False
        self._prev: tuple[float, float, float, float] | None = None  # heading, vx, vz, time
        self._menu_since = time.monotonic()  # when the session last had no scene (idle timeout)
        self.connected_at = self._menu_since
        self.spoke = False  # it sent a readable message (a peer that never does is dropped soon)
        self._end_reason: str | None = None  # why the server ended the session (said once, by the thread)
        self._clamp_reported = False
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"DonkeySession {self.address}", daemon=True)
        self.alive = True

    def start(self) -> None:
        """Serve the connection in a thread."""
        self._thread.start()

    def close(self) -> None:
        """End the session (thread-safe)."""
        self._closing.set()
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)

    def end(self, reason: str) -> None:
        """End the session for ``reason``, which its thread logs (thread-safe)."""
        self._end_reason = reason
        self.close()

    def join(self, timeout: float) -> None:
        """Wait for the session's thread."""
        self._thread.join(timeout)

    # -- the session thread -----------------------------------------------------------------------
    def _run(self) -> None:
        logger.info("Donkey server: client %s connected", self.address)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.settimeout(5.0)  # a client that stops reading must not hang the session forever
        try:
            self._send("scene_selection_ready", loaded="1")
            next_tick = time.monotonic()
            with selectors.DefaultSelector() as sel:
                sel.register(self.sock, selectors.EVENT_READ)
                while not self._closing.is_set():
                    realtime = self.sim is not None and not self.synchronous
                    timeout = max(0.0, next_tick - time.monotonic()) if realtime else 0.2
                    if sel.select(timeout):
                        data = self.sock.recv(1 << 16)
                        if not data:
                            break
                        for msg in self.stream.feed(data):
                            self.spoke = True
                            self._handle(msg)
                        self._check_errors()
                    if not self.spoke and time.monotonic() - self.connected_at > self.server.hello_timeout_s:
                        raise _SessionEnd(f"sent no message in {self.server.hello_timeout_s:.0f} s: disconnected "
                                          "(a Donkey client asks for the scenes at once)")
                    if self.sim is None and time.monotonic() - self._menu_since > self.server.idle_timeout_s:
                        raise _SessionEnd(f"loaded no scene for {self.server.idle_timeout_s:.0f} s: disconnected "
                                          "(a Donkey client sends load_scene after scene_names)")
                    if self.sim is not None and not self.synchronous:
                        now = time.monotonic()
                        if now >= next_tick:
                            self._step_and_report(self.server.period)
                            # absolute deadlines, but no burst to catch up after a stall
                            next_tick = max(next_tick + self.server.period, now)
                    else:
                        next_tick = time.monotonic() + self.server.period
        except OSError as exc:
            if not self._closing.is_set():
                logger.info("Donkey server: client %s: %s", self.address, exc)
        except (BridgeError, _SessionEnd) as exc:
            logger.error("Donkey server: client %s: %s", self.address, exc)
        except Exception as exc:  # a bug or a message nobody foresaw: this session ends, the server goes on
            logger.error("Donkey server: client %s: session ended by %s: %s", self.address,
                         type(exc).__name__, exc, exc_info=logger.isEnabledFor(logging.DEBUG))
        finally:
            self.alive = False
            if self._end_reason is not None:  # ended by the server (its slot was needed)
                logger.warning("Donkey server: client %s %s: disconnected", self.address, self._end_reason)
            with contextlib.suppress(OSError):
                self.sock.close()
            logger.info("Donkey server: client %s left after %d steps, %d telemetry messages",
                        self.address, self.steps, self.telemetry_sent)

    def _check_errors(self) -> None:
        """End the session on a message over the size limit or too many unreadable ones."""
        if self.stream.overflows:
            raise _SessionEnd(f"sent a message longer than {MAX_CLIENT_MESSAGE_BYTES // 1024} KiB (Donkey client "
                              "messages are a few hundred bytes): disconnected")
        if self.stream.junk_bytes > MAX_JUNK_BYTES:
            raise _SessionEnd(f"sent {self.stream.junk_bytes} bytes that are not Donkey JSON messages: disconnected "
                              "(is it a Donkey simulator client?)")
        if self.stream.errors > self.server.max_errors:
            raise _SessionEnd(f"sent {self.stream.errors} unreadable messages: disconnected (is it a Donkey "
                              "simulator client?)")

    def _send(self, msg_type: str, **fields: Any) -> None:
        """One message, one send (as the simulator does; on loopback a reader may still get several
        in one chunk: clients must read a stream)."""
        self.sock.sendall(proto.sim_message(msg_type, **fields))

    def _handle(self, msg: dict[str, Any]) -> None:
        kind = msg.get("msg_type")
        if kind == "control":
            self.steering = _clamped(msg.get("steering"), -1.0, 1.0)
            self.throttle = _clamped(msg.get("throttle"), -1.0, 1.0)
            self.brake = _clamped(msg.get("brake"), 0.0, 1.0)
            if self.sim is not None and self.synchronous:
                self._step_and_report(self.time_step)
        elif kind == "get_scene_names":
            self._send("scene_names", scene_names=scene_names(self.server.seeds))
        elif kind == "load_scene":
            name = str(msg.get("scene_name", ""))
            seed = seed_for_scene(name, self.server.seeds)
            if self.sim is not None:
                logger.info("Donkey server: %s asked for %s while in a scene; ignored", self.address, name)
            elif seed is None:
                logger.warning("Donkey server: %s asked for unknown scene %r (offered: %s)", self.address, name,
                               ", ".join(scene_names(self.server.seeds)))
            else:
                self._load(name, seed)
                self._send("car_loaded")
        elif kind == "get_protocol_version":
            # the simulator's answer, plus what sets this server apart (fields other clients ignore)
            self._send("protocol_version", version="2", server="vehicle-rc",
                       capabilities=[proto.STEP_MODE_CAPABILITY])
        elif kind == "reset_car":
            if self.sim is not None:
                self.sim.reset("start")
                self.resets += 1
                self._restart()
        elif kind == "exit_scene":
            self.sim, self.scene = None, None
            self._menu_since = time.monotonic()
            self._send("scene_selection_ready", loaded="1")
        elif kind == "quit_app":
            self._closing.set()
        elif kind in ("step_mode", "settings"):
            self.synchronous = str(msg.get("step_mode", "")).lower() == "synchronous"
            step = proto.number(msg.get("time_step"))
            # within what the car model integrates well: 1 ms .. 0.2 s per step
            self.time_step = min(MAX_TIME_STEP, max(MIN_TIME_STEP, step)) if step is not None and step > 0 \
                else self.server.period
            if self.sim is not None and self.synchronous:
                self._report()  # the observation a stepping client waits for before its first control
        elif kind == "cam_config":
            self._cam_config(msg)
        elif kind == "regen_road":
            seed = proto.number(msg.get("rand_seed"))
            if self.sim is not None and seed is not None:
                self._load(f"track_{int(seed)}", int(seed))
        elif kind == "set_position":
            self._set_position(msg)
        elif kind == "node_position":
            self._node_position(msg)
        # car_config, cam_config_b, lidar_config, racer_info: accepted; nothing to draw them with

    def _cam_config(self, msg: dict[str, Any]) -> None:
        """``img_w``/``img_h`` set the camera size ("0" keeps it, as in the simulator), within limits."""
        from parts.bridges.frames import MAX_PIXELS, MAX_SIDE, clamp_size, within_limits

        w, h = proto.number(msg.get("img_w"), 0.0), proto.number(msg.get("img_h"), 0.0)
        if not (w and h and w >= 8 and h >= 8):
            return
        size = (int(w), int(h))
        if not within_limits(*size):
            clamped = clamp_size(*size)
            if not self._clamp_reported:
                self._clamp_reported = True
                logger.warning("Donkey server: client %s asked for a %dx%d camera: clamped to %dx%d (at most %d "
                               "pixels a side, %d Mpx)", self.address, *size, *clamped, MAX_SIDE,
                               MAX_PIXELS // (1024 * 1024))
            size = clamped
        self.camera_size = size
        if self.sim is not None:
            self.sim.camera = self._camera()

    def _camera(self) -> Any:
        from parts.sim.camera import PinholeCamera

        cfg = self.server.cfg
        w, h = self.camera_size or (cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H)
        return PinholeCamera(w, h, cfg.SIM_CAMERA_FOV, cfg.SIM_CAMERA_PITCH, cfg.SIM_CAMERA_HEIGHT,
                             cfg.SIM_CAMERA_FORWARD)

    def _load(self, name: str, seed: int) -> None:
        from parts.sim.simulator import SimCar

        with _WORLD_LOCK:
            self.sim = SimCar.from_config(self.server.cfg, seeds=[seed], dt=self.server.period,
                                          reset_off_track=False, camera=self._camera(), realtime=False)
        self.scene = name
        self.steering = self.throttle = self.brake = 0.0
        self.level_time = 0.0
        self._restart()
        logger.info("Donkey server: client %s drives scene %s (track %d)", self.address, name, seed)

    def _restart(self) -> None:
        self.steering = self.throttle = self.brake = 0.0
        self._restart_pending = True
        self._was_off = False
        self._prev = None

    def _step_and_report(self, dt: float) -> None:
        sim = self.sim
        sim.dt = dt
        frame = sim.step(self.steering, self._effective_throttle())
        self.level_time += dt
        self.steps += 1
        if frame.lap_completed:
            self._send("collision_with_starting_line", starting_line_index=0, timeStamp=self.level_time)
        self._report()

    def _effective_throttle(self) -> float:
        """Throttle with the brake: the brake stops the car (and holds it) whatever the throttle."""
        if self.brake <= 0.0:
            return self.throttle
        v = self.sim.car.state.speed
        if v > BRAKE_HOLD_SPEED:
            return -self.brake
        if v < -BRAKE_HOLD_SPEED:
            return self.brake
        return 0.0

    def _report(self) -> None:
        """Send the telemetry of the current state (after the start-line event of a restart)."""
        sim = self.sim
        frame, state, track = sim.frame, sim.car.state, sim.track
        if self._restart_pending and sim.tracker.distance > 0:
            # the car starts on the line: it crosses it when it first moves forward (clients that
            # clear their lap state after a reset, as gym-donkeycar does, still see this crossing)
            self._restart_pending = False
            self._send("collision_with_starting_line", starting_line_index=0, timeStamp=self.level_time)
        hit = "none"
        if self.server.off_track_hit and frame.off_track and not self._was_off:
            hit = "off_track"
        self._was_off = frame.off_track
        from parts.tub.codec import encode_image

        jpeg, _ = encode_image(sim.render(), "image_array", self.server.jpeg_quality)
        heading, v = state.heading, state.speed
        vx, vz = v * math.cos(heading), v * math.sin(heading)
        gyro = accel_x = accel_z = 0.0
        if self._prev is not None and self.level_time > self._prev[3]:
            dt = self.level_time - self._prev[3]
            turn = (heading - self._prev[0] + math.pi) % (2 * math.pi) - math.pi
            gyro = -turn / dt  # Unity: positive yaw rate turns clockwise seen from above
            accel_x, accel_z = (vx - self._prev[1]) / dt, (vz - self._prev[2]) / dt
        self._prev = (heading, vx, vz, self.level_time)
        max_steer = sim.car.params.max_steer
        self._send(
            "telemetry", steering_angle=-state.steer / max_steer, throttle=self._effective_throttle(),
            speed=abs(v), image=base64.b64encode(jpeg).decode("ascii"), hit=hit, time=self.level_time,
            accel_x=accel_x, accel_y=0.0, accel_z=accel_z, gyro_x=0.0, gyro_y=gyro, gyro_z=0.0,
            pitch=0.0, yaw=(90.0 - math.degrees(heading)) % 360.0, roll=0.0,
            cte=frame.cte, activeNode=int(frame.s / track.length * track.n) % track.n, totalNodes=track.n,
            pos_x=state.x, pos_y=0.0, pos_z=state.y, vel_x=vx, vel_y=0.0, vel_z=vz)
        self.telemetry_sent += 1

    def _set_position(self, msg: dict[str, Any]) -> None:
        x, z = proto.number(msg.get("pos_x")), proto.number(msg.get("pos_z"))
        if self.sim is None or x is None or z is None:
            return
        heading = self.sim.car.state.heading
        qy, qw = proto.number(msg.get("Qy")), proto.number(msg.get("Qw"))
        if qy is not None and qw is not None:  # rotation about the up axis only
            heading = math.radians(90.0 - math.degrees(2 * math.atan2(qy, qw)))
        self.sim.car.place(x, z, heading)
        self.sim.tracker.relocate()

    def _node_position(self, msg: dict[str, Any]) -> None:
        index = proto.number(msg.get("index"))
        if self.sim is None or index is None:
            return
        track = self.sim.track
        i = int(index) % track.n
        x, y = track.points[i]
        half_yaw = math.radians(90.0 - math.degrees(track.heading[i])) / 2
        self._send("node_position", index=i, pos_x=float(x), pos_y=0.0, pos_z=float(y),
                   Qx=0.0, Qy=math.sin(half_yaw), Qz=0.0, Qw=math.cos(half_yaw))


class _SessionEnd(Exception):
    """The session ends for a reason the log line gives (a misbehaving or idle client)."""


def _clamped(value: Any, low: float, high: float) -> float:
    number = proto.number(value, 0.0)
    assert number is not None
    return min(high, max(low, number))
