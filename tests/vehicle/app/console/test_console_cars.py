"""The console's Cars: pair with a real car (a Vehicle with the web page, the laptop link and a pilot,
in a thread), watch it, pull its tub into the datasets, push a model from the model manager and
switch the car's pilot to it; by the JSON API and in chromium at desktop and phone sizes."""

from __future__ import annotations

import json
import re
import stat
import threading
import time

import numpy as np
import pytest
from fixtures.load import scaled
from fixtures.pilots import write_tub

pytest.importorskip("socketio")
torch = pytest.importorskip("torch")

TOKEN = "Kq3vT9xLm2Rw8ZpN4bYc"


class Camera:
    """120x160 frames, a column moving with the loop."""

    def __init__(self) -> None:
        self.i = 0

    def run(self) -> np.ndarray:
        self.i += 1
        img = np.zeros((120, 160, 3), np.uint8)
        img[:, self.i % 160] = 255
        return img


@pytest.fixture
def real_car(tmp_path):
    """A car as manage.py drive assembles it (camera, web page with the link, pilot a.pt, drive
    mode), its data folder holding one tub of 60 records; driving in a thread at 20 Hz."""
    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.config import Config

    folder = tmp_path / "thecar"
    pre = Preprocess(crop=(40, 0, 0, 0), image_shape=(120, 160, 3))
    torch.manual_seed(0)
    model = save_model(folder / "models" / "a.pt", create_model("linear", pre.output_shape((120, 160, 3))),
                       {"preprocess": pre.to_dict()})
    write_tub(folder / "data" / "tub_1", n=30, sessions=2)
    cfg = Config.defaults(CAR_PATH=str(folder), WEB_CONTROL_PORT=0, WEB_TOKEN=TOKEN, PILOT_BACKEND="torch",
                          CAR_NAME="red")
    V = Vehicle()
    V.add(Camera(), outputs=["cam/image_array"])
    web = assembly.add_controller(V, cfg)
    assembly.add_pilot(V, cfg, model)
    assembly.add_drive_mode(V, cfg)
    errors: list[BaseException] = []

    def drive() -> None:
        try:
            V.start(rate_hz=20)
        except BaseException as exc:  # noqa: BLE001 - reported by the fixture
            errors.append(exc)

    thread = threading.Thread(target=drive, daemon=True)
    thread.start()
    end = time.monotonic() + scaled(20)
    while web.port == 0 or web.state.snapshot()["telemetry"]["loops"] < 3:
        assert time.monotonic() < end and not errors, errors
        time.sleep(0.02)
    web.folder = folder
    yield web
    V.stop()
    thread.join(scaled(20))
    assert not errors, errors


def call(port, path, method="GET", body=None):
    import urllib.error
    import urllib.request

    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data=data, method=method,
                                 headers={"Content-Type": "application/json"} if body is not None else {})
    try:
        with urllib.request.urlopen(req, timeout=scaled(90)) as resp:
            return resp.status, json.loads(resp.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def wait_pull(port, car_id):
    end = time.monotonic() + scaled(60)
    while True:
        status, pull = call(port, f"/api/cars/{car_id}/pull")
        if pull["state"] != "running":
            return pull
        assert time.monotonic() < end, pull
        time.sleep(0.05)


def test_pair_watch_pull_push_and_switch_by_the_api(console, real_car, registered_model, config):
    registered_model("laptop_pilot")
    port, car_url = console.port, f"http://127.0.0.1:{real_car.port}/"
    status, body = call(port, "/api/cars", "POST", {"address": "ftp://nowhere"})
    assert status == 400 and body["field"] == "address"
    status, body = call(port, "/api/cars", "POST", {"address": car_url, "token": "wrong-token-123456"})
    assert (status, body["field"]) == (400, "token") and "pairing token" in body["error"]
    status, car = call(port, "/api/cars", "POST", {"address": f"{car_url}?token={TOKEN}"})
    assert status == 201 and car == {"id": 1, "name": "red", "url": car_url, "paired": True}
    cars_file = console.jobs.jobs_dir / "cars.json"
    assert stat.S_IMODE(cars_file.stat().st_mode) == 0o600 and TOKEN in cars_file.read_text()
    assert TOKEN not in json.dumps(call(port, "/api/cars")[1])  # the page never gets the token

    status, view = call(port, "/api/cars/1")
    assert status == 200
    assert (view["status"]["name"], view["status"]["mode"], view["status"]["pilot"]) == ("red", "user", "a.pt")
    assert view["status"]["loops"] > 0 and view["status"]["battery_v"] is None
    assert view["tubs"] == [{"name": "tub_1", "records": 60, "bytes": view["tubs"][0]["bytes"], "new": 60,
                             "pulled": False, "folder": "red_tub_1"}]
    assert [m["name"] for m in view["models"]] == ["a.pt"]

    assert call(port, "/api/cars/1/pull", "POST")[0] == 202
    pull = wait_pull(port, 1)
    assert (pull["state"], pull["done"], pull["total"]) == ("done", 60, 60)
    assert pull["pulled"] == [{"folder": "red_tub_1", "received": 60, "new_tub": True}]
    datasets = {d["name"]: d for d in call(port, "/api/datasets")[1]}
    assert datasets["red_tub_1"]["stats"]["records"] == 60  # a dataset of the console now
    assert call(port, "/api/cars/1")[1]["tubs"][0]["new"] == 0

    status, body = call(port, "/api/cars/1/push", "POST", {"model": "no_such_model"})
    assert status == 404 and body["field"] == "model"
    status, body = call(port, "/api/cars/1/push", "POST", {"model": "laptop_pilot", "use": True})
    assert (status, body) == (200, {"ok": True, "model": "laptop_pilot.pt", "new": True, "switched": True})
    after = call(port, "/api/cars/1")[1]["status"]
    assert (after["pilot"], after["mode"]) == ("laptop_pilot.pt", "user")
    assert (real_car.folder / "models" / "laptop_pilot.pt").read_bytes() == \
        (config.path("MODELS_PATH") / "laptop_pilot.pt").read_bytes()
    assert call(port, "/api/cars/1", "DELETE")[0] == 200
    assert call(port, "/api/cars")[1] == []


@pytest.mark.browser
@pytest.mark.parametrize("size", [(1280, 900), (390, 844)], ids=["desktop", "phone"])
def test_the_cars_page(page_factory, console, real_car, registered_model, size):
    expect = pytest.importorskip("playwright.sync_api").expect
    registered_model("laptop_pilot")
    page = page_factory(*size)
    page.goto(f"http://127.0.0.1:{console.port}/#/cars")
    expect(page.locator("main h1")).to_have_text("Cars")
    page.click("nav >> text=Cars")
    page.fill("#add-car [name=address]", f"http://127.0.0.1:{real_car.port}/")
    page.fill("#add-car [name=token]", "wrong-token-123456")
    page.click("#add-car button[type=submit]")
    expect(page.locator('#add-car [data-err="token"]')).to_contain_text("pairing token")
    page.fill("#add-car [name=token]", TOKEN)
    page.click("#add-car button[type=submit]")
    card = page.locator(".car[data-car='1']")
    expect(card.locator("h2")).to_contain_text("red")
    expect(card.locator('[data-field="pilot"]')).to_have_text("a.pt")
    expect(card.locator('[data-field="mode"]')).to_have_text("user")
    expect(card.locator('[data-field="loop"]')).to_have_text(re.compile(r"Hz · \d+ overruns?"))
    expect(card.locator('[data-field="battery"]')).to_have_text("no sensor")
    expect(card.locator("tr[data-tub=tub_1] td").nth(3)).to_have_text("60")

    card.locator("[data-action=pull]").click()
    expect(card.locator("[data-pull-text]")).to_have_text("Pulled: 60 records into red_tub_1")
    expect(card.locator("[data-pull] .bar")).to_have_attribute("aria-valuenow", "100")
    expect(card.locator("tr[data-tub=tub_1] td").nth(3)).to_have_text("0")

    card.locator("select[name=model]").select_option("laptop_pilot")
    card.locator("[data-action=push-use]").click()
    expect(card.locator('[data-field="pilot"]')).to_have_text("laptop_pilot.pt")
    expect(card.locator('[data-field="notice"]')).to_contain_text("laptop_pilot.pt")
    expect(card.locator("[data-car-model='laptop_pilot.pt'] b")).to_have_text("driving")
    # nothing wider than the screen (the phone reads the tub table as cards)
    assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth + 1")
