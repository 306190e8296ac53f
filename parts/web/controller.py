"""WebController: the web page as a threaded part of the drive loop.

>>> from parts.web.controller import WebController
>>> web = WebController(port=0)            # 0 = any free port (tests); the car uses 8887
>>> V.add(web, inputs=list(WebController.INPUTS), outputs=list(WebController.OUTPUTS),
...       threaded=True)                   # doctest: +SKIP

The server (python-socketio on aiohttp) runs in the part's own thread and event loop. The loop
thread only calls :meth:`WebController.run_threaded`, which hands the loop's telemetry and camera
frame to the server and returns the browsers' commands through the lock-protected
:class:`~parts.web.state.ControlState`, after the dead-man rule.
"""

from __future__ import annotations

import asyncio
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from parts.web.pairing import is_loopback, page_url, resolve_token, terminal_qr
from parts.web.pathview import PathSlot, path_telemetry
from parts.web.server import LatestFrame, ListenError, WebServer
from parts.web.state import ControlState, Telemetry
from vehicle.part import ThreadedPart, run_event_loop

if TYPE_CHECKING:
    from parts.web.carlink import CarLink

logger = logging.getLogger(__name__)


def _num(value: Any) -> float | None:
    if value is None or isinstance(value, bool):
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def car_name(cfg: Any) -> str:
    """CAR_NAME, else the car folder's name."""
    return cfg.CAR_NAME or Path(cfg.CAR_PATH).resolve().name


class WebController(ThreadedPart):
    """Drive from a browser: camera view, joystick/keyboard/gamepad, modes, recording, e-stop.

    Add it with ``threaded=True``, ``inputs=list(INPUTS)``, ``outputs=list(OUTPUTS)`` (or rename
    the outputs, e.g. ``web/angle``, to arbitrate with a gamepad). Inputs the car does not produce
    may be None.

    Args:
        host: interface to bind. Default ``"127.0.0.1"`` (this machine only); ``"0.0.0.0"`` for a
            phone on the same network, which then needs the pairing token.
        port: TCP port. Default 8887; 0 picks a free one (read :attr:`port` after :meth:`start`).
        token: pairing token. Default None: none on localhost, a random one otherwise.
        deadman_s: seconds without a message from the driving browser before a moving car falls
            back to throttle 0 and user mode. Default 0.5.
        init_mode: drive mode at start. Default ``"user"``.
        max_throttle: initial throttle scale in [0, 1]. Default 0.5.
        models_dir: folder of ``*.pt`` files for the model picker. Default None (no picker).
        max_speed_limit: largest speed limit the page offers, m/s. Default 5.0.
        telemetry_hz: rate of state updates to the page. Default 20.
        jpeg_quality: JPEG quality of the camera view, 1-100. Default 80.
        allowed_hosts: host names, besides IP addresses, ``localhost``, this machine's name and
            ``host``, that the page may be opened by (a DNS name of the car). Requests naming
            another host are refused (DNS rebinding). Default none.
        start_timeout: seconds :meth:`start` waits for the server to listen. Default 10.
        clock: monotonic seconds for the dead-man timer. Default ``time.monotonic``.
        link: the laptop link (:class:`parts.web.carlink.CarLink`: tubs, models, pilot switch for
            the paired user). Default None.
        announce: announce the car on the local network (mDNS) when it listens on it and has a
            link (:mod:`parts.web.announce`). Default False.
    """

    #: memory keys the part reads (telemetry for the page), in this order
    INPUTS: ClassVar[tuple[str, ...]] = (
        "cam/image_array", "user/mode", "recording", "estop", "tub/num_records", "angle", "throttle", "pilot/angle",
        "pilot/throttle", "pilot/model", "sim/speed", "enc/speed", "loop/rate_hz", "loop/overruns", "behavior/label",
        "run_pilot", "pilot/load_error", "sim/cte", "sim/lap", "sim/off_track", "js/status", "enc/ok", "imu/ok",
        "gps/ok", "lidar/ok", "obstacle/stop", "obstacle/distance", "battery/voltage",
        # the path-follow view's (parts.web.pathview.PATH_INPUTS; a test keeps the two equal)
        "loc/x", "loc/y", "loc/angle", "loc/std", "loc/ok", "loc/source", "path/xy", "path/version",
        "path/target_x", "path/target_y", "path/cte", "path/state",
    )
    #: every input is telemetry for the page: it may be absent (None) and is the last loop's value
    #: when a part added after the controller produces it (drive mode, pilot, tub writer ...)
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = INPUTS
    FEEDBACK: ClassVar[tuple[str, ...]] = INPUTS
    #: memory keys the part writes, in this order
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/angle", "user/throttle", "user/mode", "recording", "estop",
                                          "user/speed_limit", "pilot/model_request", "web/behavior_step",
                                          "web/path_command")

    def __init__(self, host: str = "127.0.0.1", port: int = 8887, token: str | None = None, *,
                 deadman_s: float = 0.5, init_mode: str = "user", max_throttle: float = 0.5,
                 models_dir: str | Path | None = None, max_speed_limit: float = 5.0,
                 telemetry_hz: float = 20.0, jpeg_quality: int = 80,
                 allowed_hosts: Sequence[str] = (), start_timeout: float = 10.0,
                 clock: Callable[[], float] = time.monotonic, link: CarLink | None = None,
                 announce: bool = False) -> None:
        super().__init__()
        self.name = "WebController"
        self.token = resolve_token(host, token)
        self.state = ControlState(deadman_s=deadman_s, init_mode=init_mode,
                                  max_throttle=max_throttle, clock=clock)
        self.frames = LatestFrame(jpeg_quality)
        self.paths = PathSlot()
        self.server = WebServer(self.state, self.frames, host=host, port=port, token=self.token,
                                paths=self.paths,
                                models_dir=Path(models_dir) if models_dir is not None else None,
                                max_speed_limit=max_speed_limit, telemetry_hz=telemetry_hz,
                                extra_hosts=tuple(allowed_hosts), link=link)
        self.link = link
        self.announce = announce
        self._announcer: Any = None
        self.start_timeout = start_timeout
        self._ready = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._runner: Any = None

    @classmethod
    def from_config(cls, cfg: Any) -> WebController:
        """Build from a car's settings (``WEB_*``, ``CAR_*``, ``MODELS_PATH``, ``DATA_PATH``)."""
        link = None
        if cfg.CAR_LINK:
            from parts.web.carlink import CarLink

            link = CarLink(cfg.path("DATA_PATH"), cfg.path("MODELS_PATH"), name=car_name(cfg),
                           max_model_bytes=int(cfg.CAR_MAX_MODEL_MB * 1e6))
        return cls(cfg.WEB_HOST, cfg.WEB_CONTROL_PORT, cfg.WEB_TOKEN, deadman_s=cfg.WEB_DEADMAN_S,
                   init_mode=cfg.DEFAULT_MODE, max_throttle=cfg.WEB_MAX_THROTTLE,
                   models_dir=cfg.path("MODELS_PATH"), max_speed_limit=cfg.WEB_MAX_SPEED_LIMIT,
                   telemetry_hz=cfg.WEB_TELEMETRY_HZ, jpeg_quality=cfg.WEB_JPEG_QUALITY,
                   allowed_hosts=cfg.WEB_ALLOWED_HOSTS, link=link, announce=cfg.CAR_ANNOUNCE)

    # -- lifecycle --------------------------------------------------------------------------------
    @property
    def port(self) -> int:
        """The TCP port the server listens on (the real one once started with port 0)."""
        return self.server.port

    @property
    def url(self) -> str:
        """The page's URL for a browser, with the token when one is needed."""
        return page_url(self.server.host, self.server.port, self.token)

    def start(self) -> WebController:
        """Start the server thread and wait until it listens.

        Raises:
            ListenError: the port is taken or the address cannot be bound (the message says the fix).
            TimeoutError: the server did not start within ``start_timeout`` seconds.
        """
        if self._thread is not None:
            return self
        super().start()
        if not self._ready.wait(self.start_timeout):
            self.shutdown()
            raise TimeoutError(f"web controller did not start within {self.start_timeout} s")
        if self.error is not None:
            raise self.error
        if self.token is None:
            logger.info("Web controller: open %s", self.url)
        elif is_loopback(self.server.host):
            logger.info("Web controller: open %s (pairing token required)", self.url)
        else:
            qr = terminal_qr(self.url)
            logger.warning("Web controller reachable from the network (%s): pair a browser by "
                           "opening %s%s", self.server.host, self.url, f"\n{qr}" if qr else "")
            if self.announce and self.link is not None:
                from parts.web.announce import Announcer

                self._announcer = Announcer(self.link.name, self.server.port, self.server.host).start()
        return self

    def open(self) -> None:
        """In the web thread: create its event loop and bind the server."""
        try:
            self._loop = asyncio.new_event_loop()
            asyncio.set_event_loop(self._loop)
            self._runner = self._loop.run_until_complete(self.server.start())
        except ListenError as exc:  # a user's mistake: start() raises it, one line, no traceback
            self.error = exc
            self.stop_event.set()
            self._ready.set()
            return
        except BaseException as exc:
            self.error = exc
            self._ready.set()
            raise
        self._ready.set()

    def poll(self) -> Any:
        """In the web thread: serve until shutdown."""
        loop = self._loop
        assert loop is not None  # open() ran  # noqa: S101
        try:
            run_event_loop(loop, self.server.serve_until_stopped(self._runner))
        finally:
            self.stop_event.set()
        return self.NOTHING

    def shutdown(self) -> None:
        """Close every connection, stop the server and join its thread."""
        if self._announcer is not None:
            self._announcer.stop()
            self._announcer = None
        self.server.stop()
        super().shutdown()

    # -- the loop's side --------------------------------------------------------------------------
    def run_threaded(self, *inputs: Any) -> tuple[Any, ...]:
        """Hand this loop's telemetry and frame to the page; return the browsers' commands:
        ``(user/angle, user/throttle, user/mode, recording, estop, user/speed_limit,
        pilot/model_request, web/behavior_step, web/path_command)``."""
        if self.error is not None:
            raise RuntimeError(f"web controller thread failed: {self.error!r}") from self.error
        values = dict(zip(self.INPUTS, inputs, strict=False))
        image = values.get("cam/image_array")
        if isinstance(image, np.ndarray) and self.server.has_viewers:
            self.frames.put(image)
            self.server.notify_frame()
        speed = _num(values.get("sim/speed"))
        if speed is None:
            speed = _num(values.get("enc/speed"))
        records = values.get("tub/num_records")
        overruns = values.get("loop/overruns")
        mode = values.get("user/mode")
        recording = values.get("recording")
        estop = values.get("estop")
        model = values.get("pilot/model")
        behavior = values.get("behavior/label")
        run_pilot, load_error = values.get("run_pilot"), values.get("pilot/load_error")
        lap, off_track = values.get("sim/lap"), values.get("sim/off_track")
        pad = values.get("js/status")
        self.paths.put(values.get("path/xy"), values.get("path/version"))
        self.state.report(Telemetry(
            mode=mode if isinstance(mode, str) else None,
            recording=bool(recording) if isinstance(recording, bool | np.bool_) else None,
            estop=bool(estop) if isinstance(estop, bool | np.bool_) else None,
            num_records=int(records) if isinstance(records, int | np.integer) else None,
            angle=_num(values.get("angle")), throttle=_num(values.get("throttle")),
            pilot_angle=_num(values.get("pilot/angle")),
            pilot_throttle=_num(values.get("pilot/throttle")),
            pilot_model=Path(model).name if isinstance(model, str) else None,
            speed=speed, loop_rate_hz=_num(values.get("loop/rate_hz")),
            loop_overruns=int(overruns) if isinstance(overruns, int | np.integer) else None,
            behavior=behavior if isinstance(behavior, str) else None,
            pilot_active=bool(run_pilot) if isinstance(run_pilot, bool | np.bool_) else None,
            pilot_error=load_error[:300] if isinstance(load_error, str) else None,
            sim_cte=_num(values.get("sim/cte")),
            sim_laps=int(lap) if isinstance(lap, int | np.integer) else None,
            sim_off_track=bool(off_track) if isinstance(off_track, bool | np.bool_) else None,
            car_gamepad=pad if pad in ("connected", "silent", "lost") else None,
            sensors={name: bool(ok) for name in ("enc", "imu", "gps", "lidar")
                     if isinstance(ok := values.get(f"{name}/ok"), bool | np.bool_)},
            obstacle_stop=bool(stop) if isinstance(stop := values.get("obstacle/stop"), bool | np.bool_) else None,
            obstacle_distance=_num(values.get("obstacle/distance")),
            battery_v=_num(values.get("battery/voltage")),
            path=path_telemetry(values)))
        cmd = self.state.outputs()
        return (cmd.angle, cmd.user_throttle(), cmd.mode, cmd.recording, cmd.estop,
                cmd.speed_limit, cmd.model_request, cmd.behavior_step, cmd.path_command)

    def run(self, *inputs: Any) -> tuple[Any, ...]:
        """Non-threaded use: start the server on first call, then as :meth:`run_threaded`."""
        self.start()
        return self.run_threaded(*inputs)
