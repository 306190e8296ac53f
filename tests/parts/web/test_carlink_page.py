"""The driver page says why the car stopped when the paired laptop switched its pilot (chromium)."""

from __future__ import annotations

import pytest

from vehicle.app.carlink.client import CarAddress, CarClient

pytestmark = pytest.mark.browser


def test_a_pilot_switch_from_the_laptop_is_said_on_the_page(make_car, open_page, make_model_file):
    model = make_model_file("linear", name="pilot")
    car = make_car(model=model, MODELS_PATH=str(model.parent), DEFAULT_MODE="local")
    page = open_page(car.web.url, role="driver")
    page.wait_for_function("webStats.state && webStats.state.telemetry.mode === 'local'")
    client = CarClient(CarAddress("127.0.0.1", car.web.port))  # no token on loopback: the header only
    client.push(make_model_file("linear", name="next", seed=1))
    assert client.use("next.pt") == {"ok": True, "model": "next.pt", "switched": True}
    page.wait_for_function("webStats.state.telemetry.pilot_model === 'next.pt'")
    # the page first says the switch was asked (the car drops to user mode), then that it is done
    page.wait_for_function("document.getElementById('notice').textContent.includes('The pilot is now next.pt')")
    assert page.is_visible("#notice")
    assert page.inner_text("#notice") == ("The pilot is now next.pt (the car was put in user mode for the "
                                          "switch): choose a pilot mode to let it drive.")
    assert page.evaluate("webStats.state.command.mode") == "user"  # it stopped, and the page said why
