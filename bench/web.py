"""Web controller benchmark, in a real headless chromium against a real Vehicle.

1. Latency from a browser key press (Playwright's keyboard.down("ArrowUp"): a DevTools
   Input.dispatchKeyEvent) to the command in the vehicle memory (``user/throttle`` written by the
   loop), and to the server (the socket message applied to the control slot), median and p99 over
   N presses. The loop-side figure includes the wait for the next loop, so it is also given as a
   ratio to the loop period.
2. Camera frame delivery rate to one and to three viewers (visible pages that Playwright does not
   instrument, see open_viewers; frames counted as the pages acknowledge them, after drawing), as
   a ratio to the frames the loop produced (one per loop). Median of several runs.

    .venv/bin/python bench/web.py                      # 20 Hz loop, 160x120 frames
    .venv/bin/python bench/web.py --hz 50 --size 640x480
    .venv/bin/python bench/web.py --screenshots docs/img   # also the docs screenshots (simulator)

Playwright (the dev extra) drives the system chromium (tests/fixtures/browser.py); no browser download.
"""

from __future__ import annotations

import argparse
import collections
import random
import shutil
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # tests/fixtures/browser.py: how the project starts chromium

from fixtures.browser import find_chromium, launch_chromium, open_page  # noqa: E402

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


def write_pilot(path: Path) -> Path:
    """An untrained linear model file for the car's frames (the pictures show a car with a pilot)."""
    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess

    shape = (120, 160, 3)
    pre = Preprocess(crop=(40, 0, 0, 0), image_shape=shape)
    return save_model(path, create_model("linear", pre.output_shape(shape)), {"preprocess": pre.to_dict()})


def build_car(args: argparse.Namespace, sim: bool = False, pilot: bool = False) -> tuple[Vehicle, object, Probe]:
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
    if pilot:
        assembly.add_pilot(V, cfg, write_pilot(Path(car) / "models" / "pilot.pt"))
    probe = Probe()
    V.add(probe, inputs=["user/throttle"])
    assembly.add_drive_mode(V, cfg)
    assembly.add_speed_limit(V, cfg)
    assembly.add_obstacle_stop(V, cfg)
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


def wait(cond, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise TimeoutError("benchmark condition not met")
        time.sleep(0.0005)


def latency(args: argparse.Namespace, browser) -> dict[str, float]:
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
        wait(lambda: web.port != 0)
        page = open_page(browser, web.url)
        page.wait_for_function("window.webStats && webStats.role === 'driver'")
        to_srv, to_mem = [], []
        for _ in range(args.presses):
            probe.reset()
            t_srv[0] = None
            # Playwright's driver passes each camera frame the page receives on to this process,
            # which reads them at its next call: read them now, not while the key press travels
            page.evaluate("0")
            t0 = time.perf_counter()
            page.keyboard.down("ArrowUp")
            wait(lambda: probe.t_mem is not None)
            to_srv.append(t_srv[0] - t0)
            to_mem.append(probe.t_mem - t0)
            page.keyboard.up("ArrowUp")
            wait(lambda: V.mem["user/throttle"] == 0.0)
            time.sleep(random.uniform(0.02, 0.02 + 1.0 / args.hz))  # random loop phase
        page.context.close()
    finally:
        V.stop()
        thread.join(10)
    period_ms = 1000.0 / args.hz
    ms = 1000.0
    return {"server_p50": statistics.median(to_srv) * ms, "server_p99": pct(to_srv, 99) * ms,
            "memory_p50": statistics.median(to_mem) * ms, "memory_p99": pct(to_mem, 99) * ms,
            "period_ms": period_ms}


def count_drawn_frames(web) -> collections.Counter[str]:
    """Frames each browser acknowledged (by Socket.IO sid), counted in the server.

    The page acknowledges a frame once it has drawn it (static/app.js), so this is the number of
    frames it showed: webStats.frames, read without attaching to the page.
    """
    counts: collections.Counter[str] = collections.Counter()
    sio = web.server._sio  # set once the server listens (web.port != 0)
    call = sio.call

    async def counting_call(event, data=None, to=None, **kwargs):
        result = await call(event, data, to=to, **kwargs)
        if event == "frame":
            counts[to] += 1
        return result

    sio.call = counting_call
    return counts


def open_viewers(browser, url: str, n: int) -> Callable[[], None]:
    """``n`` pages showing ``url`` that Playwright does not instrument; returns a function closing them.

    Playwright's own pages pass every websocket frame (the JPEGs, base64) from chromium to its
    driver and on to this process: at 640x480 and 50 Hz that costs more CPU than drawing them.
    Pages opened over DevTools in a browser context Playwright did not create are left alone (it
    detaches from them). Each is a window of its own, visible, as on separate phones: tabs of one
    window would be hidden but the last, and a hidden page does not paint.
    """
    cdp = browser.new_browser_cdp_session()
    context = cdp.send("Target.createBrowserContext")["browserContextId"]
    for _ in range(n):
        cdp.send("Target.createTarget", {"url": url, "browserContextId": context, "newWindow": True,
                                         "width": 1280, "height": 900})

    def close() -> None:
        cdp.send("Target.disposeBrowserContext", {"browserContextId": context})
        cdp.detach()

    return close


def frame_rates(args: argparse.Namespace, browser, viewers: int) -> tuple[float, float]:
    """Median over runs of (delivered fps per viewer, produced fps)."""
    V, web, probe = build_car(args)
    thread = start(V, args.hz)
    delivered, produced = [], []
    try:
        wait(lambda: web.port != 0)
        drawn = count_drawn_frames(web)
        close = open_viewers(browser, web.url, viewers)
        wait(lambda: len(drawn) == viewers and min(drawn.values()) > 5, timeout=20)
        for _ in range(args.runs):
            f0 = dict(drawn)
            l0, t0 = probe.loops, time.perf_counter()
            time.sleep(args.seconds)
            f1 = dict(drawn)
            dt = time.perf_counter() - t0
            produced.append((probe.loops - l0) / dt)
            delivered.append(statistics.mean((f1[sid] - f0[sid]) / dt for sid in f0))
        close()
    finally:
        V.stop()
        thread.join(10)
    return statistics.median(delivered), statistics.median(produced)


def screenshots(args: argparse.Namespace, browser, folder: Path) -> None:
    """The docs' pictures of the page: desktop 1280x800 (driving, recording), phone upright 390x844
    (watching) and phone sideways 844x390 (driving)."""
    V, web, probe = build_car(args, sim=True, pilot=True)
    thread = start(V, 20)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        wait(lambda: web.port != 0)
        page = open_page(browser, web.url, viewport={"width": 1280, "height": 800})
        page.wait_for_function("window.webStats && webStats.frames > 10")
        page.evaluate("document.querySelector('[data-mode=user]').click()")  # no focus ring in the picture
        page.keyboard.press("r")
        page.keyboard.down("ArrowUp")
        time.sleep(2.0)
        page.keyboard.down("ArrowLeft")
        time.sleep(0.25)
        page.screenshot(path=folder / "web-desktop.png")
        page.keyboard.up("ArrowLeft")
        page.keyboard.up("ArrowUp")
        page.keyboard.press("r")
        phone = open_page(browser, web.url, device="phone")
        phone.wait_for_function("window.webStats && webStats.frames > 30 && webStats.role === 'viewer'")
        phone.screenshot(path=folder / "web-phone.png")
        for context in browser.contexts:  # the driver leaves: the sideways phone drives
            context.close()
        sideways = open_page(browser, web.url, device="phone", viewport={"width": 844, "height": 390})
        sideways.wait_for_function("window.webStats && webStats.frames > 30 && webStats.role === 'driver'")
        time.sleep(2.0)  # the loop rate shown settles after the other pages closed
        sideways.screenshot(path=folder / "web-phone-landscape.png")
        for context in browser.contexts:  # the pages go before the car stops, as in the tests
            context.close()
    finally:
        V.stop()
        thread.join(10)
    print(f"screenshots written to {folder}/web-desktop.png, web-phone.png, web-phone-landscape.png")


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
    executable = find_chromium()
    if executable is None:
        print("chromium not found: apt-get install chromium", file=sys.stderr)
        return 2
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        print("playwright not installed: pip install -e '.[dev]'", file=sys.stderr)
        return 2

    with sync_playwright() as playwright:
        browser = launch_chromium(playwright, executable)
        if args.screenshots:
            screenshots(args, browser, args.screenshots)
            return 0
        w, h = args.size
        print(f"loop {args.hz:g} Hz, frames {w}x{h}, {args.presses} key presses, chromium {browser.version}")
        lat = latency(args, browser)
        print(f"key press -> server   : median {lat['server_p50']:6.1f} ms  p99 {lat['server_p99']:6.1f} ms")
        print(f"key press -> memory   : median {lat['memory_p50']:6.1f} ms  p99 {lat['memory_p99']:6.1f} ms"
              f"  (= {lat['memory_p50'] / lat['period_ms']:.2f} / {lat['memory_p99'] / lat['period_ms']:.2f}"
              f" loop periods of {lat['period_ms']:.0f} ms)")
        for n in (1, 3):
            fps, produced = frame_rates(args, browser, n)
            print(f"frames, {n} viewer{'s' if n > 1 else ' '}   : {fps:5.1f} fps per viewer of {produced:5.1f} "
                  f"produced (ratio {fps / produced:.2f})")
        browser.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
