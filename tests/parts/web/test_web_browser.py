"""The page itself in Debian's headless chromium (Chrome DevTools Protocol), against a real Vehicle."""

from __future__ import annotations

import asyncio
import threading
import time

import numpy as np
import pytest

from parts.web.devtools import Chromium, find_chromium
from vehicle import Vehicle
from vehicle.app.assembly.controller import add_controller
from vehicle.app.assembly.drive import add_drive_mode
from vehicle.config import Config

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(find_chromium() is None,
                       reason="chromium is not installed (Debian: apt-get install chromium; "
                              "`make browser` does it)"),
]


class FakeCamera:
    def __init__(self) -> None:
        self.i = 0

    def run(self) -> np.ndarray:
        self.i += 1
        img = np.full((120, 160, 3), 30, np.uint8)
        img[:, self.i % 160] = 255
        return img


def fake_car(tmp_path, **overrides) -> Car:
    """Fake camera -> web controller -> drive mode."""
    cfg = Config.defaults(CAR_PATH=str(tmp_path), WEB_CONTROL_PORT=0, WEB_MAX_THROTTLE=1.0, **overrides)
    V = Vehicle()
    V.add(FakeCamera(), outputs=["cam/image_array"])
    web = add_controller(V, cfg)
    add_drive_mode(V, cfg)
    return Car(V, web)


class Car:
    """A small real Vehicle (fake camera, web controller, drive mode) running in a thread."""

    def __init__(self, V: Vehicle, web) -> None:
        self.V, self.web = V, web
        self.errors: list[BaseException] = []
        self.thread = threading.Thread(target=self._run)

    def _run(self) -> None:
        try:
            self.V.start(rate_hz=40)
        except BaseException as exc:
            self.errors.append(exc)

    def __enter__(self) -> Car:
        self.thread.start()
        end = time.monotonic() + 10
        while self.web.port == 0 and time.monotonic() < end:
            time.sleep(0.01)
        return self

    def __exit__(self, *exc) -> None:
        self.V.stop()
        self.thread.join(10)
        assert not self.errors, self.errors

    async def until(self, cond, timeout: float = 5.0, what: str = "") -> None:
        end = time.monotonic() + timeout
        while not cond(self.V.mem):
            if time.monotonic() > end:
                raise AssertionError(f"vehicle memory condition not met: {what}; "
                                     f"user/angle={self.V.mem['user/angle']} "
                                     f"user/throttle={self.V.mem['user/throttle']}")
            await asyncio.sleep(0.01)


CONNECTED = "window.webStats && webStats.connected && webStats.role === '{}'"


def test_keys_drive_the_car_frames_arrive_and_closing_the_page_stops(tmp_path, arun):
    async def main(car: Car):
        async with Chromium.launch() as browser:
            page = await browser.new_page(car.web.url)
            await page.wait_for(CONNECTED.format("driver"))
            await page.wait_for("webStats.frames >= 5")
            await page.key("ArrowUp")
            await page.key("ArrowRight")
            await car.until(lambda m: m["user/throttle"] == 1.0 and m["user/angle"] > 0.5,
                            what="up + right held")
            assert car.V.mem["throttle"] == 1.0  # through DriveMode to the final command
            await page.key("ArrowRight", down=False)
            await car.until(lambda m: m["user/angle"] == 0.0, what="steering back to centre")
            # the gauges show what the car does
            await page.wait_for("document.getElementById('throttle').textContent === '1.00'")
            # close the tab with the throttle key still held: the car must stop
            await page.close()
            await car.until(lambda m: m["user/throttle"] == 0.0 and m["throttle"] == 0.0,
                            what="stop after the page closed")

    with fake_car(tmp_path) as car:
        arun(main(car))


def test_a_frozen_page_trips_the_deadman(tmp_path, arun):
    async def main(car: Car):
        async with Chromium.launch() as browser:
            page = await browser.new_page(car.web.url)
            await page.wait_for(CONNECTED.format("driver"))
            await page.key("ArrowUp")
            await car.until(lambda m: m["user/throttle"] == 1.0, what="driving")
            # block the page's JavaScript for 2 s: still connected, but no control messages
            freeze = asyncio.create_task(
                page.evaluate("(() => { const t = Date.now(); while (Date.now() - t < 2000) {} })()"))
            await car.until(lambda m: m["user/throttle"] == 0.0 and m["throttle"] == 0.0,
                            timeout=1.9, what="dead-man stop while the page is frozen")
            assert car.web.state.deadman_trips == 1
            await freeze
            await page.key("ArrowUp", down=False)
            await page.wait_for("document.getElementById('notice').textContent.startsWith('Dead-man')")

    with fake_car(tmp_path) as car:
        arun(main(car))


def test_buttons_modes_record_estop_and_watcher(tmp_path, arun):
    async def main(car: Car):
        async with Chromium.launch() as browser:
            driver = await browser.new_page(car.web.url)
            await driver.wait_for(CONNECTED.format("driver"))
            watcher = await browser.new_page(car.web.url)
            await watcher.wait_for(CONNECTED.format("viewer"))
            await driver.evaluate("document.querySelector('[data-mode=local_angle]').click()")
            await car.until(lambda m: m["user/mode"] == "local_angle", what="mode button")
            await driver.key("r")
            await car.until(lambda m: m["recording"] is True, what="R toggles recording")
            # the watcher's keys do not drive
            await watcher.key("ArrowUp")
            await asyncio.sleep(0.2)
            assert car.V.mem["user/throttle"] == 0.0
            assert await watcher.evaluate("webStats.sent") == 0  # a watching page sends no drive
            await watcher.key("ArrowUp", down=False)
            # the big stop button works from any page
            await watcher.evaluate("document.getElementById('estop').click()")
            await car.until(lambda m: m["estop"] is True and m["user/mode"] == "user",
                            what="estop latched")
            await driver.wait_for("document.getElementById('estop').classList.contains('latched')")
            await driver.evaluate("document.getElementById('estop').click()")  # release
            await car.until(lambda m: m["estop"] is False, what="estop released")
            # take control from the watcher page
            await watcher.evaluate("document.getElementById('take').click()")
            await watcher.wait_for("webStats.role === 'driver'")
            await driver.wait_for("webStats.role === 'viewer'")
            await watcher.key("ArrowDown")
            await car.until(lambda m: m["user/throttle"] == -1.0, what="new driver reverses")
            await watcher.key("ArrowDown", down=False)
            await car.until(lambda m: m["user/throttle"] == 0.0, what="key released")

    with fake_car(tmp_path) as car:
        arun(main(car))


def test_page_without_the_pairing_token_is_refused(tmp_path, arun):
    async def main(car: Car):
        async with Chromium.launch() as browser:
            url = car.web.url
            assert "?token=" in url
            page = await browser.new_page(url.split("?")[0])
            await page.wait_for("document.getElementById('notice').textContent.includes('token')")
            assert await page.evaluate("webStats.connected") is False
            ok = await browser.new_page(url)
            await ok.wait_for(CONNECTED.format("driver"))

    with fake_car(tmp_path, WEB_TOKEN="pairing-token-42") as car:
        arun(main(car))


def test_newcomer_drives_the_simulator_by_keyboard_and_records_a_tub(tmp_path, arun):
    """The simulator car as manage.py drive assembles it: keys drive, R records a tub."""
    from parts.tub.reader import load_records
    from vehicle.app import assembly

    cfg = Config.defaults(CAR_PATH=str(tmp_path), WEB_CONTROL_PORT=0)
    V = Vehicle()
    assembly.add_simulator(V, cfg)
    web = assembly.add_controller(V, cfg)
    assembly.add_drive_mode(V, cfg)
    assembly.add_tub_writer(V, cfg)
    car = Car(V, web)

    async def main():
        async with Chromium.launch() as browser:
            page = await browser.new_page(web.url)
            await page.wait_for(CONNECTED.format("driver"))
            await page.key("r")
            await page.key("ArrowUp")
            await car.until(lambda m: (m.d.get("tub/num_records") or 0) >= 20 and (m["sim/speed"] or 0) > 0,
                            timeout=15, what="records while driving")
            await page.key("ArrowUp", down=False)
            await page.key("r")
            await car.until(lambda m: m["recording"] is False, what="recording off")
            await page.wait_for("Number(document.getElementById('records').textContent) >= 20")

    with car:
        arun(main())
    records = load_records([cfg.path("DATA_PATH")])
    assert len(records) >= 20
    assert max(r.data["user/throttle"] for r in records) == pytest.approx(cfg.WEB_MAX_THROTTLE)
    assert records[-1].image().shape == (cfg.IMAGE_H, cfg.IMAGE_W, 3)
