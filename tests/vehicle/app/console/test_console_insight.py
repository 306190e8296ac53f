"""What the console shows of a pilot's sight (issue 42): an evaluation's failure gallery, a model's
saliency on frames of its datasets, a tub's movie; over the API and in chromium at two sizes."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from test_console_api import request

expect = pytest.importorskip("playwright.sync_api").expect


@pytest.fixture
def evaluated(config, registered_model):
    """A registered untrained model, evaluated (it leaves the road) with a gallery and stored, as
    ``vehicle sim eval --gallery DIR --store`` does; (model name, evaluation id, gallery folder)."""
    from vehicle.app.console.insight import insight_dir
    from vehicle.app.eval_store import store_report
    from vehicle.app.evaluate import evaluate
    from vehicle.app.failure_moments import GallerySpec

    path = registered_model("sal_1")
    folder = insight_dir(config, "galleries") / "sal_1-test"
    report = evaluate(str(path), [11], 1, cfg=config.replace(SIM_TEXTURE_RES=0.02), max_time=6.0, fixed_throttle=0.4,
                      gallery=GallerySpec(str(folder), str(path), window_s=1.0, frames=3, worst=1))
    assert report["overall"]["interventions"] >= 1
    return "sal_1", store_report(config, path, report).id, folder


def test_gallery_saliency_and_movie_over_the_api(console, evaluated, config, registered_model):
    name, eid, folder = evaluated
    port = console.port
    status, _, body = request(port, f"/api/evaluations/{eid}/gallery")
    data = json.loads(body)
    assert status == 200 and data["base"] == f"api/evaluations/{eid}/gallery/"
    assert data == {**json.loads((folder / "gallery.json").read_text()), "base": data["base"]}
    first = data["tracks"][0]["moments"][0]["frames"][0]
    status, headers, jpg = request(port, f"/api/evaluations/{eid}/gallery/{first['saliency']['camera']}")
    assert status == 200 and headers["Content-Type"] == "image/jpeg" and jpg[:2] == b"\xff\xd8"
    assert jpg == (folder / first["saliency"]["camera"]).read_bytes()
    status, headers, page = request(port, f"/api/evaluations/{eid}/gallery/index.html")
    assert status == 200 and headers["Content-Type"].startswith("text/html") and b"Failures of" in page
    for bad in ("../gallery.json", "%2e%2e/%2e%2e/myconfig.py", "track-11/../../../myconfig.py"):
        assert request(port, f"/api/evaluations/{eid}/gallery/{bad}")[0] == 404

    status, _, body = request(port, f"/api/models/{name}/saliency")
    sal = json.loads(body)
    assert status == 200, sal
    assert len(sal["samples"]) == 4 and sal["base"] == f"api/models/{name}/saliency/"
    for s in sal["samples"]:
        assert set(s["steering"]) == set(s["throttle"]) == {"camera"}
        assert request(port, f"/api/models/{name}/saliency/{s['steering']['camera']}")[0] == 200
    assert request(port, f"/api/models/{name}/saliency/..%2Fsal_1%2Fsamples.json")[0] == 404

    dataset = json.loads(request(port, "/api/datasets")[2])[0]["id"]
    status, headers, webm = request(port, f"/api/datasets/{dataset}/movie")
    assert status == 200 and headers["Content-Type"] == "video/webm" and webm[:4] == b"\x1a\x45\xdf\xa3"  # EBML
    movies = list((Path(config.CAR_PATH) / "insight" / "movies").glob("*.webm"))
    assert len(movies) == 1 and request(port, f"/api/datasets/{dataset}/movie")[2] == webm  # made once, kept


def test_bad_input_gets_one_line(console, config, registered_model):
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess
    from training.model_db import register_model

    pre = Preprocess(image_shape=(64, 64, 3))  # trained on other frames than the car's 120x160 tubs
    path = config.path("MODELS_PATH") / "small.pt"
    tubs = [str(p) for p in config.path("DATA_PATH").iterdir()]
    meta = {"type": "linear", "preprocess": pre.to_dict(), "datasets": tubs}
    torch.manual_seed(0)
    save_model(path, create_model("linear", pre.output_shape((64, 64, 3))), meta)
    register_model(path, meta)
    status, _, body = request(console.port, "/api/models/small/saliency")
    error = json.loads(body)["error"]
    assert status == 400 and "frame is 120x160x3 but the model was trained on 64x64x3 frames" in error
    assert "\n" not in error and "Traceback" not in error
    registered_model("plain_1")
    from training.model_db import ModelDB

    ev = ModelDB.for_models_dir(config.path("MODELS_PATH")).add_evaluation(
        "plain_1", {"seeds": [11], "laps": 1, "overall": {"autonomy": 100.0}, "tracks": [], "settings": {}})
    status, _, body = request(console.port, f"/api/evaluations/{ev.id}/gallery")
    assert status == 404 and "has no gallery" in json.loads(body)["error"]
    status, _, body = request(console.port, "/api/datasets/99/movie")
    assert status == 404


def _shots(tmp_path: Path) -> Path:
    """Where screenshots go: $VEHICLE_SCREENSHOTS to look at them, else the test's folder."""
    folder = Path(os.environ.get("VEHICLE_SCREENSHOTS") or tmp_path)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _all_images_loaded(page, selector):
    """Count of ``selector``'s images once every one has loaded (each scrolled to: they load lazily)."""
    page.wait_for_selector(selector, state="attached")
    images = page.locator(selector)
    for i in range(images.count()):
        images.nth(i).scroll_into_view_if_needed()
    page.wait_for_function(f"""() => {{ const imgs = [...document.querySelectorAll({selector!r})];
        return imgs.length > 0 && imgs.every(i => i.complete && i.naturalWidth > 0); }}""")
    return page.locator(selector).count()


@pytest.mark.browser
def test_console_pages_show_gallery_saliency_and_movie(page_factory, url, evaluated, browser, tmp_path):
    """At a desktop's and a phone's size (one evaluation, saliency and movie: made once, then kept)."""
    for size in ((1280, 900), (390, 844)):
        _pages_at(page_factory, url, evaluated, browser, size, _shots(tmp_path))


def _pages_at(page_factory, url, evaluated, browser, size, shots):
    name, eid, folder = evaluated
    tag = "desktop" if size[0] > 600 else "phone"
    page = page_factory(*size)
    page.goto(url + f"#/models/{name}")
    page.wait_for_selector("main h1", timeout=180000)
    gallery = page.locator(f"details.gallery[data-gallery='{eid}']")
    expect(gallery).to_have_attribute("open", "")
    moments = json.loads((folder / "gallery.json").read_text())["tracks"][0]["moments"]
    expect(gallery.locator(".moment")).to_have_count(len(moments))
    assert _all_images_loaded(page, "details.gallery figure img") == sum(len(m["frames"]) for m in moments)
    assert _all_images_loaded(page, "#saliency img") == 4 * 3  # frame, steering and throttle maps
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= size[0] + 1, f"the model page scrolls sideways at {size}"
    page.locator("#saliency").scroll_into_view_if_needed()
    page.screenshot(path=str(shots / f"console-model-{tag}.png"), full_page=True)

    page.goto(url + f"#/datasets/{json.loads(request(int(url.split(':')[2].strip('/')), '/api/datasets')[2])[0]['id']}")
    page.click("#play-movie")
    page.wait_for_function("() => { const v = document.querySelector('.movie video'); "
                           "return v && v.readyState >= 2 && v.videoWidth === 320; }", timeout=120000)
    page.screenshot(path=str(shots / f"console-dataset-{tag}.png"), full_page=True)

    static = browser.new_context(viewport={"width": size[0], "height": size[1]})  # from the disk: no server
    p2 = static.new_page()
    p2.goto((folder / "index.html").as_uri())
    assert _all_images_loaded(p2, "figure img") == 2 * sum(len(m["frames"]) for m in moments)
    assert p2.locator("section.moment").count() == len(moments)
    assert p2.evaluate("document.documentElement.scrollWidth") <= size[0] + 1
    p2.screenshot(path=str(shots / f"gallery-{tag}.png"), full_page=True)
    static.close()
