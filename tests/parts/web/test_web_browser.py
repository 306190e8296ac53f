"""The page itself in Debian's headless chromium (Playwright, tests/fixtures/browser.py), against a real Vehicle."""

from __future__ import annotations

import time

import pytest

from vehicle.config import Config

pytestmark = pytest.mark.browser  # chromium missing: the browser fixture skips, with the reason


CONNECTED = "window.webStats && webStats.connected && webStats.role === '{}'"


def test_keys_drive_the_car_frames_arrive_and_closing_the_page_stops(tmp_path, browser, new_page, fake_car):
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


def test_a_frozen_page_trips_the_deadman(tmp_path, browser, new_page, fake_car):
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


def test_buttons_modes_record_estop_and_watcher(tmp_path, browser, new_page, fake_car, make_model_file):
    with fake_car(tmp_path, browser, model=make_model_file("linear")) as car:  # Auto steer needs a pilot
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


def test_page_without_the_pairing_token_is_refused(tmp_path, browser, new_page, fake_car):
    with fake_car(tmp_path, browser, WEB_TOKEN="pairing-token-42") as car:
        url = car.web.url
        assert "?token=" in url
        page = new_page(url.split("?")[0])
        page.wait_for_function("document.getElementById('notice').textContent.includes('token')")
        assert page.evaluate("webStats.connected") is False
        ok = new_page(url)
        ok.wait_for_function(CONNECTED.format("driver"))


def test_newcomer_drives_the_simulator_by_keyboard_and_records_a_tub(tmp_path, browser, new_page, fake_car):
    """The simulator car as manage.py drive assembles it: keys drive, R records a tub."""
    from parts.tub.reader import load_records

    cfg = Config.defaults(CAR_PATH=str(tmp_path), WEB_CONTROL_PORT=0)
    with fake_car(tmp_path, browser, sim=True, tub=True, WEB_MAX_THROTTLE=cfg.WEB_MAX_THROTTLE) as car:
        page = new_page(car.web.url)
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
