"""The driver page shows the car's sensors and the obstacle stop (issue 29), in headless chromium
against a real simulator car with simulated sensors."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.browser  # chromium missing: the browser fixture skips, with the reason


def test_page_shows_sensor_freshness_and_the_obstacle_stop(make_car, new_page):
    car = make_car(sim=True, HAVE_ODOM=True, USE_LIDAR=True, OBSTACLE_STOP=True, LIDAR_BINS=90,
                   OBSTACLE_STOP_WHEN_BLIND=True, SIM_TEXTURE_RES=0.02)
    page = new_page(device="desktop", viewport={"width": 1280, "height": 800})
    page.goto(car.web.url)
    page.wait_for_function("document.querySelector('#sensors') && !document.querySelector('#sensors').hidden")
    page.wait_for_function("document.querySelector('#sensors').textContent.includes('enc ok')")
    text = page.locator("#sensors").text_content()
    assert "lidar ok" in text and "STALE" not in text
    # the measured speed (odometer, from simulated ticks) is what the page shows
    car.until(lambda m: m["enc/ok"] is True and m["enc/speed"] is not None, what="the odometer measures")
