"""Benchmark of the simulator bridges.

Donkey protocol: simulation steps per second through ``vehicle sim serve`` on loopback (a separate
process, as a real simulator is), in synchronous step mode, against the same simulator stepped in
this process (SimCar.run: physics, telemetry, render) measured in the same run:
  * with our client (parts.bridges.donkey_client.DonkeySim.run: control out, telemetry in, JPEG
    decoded, as `vehicle sim eval --sim donkey` uses it);
  * with a raw client that sends controls and reads telemetry lines without decoding (the server's
    own ceiling: render + JPEG + base64 + JSON + TCP).

Udacity: round-trip time per telemetry (telemetry sent -> steer received) seen by the fake Udacity
simulator running in its own process, against a baseline measured in the same run: drive.py's
server (python-socketio with our compatibility layer, decoding the image and answering in the
handler, no drive loop):
  * the UdacitySim part with a loop calling run_threaded every millisecond (the bridge's own cost);
  * the UdacitySim part in a Vehicle at DRIVE_LOOP_HZ (what a car sees: the answer waits for the
    loop to have computed the command from that frame), without and with SendCommands last in the
    loop (the answer leaves at the end of the loop that saw the frame instead of the next one).

Usage: .venv/bin/python bench/bridges.py [--steps 600] [--seconds 6] [--repeats 3]
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import json
import os
import socket
import statistics
import subprocess
import sys
import threading
import time
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))  # the fake Udacity client lives in tests/fixtures

import cv2  # noqa: E402

cv2.setNumThreads(1)

from parts.bridges import donkey_protocol as proto  # noqa: E402
from parts.bridges.donkey_client import DonkeySim  # noqa: E402
from parts.sim.simulator import SimCar  # noqa: E402
from vehicle.config import Config  # noqa: E402

SEED = 3
ENV = {**os.environ, "PYTHONPATH": ROOT + os.pathsep + os.environ.get("PYTHONPATH", "")}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -- Donkey protocol ---------------------------------------------------------------------------------
def in_process(steps: int) -> float:
    """Steps/s of SimCar.run in this process (the baseline)."""
    sim = SimCar.from_config(Config.defaults(), seeds=[SEED], reset_off_track=False, realtime=False)
    sim.run(0.0, 0.2)
    t = time.perf_counter()
    for _ in range(steps):
        sim.run(0.0, 0.2)
    return steps / (time.perf_counter() - t)


def our_client(port: int, steps: int) -> float:
    sim = DonkeySim(port=port, scene=f"track_{SEED}", synchronous=True, connect_timeout_s=60)
    try:
        sim.run(0.0, 0.2, False)
        t = time.perf_counter()
        for _ in range(steps):
            sim.run(0.0, 0.2, False)
        return steps / (time.perf_counter() - t)
    finally:
        sim.shutdown()


def raw_client(port: int, steps: int) -> float:
    """Controls out, telemetry lines in, nothing decoded."""
    with socket.create_connection(("127.0.0.1", port)) as s:
        buf = b""

        def wait_for(kind: bytes) -> None:
            nonlocal buf
            while True:
                line, sep, rest = buf.partition(b"\n")
                if sep:
                    buf = rest
                    if kind in line[:40]:
                        return
                    continue
                buf += s.recv(1 << 18)

        def send(msg: bytes) -> None:
            s.sendall(msg)
            time.sleep(0.1)

        wait_for(b"scene_selection_ready")
        send(proto.client_message("load_scene", scene_name=f"track_{SEED}"))
        wait_for(b"car_loaded")
        send(proto.client_message("step_mode", step_mode="synchronous", time_step=0.05))
        time.sleep(0.3)
        s.setblocking(False)
        try:
            while s.recv(1 << 20):
                pass
        except BlockingIOError:
            pass
        s.setblocking(True)
        buf = b""
        control = proto.client_message("control", steering=0.0, throttle=0.2, brake=0.0)
        t = time.perf_counter()
        for _ in range(steps):
            s.sendall(control)
            wait_for(b'"telemetry"')
        return steps / (time.perf_counter() - t)


def donkey(steps: int, repeats: int) -> dict[str, Any]:
    port = free_port()
    server = subprocess.Popen([sys.executable, "-m", "vehicle", "sim", "serve", "--port", str(port), "--tracks",
                               str(SEED), "--car", ROOT], env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        runs: dict[str, list[float]] = {"in_process": [], "our_client": [], "raw_client": []}
        for _ in range(repeats):  # interleaved, so load changes hit all three alike
            runs["in_process"].append(in_process(steps))
            runs["our_client"].append(our_client(port, steps))
            runs["raw_client"].append(raw_client(port, steps))
    finally:
        server.terminate()
        server.wait(10)
    med = {k: statistics.median(v) for k, v in runs.items()}
    return {"steps": steps, "repeats": repeats, "steps_per_s": {k: round(v, 1) for k, v in med.items()},
            "ratio_vs_in_process": {k: round(med[k] / med["in_process"], 3) for k in ("our_client", "raw_client")},
            "realtime_x": {k: round(v / 20.0, 1) for k, v in med.items()}}


# -- Udacity ------------------------------------------------------------------------------------------
FAKE = """
import json, sys, time
from fixtures.fake_udacity_client import FakeUdacityClient
port, seconds = int(sys.argv[1]), float(sys.argv[2])
with FakeUdacityClient(port) as sim:
    sim.wait_for(lambda c: len(c.steers) > 0, 60)
    time.sleep(seconds)
print(json.dumps({"rtt": sim.round_trips[5:], "steers": len(sim.steers), "stalls": sim.stalls}))
"""


def fake_simulator(port: int, seconds: float) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", FAKE, str(port), str(seconds)], env=ENV, text=True,
                            stdout=subprocess.PIPE)


def result_of(proc: subprocess.Popen[str]) -> list[float]:
    out, _ = proc.communicate(timeout=180)
    data = json.loads(out)
    if data["stalls"]:
        raise RuntimeError(f"the fake simulator stalled {data['stalls']} times")
    return data["rtt"]


def drive_py_baseline(seconds: float) -> list[float]:
    """drive.py's server: answer in the handler (image decoded with PIL as drive.py does)."""
    from io import BytesIO

    import numpy as np
    from aiohttp import web
    from PIL import Image

    from parts.bridges.engineio3 import legacy_server

    port = free_port()
    sio = legacy_server(async_mode="aiohttp")

    @sio.on("telemetry")
    async def telemetry(sid: str, data: Any = None) -> None:
        if data is None:
            await sio.emit("manual", {}, to=sid)
            return
        np.asarray(Image.open(BytesIO(base64.b64decode(data["image"]))))
        await sio.emit("steer", {"steering_angle": "0.0", "throttle": "0.2"}, to=sid)

    loop = asyncio.new_event_loop()
    stop = threading.Event()

    async def serve() -> None:
        app = web.Application()
        sio.attach(app)
        runner = web.AppRunner(app, handle_signals=False, shutdown_timeout=0.25)
        await runner.setup()
        await web.TCPSite(runner, "127.0.0.1", port).start()
        while not stop.is_set():
            await asyncio.sleep(0.05)
        if sio.eio.sockets:
            await sio.eio.disconnect()
        await sio.shutdown()
        await runner.cleanup()

    def run() -> None:
        loop.run_until_complete(serve())
        pending = asyncio.all_tasks(loop)  # engineio's tasks of closed sockets
        for task in pending:
            task.cancel()
        loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
        loop.close()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    proc = fake_simulator(port, seconds)
    rtt = result_of(proc)
    stop.set()
    thread.join(10)
    return rtt


def bridge_tight(seconds: float) -> list[float]:
    from parts.bridges.udacity_sim import UdacitySim

    port = free_port()
    part = UdacitySim(port=port).start()
    proc = fake_simulator(port, seconds)
    try:
        while proc.poll() is None:
            part.run_threaded(0.0, 0.2)
            time.sleep(0.001)
        return result_of(proc)
    finally:
        part.shutdown()


def bridge_in_vehicle(seconds: float, hz: int, commands_last: bool) -> list[float]:
    from parts.bridges.udacity_sim import UdacitySim
    from vehicle import Vehicle

    port = free_port()
    part = UdacitySim(port=port)
    V = Vehicle()
    V.add(part, threaded=True)
    V.add(lambda: (0.0, 0.2), outputs=["angle", "throttle"])
    proc = fake_simulator(port, seconds)

    class StopWhenDone:
        def run(self) -> None:
            if proc.poll() is not None:
                V.stop()

    V.add(StopWhenDone())
    if commands_last:
        from parts.bridges.commands import SendCommands

        V.add(SendCommands(part))
    V.start(rate_hz=hz, log_summary=False)
    return result_of(proc)


def udacity(seconds: float, repeats: int, hz: int) -> dict[str, Any]:
    runs: dict[str, list[float]] = {"drive_py_handler": [], "bridge_tight_loop": [], f"vehicle_{hz}hz": [],
                                    f"vehicle_{hz}hz_send_commands": []}
    for _ in range(repeats):
        runs["drive_py_handler"] += drive_py_baseline(seconds)
        runs["bridge_tight_loop"] += bridge_tight(seconds)
        runs[f"vehicle_{hz}hz"] += bridge_in_vehicle(seconds, hz, commands_last=False)
        runs[f"vehicle_{hz}hz_send_commands"] += bridge_in_vehicle(seconds, hz, commands_last=True)
    ms = {k: sorted(x * 1e3 for x in v) for k, v in runs.items()}
    base = statistics.median(ms["drive_py_handler"])
    return {k: {"samples": len(v), "median_ms": round(statistics.median(v), 2),
                "p95_ms": round(v[int(0.95 * (len(v) - 1))], 2),
                "ratio_vs_drive_py": round(statistics.median(v) / base, 2)} for k, v in ms.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=600, help="Donkey steps per run")
    parser.add_argument("--seconds", type=float, default=6.0, help="Udacity seconds per run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--hz", type=int, default=20, help="loop rate of the Vehicle run")
    parser.add_argument("--only", choices=["donkey", "udacity"])
    args = parser.parse_args()
    report: dict[str, Any] = {"load_average": os.getloadavg()}
    if args.only != "udacity":
        report["donkey"] = donkey(args.steps, args.repeats)
        print(json.dumps({"donkey": report["donkey"]}, indent=1), flush=True)
    if args.only != "donkey":
        report["udacity"] = udacity(args.seconds, args.repeats, args.hz)
        print(json.dumps({"udacity": report["udacity"]}, indent=1), flush=True)
    report["load_average_after"] = os.getloadavg()
    print(json.dumps({k: v for k, v in report.items() if k.startswith("load")}))


if __name__ == "__main__":
    main()
