"""The Udacity simulator part against the faithful fake simulator (fixtures.fake_udacity_client)."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest

pytest.importorskip("socketio")
pytest.importorskip("aiohttp")
pytest.importorskip("wsproto")

from fixtures.fake_udacity_client import FakeUdacityClient, n4, parse_like_csharp  # noqa: E402

from parts.bridges.errors import BridgeError  # noqa: E402
from parts.bridges.udacity_protocol import MS_PER_MPH, format_command, parse_number  # noqa: E402
from parts.bridges.udacity_sim import UdacitySim  # noqa: E402


class LoopDriver:
    """Calls run_threaded like the Vehicle does, at ``hz``, with commands from ``command(outputs)``."""

    def __init__(self, part: UdacitySim, command: Callable[[dict[str, Any]], tuple[float, float]],
                 hz: float = 100.0) -> None:
        self.part, self.command, self.period = part, command, 1.0 / hz
        self.outputs: dict[str, Any] = {}
        self.history: list[dict[str, Any]] = []
        self.angle: float | None = None
        self.throttle: float | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            values = self.part.run_threaded(self.angle, self.throttle)
            self.outputs = dict(zip(self.part.OUTPUTS, values, strict=True))
            self.history.append(self.outputs)
            if self.outputs["cam/image_array"] is not None:
                self.angle, self.throttle = self.command(self.outputs)
            time.sleep(self.period)

    def __enter__(self) -> LoopDriver:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)


@contextmanager
def udacity(**kwargs: Any) -> Iterator[UdacitySim]:
    part = UdacitySim(port=0, **kwargs).start()
    try:
        yield part
    finally:
        part.shutdown()


def test_parse_number_reads_every_locale() -> None:
    assert parse_number("0.1234") == 0.1234
    assert parse_number("0,1234") == 0.1234
    assert parse_number("-25,0000") == -25.0
    assert parse_number("1,234.5") == 1234.5
    assert parse_number("1.234,5") == 1234.5
    assert parse_number("1 234,5") == 1234.5
    assert parse_number(3) == 3.0
    for junk in ("", "abc", None, True, "nan", "inf", [1]):
        assert parse_number(junk) is None


def test_extra_keys_become_namespaced_snake_case_keys() -> None:
    from parts.bridges.udacity_protocol import extra_key
    from vehicle.keys import is_valid_key

    assert extra_key("lapNumber") == "sim/lap_number"
    assert extra_key("currentWayPoint") == "sim/current_way_point"
    assert extra_key("tot_obes") == "sim/tot_obes"
    assert is_valid_key(extra_key("Weird Key-2"))


def test_format_command_is_a_clamped_fixed_point_string() -> None:
    assert format_command(0.25) == "0.250000"
    assert format_command(-0.5, ",") == "-0,500000"
    assert format_command(1e-7) == "0.000000"  # never "1e-07"
    assert format_command(3.0) == "1.000000"
    assert format_command(None) == "0.000000"
    assert format_command(float("nan")) == "0.000000"
    # what the simulator reads back, in its own locale
    assert parse_like_csharp(format_command(0.25)) == 0.25
    assert parse_like_csharp(format_command(0.25, ","), comma=True) == 0.25
    assert parse_like_csharp("0.1", comma=True) == 1.0  # the bug a '.' causes in a comma locale


def test_lockstep_one_steer_per_telemetry_with_the_loop_commands() -> None:
    with udacity() as part, FakeUdacityClient(part.port) as sim, \
            LoopDriver(part, lambda out: (0.3, 0.5)) as loop:
        assert sim.wait_for(lambda c: len(c.steers) >= 30, 15)
        outputs = loop.outputs
    assert sim.stalls == 0 and sim.connect_attempts == 1
    # every steer the simulator got carries the loop's command, as strings with '.' decimals
    assert all(s == (0.3, 0.5) for s in sim.steers[2:])
    assert all(isinstance(v, str) and "." in v for r in sim.raw_steers for v in r.values())
    # lockstep: at most the two chains opened at start are in flight, never more
    assert 0 <= sim.telemetry_sent - len(sim.steers) <= 2
    image = outputs["cam/image_array"]
    assert isinstance(image, np.ndarray) and image.shape == (160, 320, 3) and image.dtype == np.uint8
    assert outputs["cam/ok"] is True and outputs["sim/manual"] is False
    assert outputs["sim/steering_deg"] == pytest.approx(0.3 * 25, abs=1e-3)
    assert outputs["sim/speed"] > 0 and outputs["enc/speed"] == outputs["sim/speed"]
    assert outputs["sim/cte"] is None and outputs["sim/lap"] is None and outputs["sim/extra"] == {}


def test_the_answer_is_computed_from_the_frame_it_answers() -> None:
    """The steer for a telemetry uses the command the loop computed after seeing that telemetry."""
    def command(out: dict[str, Any]) -> tuple[float, float]:
        # encode the speed the loop saw into the steering (a "pilot" with a known output)
        return round(out["sim/speed"] / 20, 4), 0.4

    with udacity() as part, FakeUdacityClient(part.port) as sim, LoopDriver(part, command):
        assert sim.wait_for(lambda c: len(c.steers) >= 40, 15)
    # the fake's speed only grows; a steer based on the current frame never lags two frames behind
    steering = [s for s, _ in sim.steers[2:]]
    assert steering == sorted(steering) and steering[-1] > steering[0]


def test_comma_locale_simulator_gets_decimal_commas_back() -> None:
    with udacity() as part, FakeUdacityClient(part.port, comma_decimals=True) as sim, \
            LoopDriver(part, lambda out: (-0.25, 0.75)) as loop:
        assert sim.wait_for(lambda c: len(c.steers) >= 20, 15)
        outputs = loop.outputs
    assert sim.steers[-1] == (-0.25, 0.75)  # with '.' the sim would read -25 and 75
    assert all("," in v for v in sim.raw_steers[-1].values())
    assert outputs["sim/steering_deg"] == pytest.approx(-6.25, abs=1e-3)
    assert outputs["sim/speed"] == pytest.approx(sim.car.speed, rel=0.2)


def test_manual_override_is_answered_with_manual_and_reported() -> None:
    with udacity() as part, FakeUdacityClient(part.port) as sim, \
            LoopDriver(part, lambda out: (0.0, 0.2)) as loop:
        assert sim.wait_for(lambda c: len(c.steers) >= 5, 15)
        sim.hold_manual(True)
        assert sim.wait_for(lambda c: c.manuals >= 10, 15)
        assert sim.wait_for(lambda c: loop.outputs.get("sim/manual") is True, 5)
        assert loop.outputs["cam/ok"] is True  # the simulator is alive, only the user drives
        steers_during = len(sim.steers)
        sim.hold_manual(False)
        assert sim.wait_for(lambda c: len(c.steers) >= steers_during + 10, 15)
        assert sim.wait_for(lambda c: loop.outputs.get("sim/manual") is False, 5)
    assert sim.null_telemetry_sent >= 10 and sim.stalls == 0


def test_fork_keys_are_passed_through_under_sim() -> None:
    extra = {"cte": lambda car: car.lateral, "lapNumber": 2, "sim_time": 12.5, "crash": "none"}
    with udacity(extra_keys=("sim_time",)) as part, FakeUdacityClient(part.port, extra=extra) as sim, \
            LoopDriver(part, lambda out: (0.5, 0.5)) as loop:
        assert sim.wait_for(lambda c: len(c.steers) >= 10, 15)
        outputs = loop.outputs
    assert isinstance(outputs["sim/cte"], float)
    assert outputs["sim/lap"] == 2
    assert outputs["sim/extra"] == {"sim_time": 12.5, "crash": "none"}
    assert outputs["sim/sim_time"] == 12.5
    assert part.OUTPUTS[-1] == "sim/sim_time"


def test_lost_simulator_makes_the_camera_stale_with_one_log_line(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level("INFO", logger="parts.bridges.udacity_sim"), udacity(timeout_s=0.3) as part, \
            LoopDriver(part, lambda out: (0.0, 0.3)) as loop:
        with FakeUdacityClient(part.port) as sim:
            assert sim.wait_for(lambda c: len(c.steers) >= 5, 15)
            assert loop.outputs["cam/ok"] is True
        deadline = time.monotonic() + 5
        while loop.outputs["cam/ok"] and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.5)  # many more loops while stale
        assert loop.outputs["cam/ok"] is False
        assert loop.outputs["cam/image_array"] is not None  # the last frame, marked stale
    stale = [r for r in caplog.records if "no telemetry for" in r.getMessage()]
    assert len(stale) == 1
    assert "SIM_TIMEOUT_S" in stale[0].getMessage()


def test_a_stuck_loop_gets_the_simulator_a_neutral_steer() -> None:
    with udacity(command_timeout_s=0.2) as part, FakeUdacityClient(part.port) as sim:
        # nobody calls run_threaded: the loop is stuck
        assert sim.wait_for(lambda c: len(c.steers) >= 6, 15)
    assert set(sim.steers) == {(0.0, 0.0)}
    assert part.neutral_replies == part.steers_sent >= 6


def test_neutral_answers_waiting_telemetry_with_zero() -> None:
    with udacity(command_timeout_s=30) as part, FakeUdacityClient(part.port) as sim:
        assert sim.wait_for(lambda c: c.telemetry_sent >= 2, 15)
        part.run_threaded(0.5, 1.0)  # the loop saw the frame ...
        part.neutral()  # ... and stops before answering
        assert sim.wait_for(lambda c: len(c.steers) >= 2, 5)
        assert sim.wait_for(lambda c: len(c.steers) >= 10, 5)  # later telemetries: neutral too
    assert set(sim.steers) == {(0.0, 0.0)}


def test_numeric_steer_values_would_stall_the_simulator() -> None:
    """What the fake reproduces (and why the part always sends strings)."""
    with udacity(command_timeout_s=0.2) as part, FakeUdacityClient(part.port) as sim:
        assert sim.wait_for(lambda c: len(c.steers) >= 2, 15)
        frame = '{"steering_angle":0.1,"throttle":0.2}'
        sim._on_frame(_Recorder(), '42["steer",' + frame + "]")
    assert sim.stalls == 1


class _Recorder:
    def __init__(self) -> None:
        self.sent: list[str] = []

    def send(self, text: str) -> None:
        self.sent.append(text)


def test_port_in_use_is_one_clear_error() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(BridgeError, match=rf"cannot listen on 127.0.0.1:{port} .*UDACITY_PORT"):
            UdacitySim(port=port).start()


def test_waiting_for_the_simulator_is_said_once(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level("INFO", logger="parts.bridges.udacity_sim"), udacity(timeout_s=0.1) as part:
        for _ in range(30):
            out = part.run_threaded(None, None)
            time.sleep(0.01)
    assert out[:3] == (None, None, False)
    waiting = [r for r in caplog.records if "waiting for the simulator" in r.getMessage()]
    assert len(waiting) == 1


def test_bad_settings_are_rejected() -> None:
    with pytest.raises(ValueError, match="timeout_s"):
        UdacitySim(timeout_s=0)
    with pytest.raises(ValueError, match="decimal"):
        UdacitySim(decimal=";")
    with pytest.raises(ValueError, match="extra_keys"):
        UdacitySim(extra_keys=("image",))


def test_n4_formats_like_csharp() -> None:
    assert n4(1.5) == "1.5000"
    assert n4(-0.25, comma=True) == "-0,2500"
    assert n4(30.2 * 1, comma=False) == "30.2000"
    assert MS_PER_MPH == pytest.approx(1 / 2.23693629)


def test_send_commands_answers_in_the_loop_that_saw_the_frame() -> None:
    """With SendCommands last in the loop the steer leaves at once, with this loop's commands."""
    from parts.bridges.commands import SendCommands

    with udacity(command_timeout_s=30) as part, FakeUdacityClient(part.port) as sim:
        send = SendCommands(part)
        assert sim.wait_for(lambda c: c.telemetry_sent >= 2, 15)
        time.sleep(0.1)
        part.run_threaded(None, None)  # loop start: both frames handed to the loop, nothing answered
        assert sim.steers == []
        send.run(0.25, 0.5)  # loop end: the commands computed from them
        assert sim.wait_for(lambda c: len(c.steers) >= 2, 5)
        part.run_threaded(0.25, 0.5)  # the next loop start has nothing left to answer for them
        time.sleep(0.2)
    assert sim.steers[:2] == [(0.25, 0.5), (0.25, 0.5)]
    assert send.name == "UdacitySim.commands"


# -- review fixes: the simulator keeps applying the last steer it got, so the last must be neutral --
class _Pilot:
    INPUTS = ("cam/image_array",)
    OUTPUTS = ("angle", "throttle")

    def run(self, image: Any) -> tuple[float | None, float | None]:
        return (0.3, 0.6) if image is not None else (None, None)


class _CtrlC:
    """Raises KeyboardInterrupt (what Ctrl-C does in the loop thread) once ``ready()`` is true."""

    def __init__(self, ready: Callable[[], bool]) -> None:
        self.ready = ready

    def run(self) -> None:
        if self.ready():
            raise KeyboardInterrupt


def test_ctrl_c_leaves_the_simulated_car_at_steer_zero() -> None:
    """Every telemetry was answered at once (SendCommands): nothing waits when the loop stops, yet
    the simulator's last steer must be (0, 0), or its car drives on with the pilot's throttle."""
    from parts.bridges.commands import SendCommands
    from vehicle import Vehicle

    part = UdacitySim(port=0, command_timeout_s=30)
    V = Vehicle()
    V.add(part, threaded=True, feedback=("angle", "throttle"))
    V.add(_Pilot())
    V.add(SendCommands(part))
    part.start()
    # Unity takes 0.2 s to render the next frame: Ctrl-C comes while the simulator renders, every
    # telemetry answered (with the pilot's command), none waiting for the loop
    with FakeUdacityClient(part.port, frame_time_s=0.2) as sim:
        V.add(_CtrlC(lambda: len(sim.steers) >= 6 and sim.in_flight == 0), outputs=[])
        with pytest.raises(KeyboardInterrupt):
            V.start(rate_hz=50, max_loop_count=2000)
        assert sim.wait_for(lambda c: c.steers[-1:] == [(0.0, 0.0)], 5)
        assert (0.3, 0.6) in sim.steers and sim.car.throttle == 0.0
    assert not part.running
    assert part.neutral_replies >= 1


def test_shutdown_alone_also_leaves_the_car_at_steer_zero() -> None:
    from parts.bridges.commands import SendCommands

    with udacity(command_timeout_s=30) as part, FakeUdacityClient(part.port) as sim:
        send = SendCommands(part)
        assert sim.wait_for(lambda c: c.telemetry_sent >= 2, 15)
        for _ in range(20):
            part.run_threaded(None, None)
            send.run(-0.5, 1.0)
            time.sleep(0.01)
        assert sim.wait_for(lambda c: c.steers[-1:] == [(-0.5, 1.0)], 5)
        part.shutdown()  # no neutral() first: a caller outside a Vehicle
        assert sim.wait_for(lambda c: c.steers[-1:] == [(0.0, 0.0)], 5)


def test_bad_telemetry_is_one_log_line_per_kind_and_bounded(caplog: pytest.LogCaptureFixture) -> None:
    """Issue 27 item 15: 300 bad images whose error text carries the sender's numbers give one
    line per kind of problem, and the memory of what was reported stays bounded."""
    import base64
    import json

    import cv2
    from fixtures.fake_udacity_client import URL_QUERY, WebSocketClient

    with caplog.at_level("INFO", logger="parts.bridges"), udacity() as part:
        ws = WebSocketClient("127.0.0.1", part.port, f"/socket.io/?{URL_QUERY}")
        try:
            assert (ws.receive(5) or "").startswith("0")
            for i in range(300):  # base64 error texts carry the sender's length: each a new text
                ok, png = cv2.imencode(".png", np.zeros((1, i + 1, 3), np.uint8))
                image = base64.b64encode(png.tobytes()).decode() if i % 3 == 0 else "A" * (4 * i + 1)
                ws.send("42" + json.dumps(["telemetry", {"image": image, "steering_angle": "0", "throttle": "0",
                                                         "speed": "0"}]))
            deadline = time.monotonic() + 20
            steers = 0
            while steers < 300 and time.monotonic() < deadline:
                frame = ws.receive(0.5)
                steers += bool(frame and frame.startswith('42["steer"'))
            assert steers == 300
        finally:
            ws.close()
        bad = [r.getMessage() for r in caplog.records if "unusable telemetry" in r.getMessage()]
        assert 1 <= len(bad) <= 4, bad
        assert len(part._bad_reported) <= 16


def test_an_over_size_message_is_said_once(caplog: pytest.LogCaptureFixture) -> None:
    from fixtures.fake_udacity_client import URL_QUERY, WebSocketClient, WebSocketClosed

    with caplog.at_level("INFO", logger="parts.bridges"), udacity() as part:
        for _ in range(2):
            ws = WebSocketClient("127.0.0.1", part.port, f"/socket.io/?{URL_QUERY}")
            try:
                assert (ws.receive(5) or "").startswith("0")
                with pytest.raises((WebSocketClosed, OSError)):
                    ws.send('42["telemetry",{"image":"' + "A" * 5_000_000 + '"}]')
                    deadline = time.monotonic() + 10
                    while time.monotonic() < deadline:
                        ws.receive(0.2)
            finally:
                ws.close()
        deadline = time.monotonic() + 5
        while not [r for r in caplog.records if "too large" in r.getMessage()] and time.monotonic() < deadline:
            time.sleep(0.05)
    lines = [r.getMessage() for r in caplog.records if "too large" in r.getMessage()]
    assert len(lines) == 1 and "4000000" in lines[0].replace(" ", "").replace(",", ""), lines
