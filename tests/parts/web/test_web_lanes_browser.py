"""The page's lane display and "change lane" button in headless chromium (Playwright), against the
simulator car with behaviours as manage.py assembles it."""

from __future__ import annotations

import shutil
import threading
import time

import pytest

from vehicle import Vehicle
from vehicle.app import assembly
from vehicle.config import Config

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(not shutil.which("chromium") and not __import__("os").path.exists(CHROMIUM),
                       reason="Debian's chromium is not installed (apt-get install chromium)"),
]


def _wait(cond, timeout: float = 10.0, what: str = "") -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"not within {timeout} s: {what}")
        time.sleep(0.02)


def test_page_shows_the_lane_and_changes_it(tmp_path):
    sync_api = pytest.importorskip("playwright.sync_api")
    cfg = Config.defaults(CAR_PATH=str(tmp_path), WEB_CONTROL_PORT=0, SIM_LANES=2, TRAIN_BEHAVIORS=True,
                          SIM_TEXTURE_RES=0.02)
    V = Vehicle()
    assembly.add_simulator(V, cfg)
    web = assembly.add_controller(V, cfg)
    assembly.add_behavior(V, cfg)
    assembly.add_drive_mode(V, cfg)
    errors: list[BaseException] = []

    def drive() -> None:
        try:
            V.start(rate_hz=20)
        except BaseException as exc:  # reported below
            errors.append(exc)

    thread = threading.Thread(target=drive)
    thread.start()
    try:
        _wait(lambda: web.port != 0, what="web server up")
        with sync_api.sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM)
            page = browser.new_page()
            page.goto(web.url)
            page.wait_for_function("window.webStats && webStats.connected && webStats.role === 'driver'")
            row = page.locator("#behaviorrow")
            page.wait_for_function("!document.getElementById('behaviorrow').hidden")
            assert row.is_visible()
            assert page.locator("#behavior").inner_text() == "Left Lane"
            page.click("#behaviornext")
            _wait(lambda: V.mem["behavior/label"] == "Right_Lane", what="right lane after the button")
            page.wait_for_function("document.getElementById('behavior').textContent === 'Right Lane'")
            page.keyboard.press("l")
            _wait(lambda: V.mem["behavior/label"] == "Left_Lane", what="left lane after the L key")
            assert V.mem["behavior/one_hot_state_array"] == [1.0, 0.0]
            browser.close()
    finally:
        V.stop()
        thread.join(10)
    assert not errors, errors
