"""The Udacity self-driving-car simulator as a car: we are the Socket.IO server it connects to.

>>> sim = UdacitySim(port=4567)                       # the simulator's hard-coded port
>>> V.add(sim, inputs=list(UdacitySim.INPUTS), outputs=list(sim.outputs),
...       threaded=True)                              # doctest: +SKIP

The simulator (Term 1, autonomous mode) connects to ``ws://127.0.0.1:4567/socket.io/`` and sends a
``telemetry`` event (centre camera JPEG, speed, steering, throttle, all as strings); it then waits
for exactly one ``steer`` or ``manual`` before it sends the next. This part runs that server in its
own thread (python-socketio on aiohttp, with :mod:`parts.bridges.engineio3` for the simulator's
Engine.IO v3 dialect) and keeps the lockstep with the drive loop:

- a telemetry's frame is handed to the loop at its next run; the steer that answers it carries
  the ``angle``/``throttle`` the loop computed from that frame: sent at the end of that loop by
  :class:`parts.bridges.commands.SendCommands` (added last), else at the start of the next. The
  loop never waits for the simulator, and the simulator never gets a command older than the frame
  it answers;
- a telemetry the loop does not answer within ``command_timeout_s`` (the loop is stuck) is
  answered with a neutral steer (0, 0), as an actuator watchdog would;
- :meth:`UdacitySim.neutral` (every way the drive stops) answers waiting telemetries with (0, 0)
  and, when none waits (the loop had just answered the last one), sends the simulator an
  unsolicited neutral steer, as drive.py does on connect: the simulator applies the last steer it
  got until another comes, so the last one must be neutral; later telemetries get (0, 0) too;
- one simulator at a time: a new connection replaces the previous one (its frames would interleave
  with the new one's), with one warning;
- ``telemetry`` with ``null`` (the user holds W/S in autonomous mode) is answered with ``manual``
  at once and reported as ``sim/manual`` True (an intervention for evaluation);
- no telemetry for ``timeout_s`` makes ``cam/ok`` False (the camera watchdog then takes the pilot
  out) and logs one line that says what to check;
- numbers in telemetry are read whatever the simulator's locale (``"0,1234"``); steer values are
  JSON strings, with the decimal separator the simulator parses (it uses ``float.Parse`` in its
  own locale, so a simulator that sends decimal commas gets decimal commas back).

Outputs: ``cam/image_array`` (160x320x3 RGB), ``cam/timestamp``, ``cam/ok``, ``cam/frame_id`` (the
telemetry's number: a new value means a new frame), ``sim/speed`` (m/s,
from mph), ``enc/speed`` (the same), ``sim/steering_deg`` (degrees, ±25, positive = right),
``sim/throttle``, ``sim/manual``, ``sim/cte`` and ``sim/lap`` (research forks' ``cte`` and
``lapNumber``; None from the stock simulator), ``sim/extra`` (every other key a fork sends, parsed),
then ``sim/<key>`` for each name in ``extra_keys`` (in snake case: ``lapNumber`` -> ``sim/lap_number``).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from parts.bridges.errors import BridgeError, OncePerKind
from parts.bridges.udacity_protocol import (
    DECIMALS,
    FORK_KEYS,
    FRAME_SIZE,
    MS_PER_MPH,
    STOCK_KEYS,
    extra_key,
    format_command,
    parse_number,
    uses_decimal_comma,
)
from vehicle.config import ConfigError
from vehicle.part import ThreadedPart, run_event_loop

#: largest websocket message accepted, bytes (a 320x160 JPEG telemetry is ~20 KB): a larger one
#: closes the connection, said once
MAX_MESSAGE_BYTES = 4_000_000

logger = logging.getLogger(__name__)

@dataclass(frozen=True)
class UdacityTelemetry:
    """One telemetry message, parsed."""

    seq: int  # 1 for the first telemetry since the part started
    sid: str  # the connection it came on (the steer must go back there)
    image: np.ndarray  # HxWx3 uint8 RGB
    timestamp: float  # time.time() when it arrived
    steering_deg: float | None
    throttle: float | None
    speed: float | None  # m/s
    extra: dict[str, Any] = field(default_factory=dict)


class UdacitySim(ThreadedPart):
    """The Udacity simulator as a car part (add it with ``threaded=True``).

    Args:
        host: interface to listen on. Default ``"127.0.0.1"``: the simulator connects to
            127.0.0.1 (hard-coded in its build); use ``"0.0.0.0"`` only when it runs elsewhere.
        port: TCP port. Default 4567 (hard-coded in the simulator); 0 picks a free one (tests).
        timeout_s: no telemetry for this long means a stale camera (``cam/ok`` False). Default 1.
        command_timeout_s: a telemetry the loop has not answered after this long is answered with
            a neutral steer. Default 0.5; keep it above two loop periods.
        decimal: decimal separator of steer values: "auto" (the one the simulator's telemetry
            uses), "." or ",".
        extra_keys: fork telemetry keys to publish as ``sim/<key>`` outputs of their own.
        start_timeout: seconds :meth:`start` waits for the server to listen. Default 10.
    """

    #: size of the frames it delivers, fixed by the simulator (a pilot checks it fits when it loads)
    width: ClassVar[int] = FRAME_SIZE[0]
    height: ClassVar[int] = FRAME_SIZE[1]
    #: for the wiring check (:mod:`vehicle.shapes`)
    OUTPUT_SHAPES: ClassVar[dict[str, tuple[int, ...]]] = {"cam/image_array": (FRAME_SIZE[1], FRAME_SIZE[0], 3)}
    #: memory keys the part reads, in this order: the commands of the previous loop
    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle")
    FEEDBACK: ClassVar[tuple[str, ...]] = ("angle", "throttle")

    @property
    def OUTPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """Memory keys the part writes, in this order; then ``sim/<key>`` per extra key."""
        return ("cam/image_array", "cam/timestamp", "cam/ok", "cam/frame_id", "sim/speed", "enc/speed",
                "sim/steering_deg", "sim/throttle", "sim/manual", "sim/cte", "sim/lap", "sim/extra",
                *(extra_key(k) for k in self.extra_keys))

    @classmethod
    def from_config(cls, cfg: Any, **options: Any) -> UdacitySim:
        """SIM_TYPE = "udacity": the server on UDACITY_HOST:UDACITY_PORT, not started; ``options`` go
        to the part."""
        try:
            return cls(cfg.UDACITY_HOST, cfg.UDACITY_PORT, timeout_s=cfg.SIM_TIMEOUT_S,
                       # a stuck loop gets the simulator a neutral steer after 3 loop periods (>= 0.5 s)
                       command_timeout_s=max(0.5, 3.0 / cfg.DRIVE_LOOP_HZ), decimal=cfg.UDACITY_DECIMAL,
                       extra_keys=tuple(cfg.UDACITY_EXTRA_KEYS), **options)
        except ValueError as exc:
            raise ConfigError(f"{exc} (check UDACITY_PORT, SIM_TIMEOUT_S and UDACITY_EXTRA_KEYS in myconfig.py)") \
                from exc

    def __init__(self, host: str = "127.0.0.1", port: int = 4567, *, timeout_s: float = 1.0,
                 command_timeout_s: float = 0.5, decimal: str = "auto", extra_keys: Sequence[str] = (),
                 start_timeout: float = 10.0) -> None:
        super().__init__()
        for name, value in (("timeout_s", timeout_s), ("command_timeout_s", command_timeout_s)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
                raise ValueError(f"UdacitySim: {name} must be > 0 seconds, got {value!r}")
        if decimal not in DECIMALS:
            raise ValueError(f"UdacitySim: decimal must be one of {DECIMALS}, got {decimal!r}")
        if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port <= 65535:
            raise ValueError(f"UdacitySim: port must be 0..65535, got {port!r}")
        bad = [k for k in extra_keys if not isinstance(k, str) or not k or k in STOCK_KEYS]
        if bad:
            raise ValueError(f"UdacitySim: extra_keys must be names of fork telemetry keys other than "
                             f"{STOCK_KEYS}, got {bad!r}")
        self.name = "UdacitySim"
        self.host = host
        self.port = port
        self.timeout_s = float(timeout_s)
        self.command_timeout_s = float(command_timeout_s)
        self.decimal = decimal
        self.extra_keys = tuple(extra_keys)
        self.start_timeout = start_timeout
        self.join_timeout = 5.0
        self._ready = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._sio: Any = None
        self._runner: Any = None
        self._site: Any = None
        self._stop_server: asyncio.Event | None = None
        # shared with the server thread, under self._state
        self._state = threading.Lock()
        self._telemetry: UdacityTelemetry | None = None
        self._seq = 0
        self._pending: deque[tuple[str, int, float]] = deque()  # (sid, seq, arrival monotonic)
        self._delivered = 0  # seq of the frame handed to the loop at its previous run
        self._last_message: float | None = None  # monotonic time of the latest telemetry (null too)
        self._manual = False
        self._sids: dict[str, str | None] = {}  # connected Socket.IO sid -> its Engine.IO sid
        self._connected_at: float | None = None
        self._replaced_reported_at: float | None = None
        self._tasks: set[asyncio.Task[Any]] = set()  # closings of replaced connections (kept alive)
        self._comma = decimal == ","
        self._neutral = False
        # statistics and reporting (loop thread unless noted)
        self.telemetry_count = 0
        self.null_count = 0
        self.steers_sent = 0
        self.neutral_replies = 0
        self._started_at: float | None = None
        self._stale_reported = False
        self._waiting_reported = False
        self._stall_reported = False
        self._bad_reported = OncePerKind(logger)  # bounded: one line per kind of bad telemetry

    # -- lifecycle --------------------------------------------------------------------------------
    def start(self) -> UdacitySim:
        """Start the server thread and wait until it listens.

        Raises:
            BridgeError: the port cannot be bound or python-socketio cannot serve the simulator.
        """
        if self._thread is not None:
            return self
        from parts.bridges.engineio3 import check_support

        check_support()
        super().start()
        if not self._ready.wait(self.start_timeout):
            self.shutdown()
            raise BridgeError(f"Udacity bridge: server did not start within {self.start_timeout} s")
        if self.error is not None:
            error = self.error
            self.shutdown()
            if isinstance(error, OSError):
                raise BridgeError(f"Udacity bridge cannot listen on {self.host}:{self.port} "
                                  f"({error.strerror or error}): another drive.py or manage.py may be running; "
                                  "stop it, or set UDACITY_PORT (the stock simulator only connects to 4567)") from error
            raise error
        self._started_at = time.monotonic()
        logger.info("Udacity bridge listening on %s:%d: start the simulator and choose Autonomous Mode",
                    self.host, self.port)
        return self

    def open(self) -> None:
        """In the server thread: make the event loop and listen."""
        self._loop = asyncio.new_event_loop()
        asyncio.set_event_loop(self._loop)
        try:
            self._runner = self._loop.run_until_complete(self._serve())
        except Exception as exc:  # reported by start() as one line (port taken ...), no traceback
            self.error = exc
            self.stop_event.set()
            self._loop.close()
            self._loop = None
        self._ready.set()

    def poll(self) -> Any:
        """In the server thread: serve until shutdown, then close every connection."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return self.NOTHING
        try:
            run_event_loop(loop, self._serve_until_stopped())
        finally:
            self.stop_event.set()
        return self.NOTHING

    def shutdown(self) -> None:
        """Leave the simulated car at steer (0, 0) (:meth:`neutral`, unless done already), then stop
        the server and join its thread."""
        if not self._neutral:
            self.neutral()
        loop, stop = self._loop, self._stop_server
        if loop is not None and stop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # closed between the check and the call
                loop.call_soon_threadsafe(stop.set)
        super().shutdown()
        logger.info("Udacity bridge: %d telemetry messages (%d manual), %d steers sent (%d neutral)",
                    self.telemetry_count, self.null_count, self.steers_sent, self.neutral_replies)

    def neutral(self, wait_s: float = 1.0) -> None:
        """Leave the simulated car at steer (0, 0): answer every waiting telemetry, and all that
        follow, with it; when none waits, send it unsolicited to the connected simulator (which
        otherwise keeps applying the last steer). Waits up to ``wait_s`` for the steers to leave."""
        with self._state:
            self._neutral = True
            targets = [sid for sid, _, _ in self._pending]
            self._pending.clear()
            if not targets:
                targets = list(self._sids)
        if targets:
            self._send_threadsafe([(sid, 0.0, 0.0) for sid in targets], neutral=True, wait_s=wait_s)

    # -- the loop's side --------------------------------------------------------------------------
    def run_threaded(self, angle: Any = None, throttle: Any = None) -> tuple[Any, ...]:
        """Answer the telemetries whose frame the loop has seen, and return the latest telemetry."""
        if self.error is not None:
            raise RuntimeError(f"Udacity bridge server failed: {self.error!r}") from self.error
        self.command(angle, throttle)  # frames of the previous loop not answered by SendCommands yet
        with self._state:
            tel = self._telemetry
            self._delivered = tel.seq if tel is not None else 0
            last, manual, connections = self._last_message, self._manual, len(self._sids)
            connected_at = self._connected_at
        now = time.monotonic()
        ok = tel is not None and last is not None and now - last <= self.timeout_s
        self._report(ok, now, last, connections, connected_at)
        extra = tel.extra if tel is not None else {}
        cte = parse_number(extra.get("cte"))
        lap = parse_number(extra.get("lapNumber"))
        base = (None, None, False, 0, None, None, None, None, manual, None, None, {}) if tel is None else (
            tel.image, tel.timestamp, ok, tel.seq, tel.speed, tel.speed, tel.steering_deg, tel.throttle, manual,
            cte, int(lap) if lap is not None else None,
            {k: v for k, v in extra.items() if k not in FORK_KEYS})
        return base + tuple(extra.get(k) for k in self.extra_keys)

    def command(self, angle: Any, throttle: Any) -> None:
        """Answer, with these commands, the telemetries whose frame the loop has been given.

        :meth:`run_threaded` does it at the start of the next loop with the loop's previous
        commands; :class:`parts.bridges.commands.SendCommands` at the end of the loop calls it at
        once, which saves the simulator a loop period per telemetry.
        """
        with self._state:
            replies = []
            while self._pending and self._pending[0][1] <= self._delivered:
                replies.append(self._pending.popleft()[0])
        if replies:
            self._send_threadsafe([(sid, angle, throttle) for sid in replies])

    def run(self, angle: Any = None, throttle: Any = None) -> tuple[Any, ...]:
        """Non-threaded use: start the server on the first call, then as :meth:`run_threaded`."""
        self.start()
        return self.run_threaded(angle, throttle)

    def _report(self, ok: bool, now: float, last: float | None, connections: int,
                connected_at: float | None) -> None:
        """One log line per problem: never connected, connected but silent, telemetry stopped."""
        if ok:
            if self._stale_reported:
                logger.info("Udacity simulator: telemetry resumed")
            self._stale_reported = self._waiting_reported = self._stall_reported = False
            return
        if last is None:
            if connections and connected_at is not None and now - connected_at > self.timeout_s:
                if not self._stall_reported:
                    self._stall_reported = True
                    logger.error("Udacity bridge: a client connected to %s:%d but sent no telemetry for %.1f s: "
                                 "is it the Udacity simulator in Autonomous Mode? (a Socket.IO client of "
                                 "another protocol version stays silent)", self.host, self.port,
                                 now - connected_at)
            elif (not connections and not self._waiting_reported and self._started_at is not None
                  and now - self._started_at > self.timeout_s):
                self._waiting_reported = True
                logger.warning("Udacity bridge: waiting for the simulator on %s:%d: start it and choose "
                               "Autonomous Mode (camera stale, pilot held until frames arrive)",
                               self.host, self.port)
            return
        if not self._stale_reported:
            self._stale_reported = True
            logger.warning("Udacity simulator: no telemetry for %.1f s (SIM_TIMEOUT_S = %.1f): camera marked "
                           "stale, pilot disengaged; check the simulator is running, not paused and still "
                           "in Autonomous Mode%s", now - last, self.timeout_s,
                           "" if connections else " (it disconnected)")

    # -- the server thread ------------------------------------------------------------------------
    async def _serve(self) -> Any:
        from aiohttp import web

        from parts.bridges.engineio3 import legacy_server, report_unreadable_frames

        self._stop_server = asyncio.Event()
        # websocket only: the simulator never polls; the default origin check keeps browser pages
        # of other sites from posing as the simulator
        sio = legacy_server(async_mode="aiohttp", transports=["websocket"], logger=False,
                            engineio_logger=False, max_http_buffer_size=MAX_MESSAGE_BYTES)
        report_unreadable_frames(sio, lambda why: self._bad_reported.report(
            logging.ERROR, f"Udacity bridge: closed a connection: {why} (each kind of problem is said once)"))
        self._sio = sio
        sio.on("connect", self._on_connect)
        sio.on("disconnect", self._on_disconnect)
        sio.on("telemetry", self._on_telemetry)
        app = web.Application()
        sio.attach(app)
        # shutdown_timeout: a connection still open at shutdown is dropped after 0.25 s, not 60
        runner = web.AppRunner(app, access_log=None, handle_signals=False, shutdown_timeout=0.25)
        await runner.setup()
        site = web.TCPSite(runner, self.host, self.port)
        self._site = site
        try:
            await site.start()
        except BaseException:
            await runner.cleanup()
            raise
        if self.port == 0:
            addresses = getattr(runner, "addresses", None) or []  # aiohttp's public list of bound addresses
            if addresses:
                self.port = int(addresses[0][1])
        return runner

    async def _serve_until_stopped(self) -> None:
        stop = self._stop_server
        if stop is None:
            return
        watchdog = asyncio.ensure_future(self._command_watchdog())
        try:
            await stop.wait()
        finally:
            watchdog.cancel()
            try:
                await self._site.stop()  # first stop listening: the simulator reconnects within 5 ms
                with self._state:
                    sids = list(self._sids)
                for sid in sids:  # close the simulator's websocket, or cleanup waits for it
                    await asyncio.wait_for(self._close_connection(sid), 2.0)
                await self._sio.shutdown()
            except (TimeoutError, OSError) as exc:
                logger.debug("Udacity bridge: closing the connection: %r", exc)
            finally:
                await self._runner.cleanup()

    async def _command_watchdog(self) -> None:
        """Answer telemetries the loop left unanswered for command_timeout_s with a neutral steer."""
        period = min(0.05, self.command_timeout_s / 4)
        while True:
            await asyncio.sleep(period)
            now = time.monotonic()
            with self._state:
                late = []
                while self._pending and now - self._pending[0][2] > self.command_timeout_s:
                    late.append(self._pending.popleft()[0])
            if late:
                logger.warning("Udacity bridge: the drive loop gave no command for %.2f s: answered the "
                               "simulator with a neutral steer", self.command_timeout_s)
                await self._emit_steers([(sid, 0.0, 0.0) for sid in late], neutral=True)

    async def _close_connection(self, sid: str) -> None:
        """Close a simulator's websocket (a Socket.IO v2 client ignores a namespace DISCONNECT)."""
        with self._state:
            eio_sid = self._sids.get(sid)
        eio = getattr(self._sio, "eio", None)
        if eio is not None and eio_sid is not None:
            await eio.disconnect(eio_sid)
        else:  # no Engine.IO handle: leave the namespace at least (its events are then dropped)
            await self._sio.disconnect(sid)

    async def _on_connect(self, sid: str, environ: dict[str, Any], auth: Any = None) -> None:
        manager = getattr(self._sio, "manager", None)
        eio_sid = manager.eio_sid_from_sid(sid, "/") if hasattr(manager, "eio_sid_from_sid") else None
        with self._state:
            older = list(self._sids)
            self._sids[sid] = eio_sid
            self._connected_at = time.monotonic()
        logger.info("Udacity simulator connected from %s", environ.get("REMOTE_ADDR", "?"))
        if older:
            now = time.monotonic()
            if self._replaced_reported_at is None or now - self._replaced_reported_at > 10.0:
                self._replaced_reported_at = now
                logger.warning("Udacity bridge: a second simulator connected from %s: closed the previous "
                               "connection (one simulator at a time; is another one running?)",
                               environ.get("REMOTE_ADDR", "?"))
            for old in older:  # later, not inside this handler: the new connection is still opening
                task = asyncio.ensure_future(self._close_connection(old))
                self._tasks.add(task)
                task.add_done_callback(self._tasks.discard)

    async def _on_disconnect(self, sid: str, reason: Any = None) -> None:
        with self._state:
            self._sids.pop(sid, None)
            self._pending = deque(p for p in self._pending if p[0] != sid)
        logger.info("Udacity simulator disconnected%s", f" ({reason})" if reason else "")

    async def _on_telemetry(self, sid: str, data: Any = None) -> None:
        now = time.monotonic()
        if data is None:  # manual override: keep the chain alive, apply nothing
            with self._state:
                self._last_message = now
                self._manual = True
            self.null_count += 1
            await self._sio.emit("manual", {}, to=sid)
            return
        try:
            tel = self._parse(sid, data)
        except ValueError as exc:
            self._bad_reported.report(logging.ERROR, f"Udacity bridge: unusable telemetry ({exc}): answered with a "
                                      "neutral steer (each kind of problem is said once)")
            await self._emit_steers([(sid, 0.0, 0.0)], neutral=True)
            return
        self.telemetry_count += 1
        with self._state:
            self._seq += 1
            tel = UdacityTelemetry(self._seq, tel.sid, tel.image, tel.timestamp, tel.steering_deg, tel.throttle,
                            tel.speed, tel.extra)
            self._telemetry = tel
            self._last_message = now
            self._manual = False
            neutral = self._neutral
            if not neutral:
                self._pending.append((sid, tel.seq, now))
        if neutral:
            await self._emit_steers([(sid, 0.0, 0.0)], neutral=True)

    def _parse(self, sid: str, data: Any) -> UdacityTelemetry:
        """The telemetry in the event's data; ValueError says what is wrong with it."""
        from parts.bridges.frames import decode_frame

        if not isinstance(data, dict):
            raise ValueError(f"expected an object, got {type(data).__name__}")
        if not isinstance(data.get("image"), str) or not data["image"]:
            raise ValueError("no 'image' field")
        image = decode_frame(data["image"], formats=("JPEG",))  # the simulator's EncodeToJPG
        if self.decimal == "auto" and not self._comma and uses_decimal_comma(data):
            self._comma = True
            logger.info("Udacity simulator sends decimal commas (its locale): steer values follow")
        speed = parse_number(data.get("speed"))
        extra = {}
        for key, value in data.items():
            if key not in STOCK_KEYS:
                number = parse_number(value)
                extra[key] = value if number is None else number
        return UdacityTelemetry(0, sid, image, time.time(), parse_number(data.get("steering_angle")),
                         parse_number(data.get("throttle")), None if speed is None else speed * MS_PER_MPH, extra)

    def _send_threadsafe(self, replies: list[tuple[str, Any, Any]], neutral: bool = False,
                         wait_s: float = 0.0) -> None:
        """Hand steers to the server thread; wait up to ``wait_s`` for them to leave (0: never
        block the caller)."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return
        try:
            future = asyncio.run_coroutine_threadsafe(self._emit_steers(replies, neutral), loop)
        except RuntimeError:  # the loop closed meanwhile: nobody to answer
            return
        if wait_s > 0:
            with contextlib.suppress(Exception):  # timed out, or the connection closed meanwhile
                future.result(wait_s)

    async def _emit_steers(self, replies: list[tuple[str, Any, Any]], neutral: bool = False) -> None:
        decimal = "," if self._comma else "."
        for sid, angle, throttle in replies:
            await self._sio.emit("steer", {"steering_angle": format_command(angle, decimal),
                                           "throttle": format_command(throttle, decimal)}, to=sid)
            self.steers_sent += 1
            self.neutral_replies += int(neutral)
