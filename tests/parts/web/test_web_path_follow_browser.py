"""The driver page with the real path-follow parts (issue 30): record a path with the page's buttons
while driving the simulator from the page, see it drawn, save it. Skipped where the path-follow
parts (parts/path, vehicle/app/path_sim.py) are not in the tree."""

from __future__ import annotations

import pytest
from fixtures.load import wait_until

pytestmark = pytest.mark.browser  # chromium missing: the browser fixture skips, with the reason
pytest.importorskip("parts.path.recorder", reason="the path-follow parts (parts/path) are not in this tree")
pytest.importorskip("vehicle.app.path_sim", reason="vehicle/app/path_sim.py is not in this tree")


def test_record_a_path_from_the_page_see_it_drawn_and_save_it(make_car, open_page, tmp_path):
    # the path_follow template's car in the simulator (real time), as its manage.py drive --sim
    car = make_car(sim=True, path_follow=True, SIM_TEXTURE_RES=0.02, WEB_MAX_THROTTLE=0.6,
                   PATH_FILENAME=str(tmp_path / "path.csv"))
    page = open_page(car.web.url)
    page.wait_for_function("!document.getElementById('pathview').hidden")
    page.wait_for_function("document.getElementById('pathstate').textContent === 'no path'")
    page.click("#pathrecord")
    page.wait_for_function("document.getElementById('pathstate').textContent === 'recording'")
    page.keyboard.down("ArrowUp")
    car.until(lambda m: m["path/xy"] is not None and len(m["path/xy"]) >= 5, timeout=20,
              what="the recorder adds points while the car drives")
    page.keyboard.up("ArrowUp")
    page.click("#pathrecord")
    page.wait_for_function("document.getElementById('pathstate').textContent === 'ready'")
    n = len(car.V.mem["path/xy"])
    page.wait_for_function(f"webStats.pathView.drawn.points === {n}")  # the whole path, drawn
    # the car is drawn on the map, oriented (the simulator gives its heading)
    car_px, heading, size = page.evaluate(
        "[webStats.pathView.drawn.car, webStats.pathView.drawn.heading,"
        " [document.getElementById('pathmap').width, document.getElementById('pathmap').height]]")
    assert 0 <= car_px[0] <= size[0] and 0 <= car_px[1] <= size[1], (car_px, size)
    assert isinstance(heading, int | float) and abs(heading) <= 7, heading  # radians
    page.click("[data-path=save]")
    saved = tmp_path / "path.csv"

    def rows() -> list[str]:
        return saved.read_text().strip().splitlines() if saved.exists() else []

    assert wait_until(lambda: len(rows()) == n + 1, 10), rows()  # a header and every point
    assert rows()[0].startswith("x,y")
    assert page.evaluate("webStats.rejected") == 0
