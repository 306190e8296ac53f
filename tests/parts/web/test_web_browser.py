"""The page itself in Debian's headless chromium (Playwright, tests/fixtures/browser.py), against a real Vehicle."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from vehicle import Vehicle
from vehicle.app.assembly.controller import add_controller
from vehicle.app.assembly.drive import add_drive_mode
from vehicle.config import Config

pytestmark = pytest.mark.browser  # chromium missing: the browser fixture skips, with the reason


class FakeCamera:
    def __init__(self) -> None:
        self.i = 0

    def run(self) -> np.ndarray:
        self.i += 1
        img = np.full((120, 160, 3), 30, np.uint8)
        img[:, self.i % 160] = 255
        return img


def fake_car(tmp_path, browser, **overrides) -> Car:
    """Fake camera -> web controller -> drive mode."""
    cfg = Config.defaults(CAR_PATH=str(tmp_path), WEB_CONTROL_PORT=0, WEB_MAX_THROTTLE=1.0, **overrides)
    V = Vehicle()
    V.add(FakeCamera(), outputs=["cam/image_array"])
    web = add_controller(V, cfg)
    add_drive_mode(V, cfg)
    return Car(V, web, browser)


class Car:
    """A small real Vehicle (fake camera, web controller, drive mode) running in a thread.

    On exit the browser's pages are closed first, then the car stops.
    """

    def __init__(self, V: Vehicle, web, browser) -> None:
        self.V, self.web, self.browser = V, web, browser
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
        for context in self.browser.contexts:
            context.close()
        self.V.stop()
        self.thread.join(10)
        assert not self.errors, self.errors

    def until(self, cond, timeout: float = 5.0, what: str = "") -> None:
        end = time.monotonic() + timeout
        while not cond(self.V.mem):
            if time.monotonic() > end:
                raise AssertionError(f"vehicle memory condition not met: {what}; "
                                     f"user/angle={self.V.mem['user/angle']} "
                                     f"user/throttle={self.V.mem['user/throttle']}")
            time.sleep(0.01)


CONNECTED = "window.webStats && webStats.connected && webStats.role === '{}'"



def test_keys_drive_the_car_frames_arrive_and_closing_the_page_stops(tmp_path, browser, new_page):
    with fake_car(tmp_path, browser) as car:
        page = new_page(car.web.url)
        page.wait_for_function(CONNECTED.format("driver"))
        page.wait_for_function("webStats.frames >= 5")
        page.keyboard.down("ArrowUp")
        page.keyboard.down("ArrowRight")
        car.until(lambda m: m["user/throttle"] == 1.0 and m["user/angle"] > 0.5, what="up + right held")
        assert car.V.mem["throttle"] == 1.0  # through DriveMode to the final command
        page.keyboard.up("ArrowRight")
        car.until(lambda m: m["user/angle"] == 0.0, what="steering back to centre")
        # the gauges show what the car does
        page.wait_for_function("document.getElementById('throttle').textContent === '1.00'")
        # close the tab with the throttle key still held: the car must stop
        page.close()
        car.until(lambda m: m["user/throttle"] == 0.0 and m["throttle"] == 0.0,
                  what="stop after the page closed")


def test_a_frozen_page_trips_the_deadman(tmp_path, browser, new_page):
    with fake_car(tmp_path, browser) as car:
        page = new_page(car.web.url)
        page.wait_for_function(CONNECTED.format("driver"))
        page.keyboard.down("ArrowUp")
        car.until(lambda m: m["user/throttle"] == 1.0, what="driving")
        # block the page's JavaScript for 2 s (from a timer, so that this call returns at once):
        # still connected, but no control messages
        page.evaluate("ms => setTimeout(() => { const t = Date.now(); while (Date.now() - t < ms) {} }, 0)",
                      2000)
        car.until(lambda m: m["user/throttle"] == 0.0 and m["throttle"] == 0.0,
                  timeout=1.9, what="dead-man stop while the page is frozen")
        assert car.web.state.deadman_trips == 1
        page.evaluate("0")  # answered once the page runs again
        page.keyboard.up("ArrowUp")
        page.wait_for_function("document.getElementById('notice').textContent.startsWith('Dead-man')")


def test_buttons_modes_record_estop_and_watcher(tmp_path, browser, new_page):
    with fake_car(tmp_path, browser) as car:
        driver = new_page(car.web.url)
        driver.wait_for_function(CONNECTED.format("driver"))
        watcher = new_page(car.web.url)
        watcher.wait_for_function(CONNECTED.format("viewer"))
        driver.click("[data-mode=local_angle]")
        car.until(lambda m: m["user/mode"] == "local_angle", what="mode button")
        driver.keyboard.press("r")
        car.until(lambda m: m["recording"] is True, what="R toggles recording")
        # the watcher's keys do not drive
        watcher.keyboard.down("ArrowUp")
        time.sleep(0.2)
        assert car.V.mem["user/throttle"] == 0.0
        assert watcher.evaluate("webStats.sent") == 0  # a watching page sends no drive
        watcher.keyboard.up("ArrowUp")
        # the big stop button works from any page
        watcher.click("#estop")
        car.until(lambda m: m["estop"] is True and m["user/mode"] == "user", what="estop latched")
        driver.wait_for_function("document.getElementById('estop').classList.contains('latched')")
        driver.click("#estop")  # release
        car.until(lambda m: m["estop"] is False, what="estop released")
        # take control from the watcher page
        watcher.click("#take")
        watcher.wait_for_function("webStats.role === 'driver'")
        driver.wait_for_function("webStats.role === 'viewer'")
        watcher.keyboard.down("ArrowDown")
        car.until(lambda m: m["user/throttle"] == -1.0, what="new driver reverses")
        watcher.keyboard.up("ArrowDown")
        car.until(lambda m: m["user/throttle"] == 0.0, what="key released")


def test_page_without_the_pairing_token_is_refused(tmp_path, browser, new_page):
    with fake_car(tmp_path, browser, WEB_TOKEN="pairing-token-42") as car:
        url = car.web.url
        assert "?token=" in url
        page = new_page(url.split("?")[0])
        page.wait_for_function("document.getElementById('notice').textContent.includes('token')")
        assert page.evaluate("webStats.connected") is False
        ok = new_page(url)
        ok.wait_for_function(CONNECTED.format("driver"))


def test_newcomer_drives_the_simulator_by_keyboard_and_records_a_tub(tmp_path, browser, new_page):
    """The simulator car as manage.py drive assembles it: keys drive, R records a tub."""
    from parts.tub.reader import load_records
    from vehicle.app import assembly

    cfg = Config.defaults(CAR_PATH=str(tmp_path), WEB_CONTROL_PORT=0)
    V = Vehicle()
    assembly.add_simulator(V, cfg)
    web = assembly.add_controller(V, cfg)
    assembly.add_drive_mode(V, cfg)
    assembly.add_tub_writer(V, cfg)
    with Car(V, web, browser) as car:
        page = new_page(web.url)
        page.wait_for_function(CONNECTED.format("driver"))
        page.keyboard.press("r")
        page.keyboard.down("ArrowUp")
        car.until(lambda m: (m.d.get("tub/num_records") or 0) >= 20 and (m["sim/speed"] or 0) > 0,
                  timeout=15, what="records while driving")
        page.keyboard.up("ArrowUp")
        page.keyboard.press("r")
        car.until(lambda m: m["recording"] is False, what="recording off")
        page.wait_for_function("Number(document.getElementById('records').textContent) >= 20")
    records = load_records([cfg.path("DATA_PATH")])
    assert len(records) >= 20
    assert max(r.data["user/throttle"] for r in records) == pytest.approx(cfg.WEB_MAX_THROTTLE)
    assert records[-1].image().shape == (cfg.IMAGE_H, cfg.IMAGE_W, 3)
