"""The Engine.IO v3 / Socket.IO v2 compatibility layer against the faithful fake Udacity client.

The stock python-socketio 5 server must fail against the fake exactly as it fails against the
real simulator (handshake accepted, events dropped), which proves the fake is faithful; the
legacy server must then work against the same fake.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("socketio")
pytest.importorskip("aiohttp")
pytest.importorskip("wsproto")

from fixtures.fake_udacity_client import FakeUdacityClient, WebSocketClient  # noqa: E402

from parts.bridges import engineio3  # noqa: E402
from parts.bridges.errors import BridgeError  # noqa: E402


@contextlib.contextmanager
def drive_py_server(sio: Any) -> Iterator[dict[str, Any]]:
    """drive.py's server on aiohttp: steer (string values) for every telemetry, manual for null."""
    from aiohttp import web

    seen: dict[str, Any] = {"connects": 0, "telemetry": 0, "null": 0}

    @sio.on("connect")
    async def connect(sid: str, environ: dict[str, Any], auth: Any = None) -> None:
        seen["connects"] += 1

    @sio.on("telemetry")
    async def telemetry(sid: str, data: Any = None) -> None:
        if data is None:
            seen["null"] += 1
            await sio.emit("manual", {}, to=sid)
            return
        seen["telemetry"] += 1
        await sio.emit("steer", {"steering_angle": "0.1", "throttle": "0.2"}, to=sid)

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        seen["port"] = s.getsockname()[1]
    loop = asyncio.new_event_loop()
    ready = threading.Event()
    stop: dict[str, Any] = {}

    async def serve() -> None:
        app = web.Application()
        sio.attach(app)
        runner = web.AppRunner(app, handle_signals=False)
        await runner.setup()
        await web.TCPSite(runner, "127.0.0.1", seen["port"]).start()
        stop["event"] = asyncio.Event()
        ready.set()
        await stop["event"].wait()
        await sio.shutdown()
        await runner.cleanup()

    def run() -> None:
        loop.run_until_complete(serve())
        pending = asyncio.all_tasks(loop)  # engineio's ping tasks of closed sockets
        for task in pending:
            task.cancel()
        loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    assert ready.wait(10)
    try:
        yield seen
    finally:
        loop.call_soon_threadsafe(stop["event"].set)
        thread.join(10)
        loop.close()


def test_stock_python_socketio_5_stays_silent_against_the_fake_client() -> None:
    import socketio

    with drive_py_server(socketio.AsyncServer(async_mode="aiohttp")) as seen, \
            FakeUdacityClient(seen["port"]) as sim:
        assert sim.wait_for(lambda c: c.telemetry_sent >= 2, 10)
        # what the real simulator sees with python-socketio 5: HTTP 200 and OPEN, then silence
        sim.wait_for(lambda c: c.steers, 1.5)
    assert sim.opens == 1
    assert sim.frames_received[0].startswith("0{")
    assert sim.telemetry_sent == 2  # the two after open; no steer ever came to ask for more
    assert sim.steers == [] and sim.manuals == 0
    assert seen["connects"] == 0 and seen["telemetry"] == 0  # events dropped: never joined '/'


def test_legacy_server_joins_slash_and_answers_every_telemetry() -> None:
    server = engineio3.legacy_server(async_mode="aiohttp", ping_interval=1, ping_timeout=1)
    with drive_py_server(server) as seen, FakeUdacityClient(seen["port"]) as sim:
        assert sim.wait_for(lambda c: len(c.steers) >= 20, 10)
        # heartbeat: the server pings every second and the fake answers; the link stays up
        assert sim.wait_for(lambda c: c.pings_answered >= 2, 10)
        assert sim.wait_for(lambda c: len(c.steers) >= 40, 10)
    assert sim.opens == 1 and sim.connect_attempts == 1
    assert seen["connects"] == 1
    assert sim.steers[0] == (0.1, 0.2)
    # the shim's own CONNECT for '/' follows OPEN, as python-socketio 4 sent it
    assert sim.frames_received[0].startswith("0{") and sim.frames_received[1].startswith("40{")


def test_legacy_server_ignores_a_second_connect_for_slash() -> None:
    """A modern client that sends '40' itself stays joined once (no second sid, no second connect)."""
    server = engineio3.legacy_server(async_mode="aiohttp")
    with drive_py_server(server) as seen:
        ws = WebSocketClient("127.0.0.1", seen["port"], "/socket.io/?EIO=4&transport=websocket")
        try:
            assert ws.receive(5).startswith("0{")
            assert ws.receive(5).startswith("40{")
            ws.send("40")
            ws.send('42["telemetry",{"speed":"1"}]')
            assert ws.receive(5) == '42["steer",{"steering_angle":"0.1","throttle":"0.2"}]'
        finally:
            ws.close()
    assert seen["connects"] == 1 and seen["telemetry"] == 1


def test_unreadable_packets_cost_one_log_line_and_nothing_else(caplog: pytest.LogCaptureFixture) -> None:
    """Junk and JSON nested beyond the parser's recursion limit: no traceback, the link goes on."""
    server = engineio3.legacy_server(async_mode="aiohttp")
    with caplog.at_level("WARNING"), drive_py_server(server) as seen:
        ws = WebSocketClient("127.0.0.1", seen["port"], "/socket.io/?EIO=4&transport=websocket")
        try:
            assert ws.receive(5).startswith("0{")
            assert ws.receive(5).startswith("40{")
            depth = 100000
            ws.send('42["telemetry",' + "[" * depth + "]" * depth + "]")
            ws.send('42["telemetry",{"speed":')
            ws.send('42["telemetry",{"speed":"1"}]')
            assert ws.receive(5) == '42["steer",{"steering_angle":"0.1","throttle":"0.2"}]'
        finally:
            ws.close()
    assert seen["telemetry"] == 1
    assert not [r for r in caplog.records if r.exc_info]
    junk = [r for r in caplog.records if "unreadable packet" in r.getMessage()]
    assert len(junk) == 1 and "RecursionError" in junk[0].getMessage()


def test_check_support_names_what_to_install_when_internals_change(monkeypatch: pytest.MonkeyPatch) -> None:
    import socketio

    async def changed(self: Any, eio_sid: str, namespace: str, data: Any, extra: Any) -> None:
        return None

    monkeypatch.setattr(socketio.AsyncServer, "_handle_connect", changed)
    with pytest.raises(BridgeError, match=r"_handle_connect .*pip install 'vehicle-rc\[web\]'"):
        engineio3.check_support()


def test_untested_versions_warn_once(monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.setattr(engineio3, "_warned_untested", False)
    monkeypatch.setitem(engineio3.SUPPORTED, "python-socketio", ((9, 0), (9, 1)))
    with caplog.at_level("WARNING", logger="parts.bridges.engineio3"):
        engineio3.check_support()
        engineio3.check_support()
    warnings = [r for r in caplog.records if "not tested" in r.getMessage()]
    assert len(warnings) == 1
    assert "python-socketio 5." in warnings[0].getMessage()
