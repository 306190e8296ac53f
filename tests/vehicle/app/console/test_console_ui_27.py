"""Issue 27 item 18: the console's words and controls say what is true (chromium, desktop and
phone sizes): finished evaluations, cancelled trainings, renamed models, errors that clear as the
user types, no broken preview image, plurals, the run page's heading, and the delete dialog."""

from __future__ import annotations

import json
import re
import sqlite3

import pytest
from test_console_api import request

pytestmark = pytest.mark.browser
expect = pytest.importorskip("playwright.sync_api").expect
SIZES = [(1280, 800), (390, 844)]


def _open(page, url, route=""):
    page.goto(url + "#/" + route)
    page.wait_for_selector("main h1", timeout=180000)  # the first page waits for the model types (torch)
    return page


def _finished_jobs(config, model):
    """A finished training of ``model`` and a finished evaluation of it, as a console stored them."""
    from training.model_db import DB_FILENAME
    from vehicle.app.console.jobs import _TABLE

    db = config.path("MODELS_PATH") / DB_FILENAME
    overall = {"autonomy": 100.0, "laps_completed": 1, "mean_abs_cte": 0.1, "mean_speed": 1.0, "interventions": 0}
    rows = [("train", "done", f"Train {model}", {"model_name": model, "tubs": [], "hyper": {}},
             {"model": model, "metrics": {"best_epoch": 1, "epochs": 1, "best_val_loss": 0.1}}),
            ("evaluate", "done", f"Evaluate {model}", {"model": model, "tracks": [101], "laps": 1},
             {"evaluation_id": 1, "overall": overall, "per_track": []})]
    with sqlite3.connect(db) as conn:
        conn.execute(_TABLE)
        for kind, status, title, params, result in rows:
            conn.execute("INSERT INTO console_jobs (kind, status, title, params, created, finished, result) "
                         "VALUES (?, ?, ?, ?, '2026-01-01T00:00:00', '2026-01-01T00:01:00', ?)",
                         (kind, status, title, json.dumps(params), json.dumps(result)))
    return db


@pytest.mark.parametrize("size", SIZES, ids=["desktop", "phone"])
def test_finished_runs_and_renamed_models(page_factory, config, registered_model, console_factory, size):
    registered_model("first_name")
    registered_model("other_model")
    assert console_factory  # the console starts after the jobs are stored
    _finished_jobs(config, "first_name")
    app = console_factory()
    url = f"http://127.0.0.1:{app.port}/"
    page = page_factory(*size)
    # a finished evaluation: progress and the result card agree, in plain plurals
    _open(page, url, "runs/2")
    expect(page.locator("main h1")).to_have_text("Evaluation result")
    expect(page.locator("#stat-laps")).to_have_text("1 / 1")
    assert page.evaluate("document.querySelector('.bar div').style.width") == "100%"
    expect(page.locator("main")).to_contain_text("Tracks 101, 1 lap each.")
    expect(page.locator("main")).not_to_contain_text("1 laps")
    # a rename: the runs link to the model's new name, also after a console restart
    assert request(app.port, "/api/models/first_name", "PATCH", {"name": "new_name"})[0] == 200
    _open(page, url, "runs/1")
    expect(page.locator("main h1")).to_have_text("Training result")
    expect(page.locator("#run-result a")).to_have_text("new_name")
    app.close()
    again = console_factory()
    assert json.loads(request(again.port, "/api/jobs/1")[2])["result"]["model"] == "new_name"
    assert json.loads(request(again.port, "/api/jobs/2")[2])["params"]["model"] == "new_name"
    _open(page, f"http://127.0.0.1:{again.port}/", "")
    expect(page.locator("#home-models")).to_contain_text("2 models")
    # delete: the files stay unless the user ticks the box
    _open(page, f"http://127.0.0.1:{again.port}/", "models")
    page.locator("tr[data-model=other_model] [data-action=delete]").click()
    expect(page.locator("#delete-files")).not_to_be_checked()
    page.click("#modal-ok")
    expect(page.locator("tr[data-model=other_model]")).to_have_count(0)
    assert (config.path("MODELS_PATH") / "other_model.pt").is_file()


@pytest.mark.parametrize("size", SIZES, ids=["desktop", "phone"])
def test_training_setup_preview_and_name_error(page_factory, url, registered_model, size):
    registered_model("taken_name")
    page = _open(page_factory(*size), url, "train")
    expect(page.locator("#train-datasets input:checked")).to_have_count(0)
    expect(page.locator("#aug-note")).to_contain_text("Choose a dataset")
    expect(page.locator("#aug-preview")).to_be_hidden()  # no broken-image icon
    page.locator("#train-datasets input").first.check()
    expect(page.locator("#aug-preview")).to_be_visible()
    page.wait_for_function("document.querySelector('#aug-preview').naturalWidth > 0")
    page.fill("#model-name", "taken_name")
    page.click("#start-training")
    err = page.locator("[data-err=name]")
    expect(err).not_to_be_empty()
    page.locator("#model-name").press_sequentially("_2")
    expect(err).to_be_empty()
    expect(page.locator("#model-name")).not_to_have_class(re.compile("invalid"))
    page.locator("#train-datasets input").first.uncheck()
    expect(page.locator("#aug-preview")).to_be_hidden()


def test_a_training_cancelled_before_its_first_epoch_says_no_model_was_saved(page, config, console_factory):
    from training.model_db import DB_FILENAME
    from vehicle.app.console.jobs import _TABLE

    db = config.path("MODELS_PATH") / DB_FILENAME
    with sqlite3.connect(db) as conn:
        conn.execute(_TABLE)
        conn.execute("INSERT INTO console_jobs (kind, status, title, params, created, finished, message) VALUES "
                     "('train', 'cancelled', 'Train x', ?, '2026-01-01T00:00:00', '2026-01-01T00:01:00', "
                     "'training was cancelled before its first epoch ended: no model was saved')",
                     (json.dumps({"model_name": "x", "tubs": [], "hyper": {}}),))
    app = console_factory()
    _open(page, f"http://127.0.0.1:{app.port}/", "runs/1")
    expect(page.locator("main h1")).to_have_text("Training result")
    expect(page.locator("#run-result")).to_contain_text("No model was saved")
    expect(page.locator("main")).not_to_contain_text("best model so far")
