"""What the driver page shows about safety (issue 27, items 2-7), in headless chromium against a real
car: pilot modes refused in a car without a pilot, what a watching browser may do, a refused
pairing, the phone layout, model-load errors in plain words, and the smaller items (knob, speed
limit, disconnected state, model list, contrast, screen-reader attributes)."""

from __future__ import annotations

import io
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fixtures.browser import CONTRAST

pytestmark = pytest.mark.browser  # chromium missing: the browser fixture skips, with the reason

DESKTOP = {"width": 1280, "height": 800}
IPHONE13 = {"width": 390, "height": 664}  # Safari's viewport: the screen less its bars
IPHONE13_LANDSCAPE = {"width": 844, "height": 340}
PHONE_LANDSCAPE = {"width": 844, "height": 390}

#: the element is fully inside the viewport as the page is now (no scrolling)
ON_SCREEN = """sel => { const r = document.querySelector(sel).getBoundingClientRect();
  return r.width > 0 && r.height > 0 && r.left >= 0 && r.top >= 0 && r.right <= innerWidth + 1
         && r.bottom <= innerHeight + 1; }"""


def box(page: Any, selector: str) -> dict[str, float]:
    return page.locator(selector).bounding_box()


def opacity(page: Any, selector: str) -> float:
    return page.evaluate(CONTRAST, selector)["opacity"]


# -- 2: Auto steer and Full auto need a pilot --------------------------------------------------
@pytest.mark.parametrize("viewport", [DESKTOP, IPHONE13, IPHONE13_LANDSCAPE], ids=["desktop", "portrait", "landscape"])
def test_pilot_modes_are_refused_with_a_visible_reason_in_a_car_without_a_pilot(make_car, open_page, viewport):
    car = make_car()
    page = open_page(car.web.url, viewport, touch=viewport is not DESKTOP)
    page.wait_for_function("webStats.state && webStats.state.telemetry.loops > 2")
    page.evaluate("document.querySelector('[data-mode=local_angle]').click()")
    page.keyboard.press("m")
    page.evaluate("send('set', { mode: 'local' })")  # past the page: the car refuses it too
    page.wait_for_function("webStats.lastError && webStats.lastError.includes('pilot')")
    time.sleep(0.3)
    assert car.V.mem["user/mode"] == "user"
    assert car.web.server.state.snapshot()["command"]["mode"] == "user"
    note = page.locator("#mode-note")
    assert note.is_visible() and "no pilot" in note.inner_text() and "--model" in note.inner_text()
    assert page.evaluate(ON_SCREEN, "#mode-note") and page.evaluate(CONTRAST, "#mode-note")["ratio"] >= 4.5
    assert page.is_disabled("[data-mode=local_angle]") and page.is_disabled("[data-mode=local]")


# -- 3: a watching browser sees what it can do ------------------------------------------------
@pytest.mark.parametrize("viewport", [DESKTOP, IPHONE13], ids=["desktop", "phone"])
def test_a_watcher_is_told_on_screen_what_it_can_do(make_car, open_page, viewport):
    car = make_car()
    touch = viewport is not DESKTOP
    driver = open_page(car.web.url, viewport, touch=touch)
    watcher = open_page(car.web.url, viewport, touch=touch, role="viewer")
    text = watcher.inner_text("#watching")
    assert "STOP" in text and "Take control" in text and "release" in text
    assert watcher.evaluate(ON_SCREEN, "#watching"), "the watcher's note is off screen"
    assert opacity(watcher, "#pad") < 0.7 and opacity(driver, "#pad") == 1  # its joystick looks inactive
    watcher.click("#estop")
    car.until(lambda m: m["estop"] is True, what="a watcher may stop")
    watcher.wait_for_function("document.getElementById('estop').classList.contains('latched')")
    assert "release" not in watcher.inner_text("#estop").lower()
    assert "press the STOP button again" not in watcher.inner_text("#notice")
    watcher.click("#estop")  # it cannot release: it is told so on the page
    watcher.wait_for_function("document.getElementById('notice').textContent.includes('Take control')")
    assert watcher.evaluate(ON_SCREEN, "#notice")
    time.sleep(0.2)
    assert car.V.mem["estop"] is True
    driver.wait_for_function("document.getElementById('estop').textContent.includes('release')")


# -- 4: a refused pairing -------------------------------------------------------------------------
def test_a_refused_pairing_offers_a_token_field_and_says_why_readably(make_car, open_page):
    car = make_car(WEB_TOKEN="pairing-token-42")
    page = open_page(car.web.url.split("?")[0], role=None)
    page.wait_for_function("document.getElementById('conn').textContent.includes('refused')")
    assert page.is_visible("#token")
    reason = page.evaluate(CONTRAST, "#notice")
    assert "token" in page.inner_text("#notice") and reason["ratio"] >= 4.5 and reason["opacity"] == 1, reason
    assert opacity(page, "#estop") < 0.7  # STOP does not look active: nothing is connected
    page.fill("#token", "wrong")
    page.keyboard.press("Enter")
    page.wait_for_function("document.getElementById('conn').textContent.includes('refused')")
    assert "token=wrong" in page.url and page.is_visible("#token")
    page.fill("#token", "pairing-token-42")
    page.click("#pair button")
    page.wait_for_function("window.webStats && webStats.connected && webStats.role === 'driver'")
    assert "token=pairing-token-42" in page.url and not page.is_visible("#token")
    assert opacity(page, "#estop") == 1


# -- 5: phones: mode and record within reach, no key help -----------------------------------------
@pytest.mark.parametrize("viewport", [IPHONE13, IPHONE13_LANDSCAPE, PHONE_LANDSCAPE],
                         ids=["portrait", "landscape-safari", "landscape"])
def test_mode_and_record_are_within_reach_on_a_phone(make_car, open_page, make_model_file, viewport):
    car = make_car(model=make_model_file("linear"))
    page = open_page(car.web.url, viewport, touch=True)
    page.wait_for_function("webStats.state && webStats.state.telemetry.pilot_model")
    assert page.evaluate("scrollY") == 0
    for selector in ("#pad", "#estop", "[data-mode=user]", "[data-mode=local_angle]", "[data-mode=local]",
                     "#record"):
        assert page.evaluate(ON_SCREEN, selector), (selector, box(page, selector))
    if viewport["width"] > viewport["height"]:  # beside the joystick, right of the camera
        cam, drive = box(page, "#cam"), box(page, ".drive")
        for selector in ("[data-mode=user]", "[data-mode=local]", "#record"):
            b = box(page, selector)
            assert b["x"] >= cam["x"] + cam["width"] - 1, selector
            assert drive["y"] <= b["y"] and b["y"] + b["height"] <= drive["y"] + drive["height"] + 1, selector
    assert not page.is_visible(".help")  # no keys on a phone
    page.click("[data-mode=local]")
    car.until(lambda m: m["user/mode"] == "local", what="full auto from the phone")


def test_the_key_help_shows_on_a_desktop(make_car, open_page):
    car = make_car()
    page = open_page(car.web.url)
    assert page.is_visible(".help")


# -- 6: model-load errors in plain words where the eye is ------------------------------------------
def test_a_model_load_error_is_plain_and_on_screen(make_car, open_page, make_model_file, tmp_path):
    model = make_model_file("linear", name="pilot")
    (model.parent / "broken.pt").write_bytes(b"not a model")
    car = make_car(model=model, MODELS_PATH=str(model.parent))
    page = open_page(car.web.url, DESKTOP)
    page.select_option("#model", "broken.pt")
    page.click("#load")
    page.wait_for_function("document.getElementById('model-error').textContent.includes('broken.pt')")
    text = page.inner_text("#model-error")
    assert page.evaluate(ON_SCREEN, "#model-error"), box(page, "#model-error")
    assert page.evaluate(CONTRAST, "#model-error")["ratio"] >= 4.5
    assert text.startswith("Could not load broken.pt:"), text
    assert text.count("broken.pt") == 1 and str(tmp_path) not in text, text
    assert "set:" not in text
    # a page opened later shows the error too, and opens at its top: joystick and STOP first
    phone = open_page(car.web.url, IPHONE13, touch=True, role="viewer")
    phone.wait_for_function("document.getElementById('model-error').textContent.includes('broken.pt')")
    assert phone.evaluate("scrollY") == 0 and phone.evaluate(ON_SCREEN, "#estop")


def test_the_model_list_shows_the_running_model_at_once(make_car, open_page, make_model_file):
    car = make_car(model=make_model_file("linear", name="pilot"))
    page = open_page(car.web.url)
    page.wait_for_function("webStats.state && webStats.state.telemetry.pilot_model === 'pilot.pt'")
    assert page.eval_on_selector("#model", "s => s.value") == "pilot.pt"


def test_loading_a_model_without_a_pilot_says_it_in_plain_words(make_car, open_page, make_model_file):
    model = make_model_file("linear", name="pilot")
    car = make_car(MODELS_PATH=str(model.parent))
    page = open_page(car.web.url)
    page.select_option("#model", "pilot.pt")
    page.click("#load")
    page.wait_for_function("document.getElementById('model-error').textContent.includes('no pilot')")
    assert not page.inner_text("#model-error").startswith("set:")
    assert page.evaluate(ON_SCREEN, "#model-error")


# -- 7: the smaller items ---------------------------------------------------------------------
def test_the_knob_follows_keyboard_steering(make_car, open_page):
    car = make_car()
    page = open_page(car.web.url)
    knob = "() => [parseFloat(knob.style.left || '35'), parseFloat(knob.style.top || '35')]"
    page.keyboard.down("ArrowRight")
    page.keyboard.down("ArrowUp")
    page.wait_for_function(f"({knob})()[0] > 55 && ({knob})()[1] < 15")  # up and right, in the circle
    page.keyboard.up("ArrowRight")
    page.keyboard.up("ArrowUp")
    page.wait_for_function(f"({knob})()[0] === 35 && ({knob})()[1] === 35")


def thumb_pixels(page: Any) -> int:
    """Pixels of the accent colour (the slider's thumb) in a picture of the speed-limit slider."""
    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(page.locator("#speedlimit").screenshot())).convert("RGB"), int)
    accent = np.array([0x3d, 0x8b, 0xfd])
    return int((np.abs(image - accent).sum(axis=2) < 60).sum())


def test_speed_limit_none_shows_no_slider_position(make_car, open_page):
    car = make_car(sim=True)
    page = open_page(car.web.url)
    page.wait_for_function("!document.getElementById('nolimit').disabled")
    assert page.is_checked("#nolimit") and thumb_pixels(page) == 0
    page.uncheck("#nolimit")
    car.until(lambda m: m["user/speed_limit"] is not None, what="a limit")
    page.wait_for_function("!document.getElementById('speedlimit').disabled")
    assert thumb_pixels(page) > 20


def test_a_disconnected_page_dims_stop_and_the_loop_rate(make_car, open_page):
    car = make_car()
    page = open_page(car.web.url)
    page.wait_for_function("document.getElementById('rate').textContent !== '–'")
    assert opacity(page, "#estop") == 1 and opacity(page, ".health") == 1
    car.stop()
    page.wait_for_function("!webStats.connected")
    page.wait_for_function("getComputedStyle(document.getElementById('estop')).opacity < 0.7")
    assert opacity(page, ".health") < 0.7


def test_the_model_list_preselects_nothing_when_no_model_is_loaded(make_car, open_page, tmp_path: Path):
    (tmp_path / "models").mkdir()
    for name in ("a.pt", "b.pt"):
        (tmp_path / "models" / name).write_bytes(b"x")
    car = make_car()
    page = open_page(car.web.url)
    page.wait_for_function("webStats.state && webStats.state.telemetry.loops > 2")
    assert page.eval_on_selector("#model", "s => s.value") == ""
    assert page.is_disabled("#load")


def test_labels_have_enough_contrast_and_screen_readers_are_told(make_car, open_page):
    car = make_car()
    page = open_page(car.web.url)
    page.click("#record")
    page.wait_for_function("document.getElementById('record').classList.contains('on')")
    page.wait_for_function("document.getElementById('conn').textContent === 'connected'")
    for selector in ("#conn", "#role", "[data-mode=user]", "#record", ".gauge .label", ".health",
                     "#speedlimit-note", "#estop", "#gamepad"):
        c = page.evaluate(CONTRAST, selector)
        assert c["ratio"] >= 4.5 and c["opacity"] == 1, (selector, c)
    pressed = page.eval_on_selector_all("[data-mode]", "bs => bs.map(b => b.getAttribute('aria-pressed'))")
    assert pressed == ["true", "false", "false"]
    page.click("#estop")
    page.wait_for_function("!document.getElementById('notice').hidden")
    assert page.get_attribute("#notice", "role") == "alert"
    c = page.evaluate(CONTRAST, "#notice")
    assert c["ratio"] >= 4.5, c
