"""Web controller benchmark, in a real headless chromium against a real Vehicle.

1. Latency from a browser key press (CDP Input.dispatchKeyEvent of ArrowUp) to the command in the
   vehicle memory (``user/throttle`` written by the loop), and to the server (the socket message
   applied to the control slot), median and p99 over N presses. The loop-side figure includes the
   wait for the next loop, so it is also given as a ratio to the loop period.
2. Camera frame delivery rate to one and to three viewers (pages), as a ratio to the frames the
   loop produced (one per loop). Median of several runs.

    .venv/bin/python bench/web.py                      # 20 Hz loop, 160x120 frames
    .venv/bin/python bench/web.py --hz 50 --size 640x480
    .venv/bin/python bench/web.py --screenshots docs/img   # also the docs screenshots (simulator)
"""

from __future__ import annotations

import argparse
import asyncio
import random
import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from parts.web.devtools import Chromium, find_chromium  # noqa: E402
from vehicle import Vehicle  # noqa: E402
from vehicle.app import assembly  # noqa: E402
from vehicle.config import Config  # noqa: E402


class FakeCamera:
    """A frame per loop: noise-free gradient with a moving bar (JPEG size like a real scene)."""

    def __init__(self, w: int, h: int) -> None:
        rng = np.random.default_rng(0)
        self.base = (rng.integers(0, 60, (h, w, 3)) + np.linspace(0, 150, w)[None, :, None]).astype(np.uint8)
        self.i = 0

    def run(self) -> np.ndarray:
        self.i += 1
        img = self.base.copy()
        img[:, self.i % img.shape[1]] = 255
        return img


class Probe:
    """Loop part after the controller: time at which user/throttle first became non-zero."""

    def __init__(self) -> None:
        self.t_mem: float | None = None
        self.loops = 0

    def reset(self) -> None:
        self.t_mem = None

    def run(self, throttle: float | None) -> None:
        self.loops += 1
        if throttle and self.t_mem is None:
            self.t_mem = time.perf_counter()


CARS: list[str] = []  # temporary car folders, removed at exit


def build_car(args: argparse.Namespace, sim: bool = False) -> tuple[Vehicle, object, Probe]:
    car = tempfile.mkdtemp(prefix="bench-web-")
    CARS.append(car)
    cfg = Config.defaults(CAR_PATH=car, WEB_CONTROL_PORT=0, WEB_MAX_THROTTLE=1.0 if not sim else 0.6)
    (Path(car) / "models").mkdir()
    for name in ("pilot.pt", "pilot-night.pt"):
        (Path(car) / "models" / name).write_bytes(b"")
    V = Vehicle()
    if sim:
        assembly.add_simulator(V, cfg)
    else:
        w, h = args.size
        V.add(FakeCamera(w, h), outputs=["cam/image_array"])
    web = assembly.add_controller(V, cfg)
    probe = Probe()
    V.add(probe, inputs=["user/throttle"])
    assembly.add_drive_mode(V, cfg)
    if sim:
        assembly.add_tub_writer(V, cfg)  # the record count on the page
    return V, web, probe


def start(V: Vehicle, hz: float) -> threading.Thread:
    thread = threading.Thread(target=V.start, kwargs={"rate_hz": hz}, daemon=True)
    thread.start()
    return thread


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(q / 100 * (len(s) - 1)))]


async def wait(cond, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise TimeoutError("benchmark condition not met")
        await asyncio.sleep(0.0005)


async def latency(args: argparse.Namespace) -> dict[str, float]:
    V, web, probe = build_car(args)
    t_srv: list[float | None] = [None]
    original = web.state.drive

    def drive(angle: float, throttle: float) -> None:  # timestamp the server side
        if throttle and t_srv[0] is None:
            t_srv[0] = time.perf_counter()
        original(angle, throttle)

    web.state.drive = drive
    thread = start(V, args.hz)
    try:
        await wait(lambda: web.port != 0)
        async with Chromium.launch() as browser:
            page = await browser.new_page(web.url)
            await page.wait_for("window.webStats && webStats.role === 'driver'")
            to_srv, to_mem = [], []
            for _ in range(args.presses):
                probe.reset()
                t_srv[0] = None
                t0 = time.perf_counter()
                await page.key("ArrowUp")
                await wait(lambda: probe.t_mem is not None)
                to_srv.append(t_srv[0] - t0)
                to_mem.append(probe.t_mem - t0)
                await page.key("ArrowUp", down=False)
                await wait(lambda: V.mem["user/throttle"] == 0.0)
                await asyncio.sleep(random.uniform(0.02, 0.02 + 1.0 / args.hz))  # random loop phase
    finally:
        V.stop()
        thread.join(10)
    period_ms = 1000.0 / args.hz
    ms = 1000.0
    return {"server_p50": statistics.median(to_srv) * ms, "server_p99": pct(to_srv, 99) * ms,
            "memory_p50": statistics.median(to_mem) * ms, "memory_p99": pct(to_mem, 99) * ms,
            "period_ms": period_ms}


async def frame_rates(args: argparse.Namespace, viewers: int) -> tuple[float, float]:
    """Median over runs of (delivered fps per viewer, produced fps)."""
    V, web, probe = build_car(args)
    thread = start(V, args.hz)
    delivered, produced = [], []
    try:
        await wait(lambda: web.port != 0)
        async with Chromium.launch() as browser:
            pages = [await browser.new_page(web.url) for _ in range(viewers)]
            for p in pages:
                await p.wait_for("window.webStats && webStats.frames > 5")
            for _ in range(args.runs):
                f0 = [await p.evaluate("webStats.frames") for p in pages]
                l0, t0 = probe.loops, time.perf_counter()
                await asyncio.sleep(args.seconds)
                f1 = [await p.evaluate("webStats.frames") for p in pages]
                dt = time.perf_counter() - t0
                produced.append((probe.loops - l0) / dt)
                delivered.append(statistics.mean((b - a) / dt for a, b in zip(f0, f1, strict=True)))
    finally:
        V.stop()
        thread.join(10)
    return statistics.median(delivered), statistics.median(produced)


async def screenshots(args: argparse.Namespace, folder: Path) -> None:
    V, web, probe = build_car(args, sim=True)
    thread = start(V, 20)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        await wait(lambda: web.port != 0)
        async with Chromium.launch(window=(1280, 860)) as browser:
            page = await browser.new_page(web.url)
            await page.viewport(1280, 860)
            await page.wait_for("window.webStats && webStats.frames > 10")
            await page.evaluate("document.querySelector('[data-mode=user]').click()")
            await page.key("r")
            await page.key("ArrowUp")
            await asyncio.sleep(2.0)
            await page.key("ArrowLeft")
            await asyncio.sleep(0.25)
            (folder / "web-desktop.png").write_bytes(await page.screenshot())
            await page.key("ArrowLeft", down=False)
            await page.key("ArrowUp", down=False)
            await page.key("r")
            phone = await browser.new_page(web.url)
            await phone.viewport(390, 844, scale=1.0, mobile=True)
            await phone.evaluate("location.reload()")
            await asyncio.sleep(0.5)
            await phone.wait_for("window.webStats && webStats.frames > 30")
            (folder / "web-phone.png").write_bytes(await phone.screenshot())
    finally:
        V.stop()
        thread.join(10)
    print(f"screenshots written to {folder}/web-desktop.png, web-phone.png")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--presses", type=int, default=60, help="key presses for the latency figures")
    parser.add_argument("--hz", type=float, default=20.0, help="drive loop rate")
    parser.add_argument("--size", type=lambda s: tuple(int(v) for v in s.split("x")), default=(160, 120),
                        help="camera frame WxH (default 160x120)")
    parser.add_argument("--seconds", type=float, default=3.0, help="length of one frame-rate run")
    parser.add_argument("--runs", type=int, default=3, help="frame-rate runs (median)")
    parser.add_argument("--screenshots", type=Path, help="write the docs screenshots to this folder")
    args = parser.parse_args(argv)
    try:
        return run(args)
    finally:
        for car in CARS:
            shutil.rmtree(car, ignore_errors=True)


def run(args: argparse.Namespace) -> int:
    if find_chromium() is None:
        print("chromium not found: apt-get install chromium", file=sys.stderr)
        return 2
    if args.screenshots:
        asyncio.run(screenshots(args, args.screenshots))
        return 0
    w, h = args.size
    print(f"loop {args.hz:g} Hz, frames {w}x{h}, {args.presses} key presses")
    lat = asyncio.run(latency(args))
    print(f"key press -> server   : median {lat['server_p50']:6.1f} ms  p99 {lat['server_p99']:6.1f} ms")
    print(f"key press -> memory   : median {lat['memory_p50']:6.1f} ms  p99 {lat['memory_p99']:6.1f} ms"
          f"  (= {lat['memory_p50'] / lat['period_ms']:.2f} / {lat['memory_p99'] / lat['period_ms']:.2f}"
          f" loop periods of {lat['period_ms']:.0f} ms)")
    for n in (1, 3):
        fps, produced = asyncio.run(frame_rates(args, n))
        print(f"frames, {n} viewer{'s' if n > 1 else ' '}   : {fps:5.1f} fps per viewer of {produced:5.1f} "
              f"produced (ratio {fps / produced:.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
