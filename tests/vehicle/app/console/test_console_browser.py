"""The trainer console in Debian's headless chromium: Track Driver AI's interface (TN), operation (TO) and
validation (TV) tables, a real training from the wizard with its live loss chart, cancel, two
browsers, a reload, an evaluation from the model manager and the leaderboard."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from parts.tub.tub import Tub
from training.model_db import ModelDB

pytestmark = pytest.mark.browser
expect = pytest.importorskip("playwright.sync_api").expect


def _open(page, url, route=""):
    page.goto(url + "#/" + route)
    page.wait_for_selector("main h1", timeout=180000)  # the first page waits for the model types (torch)
    return page


def _heading(page, text):
    expect(page.locator("main h1")).to_have_text(re.compile(text))


# -- TN: navigation ------------------------------------------------------------------------------------
def test_tn_navigation(page, url, registered_model):
    registered_model("drive_1_1")
    _open(page, url)
    page.click("nav >> text=Datasets")  # TN1a
    _heading(page, "^Datasets$")
    page.click("nav >> text=Models")  # TN1b
    _heading(page, "^Models$")
    page.click(".brand")
    page.click("#home-datasets")  # TN2a
    _heading(page, "^Datasets$")
    page.click(".brand")
    page.click("#home-models")  # TN2b
    _heading(page, "^Models$")

    page.click("nav >> text=Datasets")
    page.click("#add-dataset")  # TN3a
    _heading(page, "Add dataset")
    page.click("#back")  # TN4a
    _heading(page, "^Datasets$")
    page.click("#add-dataset")
    page.fill("input[name=name]", "test_drive_abc")
    page.click("#submit")  # TN4b
    _heading(page, "^Datasets$")
    row = page.locator("tr[data-dataset=test_drive_abc]")
    row.locator("[data-action=edit]").click()  # TN3b
    _heading(page, "Edit dataset test_drive_abc")
    page.click("#back")  # TN5a
    _heading(page, "^Datasets$")
    row.locator("[data-action=edit]").click()
    page.click("#update")  # TN5b
    _heading(page, "^Datasets$")
    row.locator("[data-action=delete]").click()  # TN3c (i)
    expect(page.locator("#modal")).to_be_visible()
    page.click("#modal-close")  # TN3c (ii)
    expect(page.locator("#modal")).to_be_hidden()
    row.locator("[data-action=delete]").click()
    page.click("#modal-ok")  # TN3c (iii)
    _heading(page, "^Datasets$")
    expect(page.locator("#datasets tr[data-dataset=test_drive_abc]")).to_have_count(0)
    page.locator("tr[data-dataset=tub_1_26-01-01] [data-action=train]").click()  # TN3d
    _heading(page, "Training setup")
    expect(page.locator("#train-datasets input:checked")).to_have_count(1)

    page.click("nav >> text=Models")
    mrow = page.locator("tr[data-model=drive_1_1]")
    mrow.locator("[data-action=edit]").click()  # TN8a
    _heading(page, "Model drive_1_1")
    page.click("#back")  # TN9a
    _heading(page, "^Models$")
    mrow.locator("[data-action=edit]").click()
    page.click("#update")  # TN9b
    _heading(page, "^Models$")
    mrow.locator("[data-action=delete]").click()  # TN8b (i)
    expect(page.locator("#modal")).to_be_visible()
    page.click("#modal-close")  # TN8b (ii)
    expect(page.locator("#modal")).to_be_hidden()
    expect(mrow).to_have_count(1)
    mrow.locator("[data-action=delete]").click()
    page.click("#modal-ok")  # TN8b (iii)
    _heading(page, "^Models$")
    expect(page.locator("tr[data-model=drive_1_1]")).to_have_count(0)


# -- TO: operations ------------------------------------------------------------------------------------
def test_to_datasets(page, url, car, console):
    _open(page, url, "datasets")
    # TO1: every dataset of the database (the tubs of data/ are found and registered)
    names = {d.name for d in console.db.datasets()}
    assert names == {"tub_1_26-01-01", "tub_2_26-01-02"}
    expect(page.locator("#datasets tbody tr")).to_have_count(2)
    for name in names:
        expect(page.locator(f"tr[data-dataset='{name}'] .ds-name")).to_have_text(name)
    expect(page.locator("tr[data-dataset=tub_1_26-01-01] td").nth(3)).to_contain_text("60")
    expect(page.locator("tr[data-dataset=tub_1_26-01-01] .thumbs img")).to_have_count(6)
    # TO2a: the folder name field offers the dataset folders
    page.click("#add-dataset")
    options = page.locator("#dataset-folders option")
    expect(options).to_have_count(2)
    assert sorted(options.evaluate_all("os => os.map(o => o.value)")) == sorted(names)
    # TO2b: a new entry, and a new folder on disk
    page.fill("input[name=name]", "race")
    page.fill("input[name=label]", "2")
    page.fill("textarea[name=comment]", "Almost always stayed in centre")
    page.click("#submit")
    expect(page.locator("tr[data-dataset=race] .ds-label")).to_have_text("2")
    expect(page.locator("tr[data-dataset=race] .ds-comment")).to_have_text("Almost always stayed in centre")
    assert (car / "data" / "race").is_dir()  # a new folder: the tub appears there with its first record
    # TO3a: the edit form holds the stored values; TO3b: updated in the table and renamed on disk
    page.locator("tr[data-dataset=race] [data-action=edit]").click()
    expect(page.locator("input[name=name]")).to_have_value("race")
    expect(page.locator("input[name=label]")).to_have_value("2")
    expect(page.locator("textarea[name=comment]")).to_have_value("Almost always stayed in centre")
    page.fill("input[name=name]", "race_smooth")
    page.fill("input[name=label]", "3")
    page.click("#update")
    expect(page.locator("tr[data-dataset=race_smooth] .ds-label")).to_have_text("3")
    assert (car / "data" / "race_smooth").is_dir() and not (car / "data" / "race").exists()
    # TO4: deleted: gone from the table (soft: the tub's own deletes), then removed from the disk
    page.locator("tr[data-dataset=tub_2_26-01-02] [data-action=delete]").click()
    page.click("#modal-ok")
    expect(page.locator("#datasets tr[data-dataset=tub_2_26-01-02]")).to_have_count(0)
    assert Tub(car / "data" / "tub_2_26-01-02", read_only=True).manifest.deleted_indexes == set(range(40))
    page.locator("#deleted-datasets tr[data-dataset=tub_2_26-01-02] [data-action=restore]").click()
    expect(page.locator("#datasets tr[data-dataset=tub_2_26-01-02]")).to_have_count(1)
    assert not Tub(car / "data" / "tub_2_26-01-02", read_only=True).manifest.deleted_indexes
    page.locator("tr[data-dataset=race_smooth] [data-action=delete]").click()
    page.click("#modal-ok")
    page.locator("#deleted-datasets tr[data-dataset=race_smooth] [data-action=purge]").click()
    page.click("#modal-ok")
    expect(page.locator("tr[data-dataset=race_smooth]")).to_have_count(0)
    assert not (car / "data" / "race_smooth").exists()


def test_dataset_page_marks_a_range_deleted_and_restores_it(page, url, car, console):
    import os
    import time

    console.datasets.sync()
    tub = car / "data" / "tub_1_26-01-01"
    past = time.time() - 60
    for p in tub.iterdir():
        os.utime(p, (past, past))
    entry = next(e for e in console.db.datasets() if e.name == tub.name)
    _open(page, url, f"datasets/{entry.id}")
    page.wait_for_function("document.querySelector('#series-chart')._uplot !== undefined")
    assert page.evaluate("document.querySelector('#series-chart')._uplot.data[0].length") == 60
    expect(page.locator("#frame-img")).to_have_attribute("src", re.compile(r"images/0$"))
    # drag over the chart to choose a range
    box = page.locator("#series-chart .u-over").bounding_box()
    page.mouse.move(box["x"] + box["width"] * 0.25, box["y"] + 20)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] * 0.5, box["y"] + 20, steps=5)
    page.mouse.up()
    start = int(page.input_value("input[name=start]"))
    end = int(page.input_value("input[name=end]"))
    assert 10 <= start < end <= 35
    page.click("#delete-range")
    expect(page.locator("main .stat").nth(1).locator("b")).to_have_text(str(end - start + 1))
    assert Tub(tub, read_only=True).manifest.deleted_indexes == set(range(start, end + 1))
    for p in tub.iterdir():
        os.utime(p, (past, past))
    page.fill("input[name=start]", str(start))
    page.fill("input[name=end]", str(end))
    page.click("#restore-range")
    expect(page.locator("main .stat").nth(1).locator("b")).to_have_text("0")
    page.fill("input[name=start]", "50")
    page.fill("input[name=end]", "70")
    page.click("#delete-range")
    expect(page.locator("#range-form [data-err=end]")).to_contain_text("numbered 0 to 59")


def test_to_models(page, url, car, registered_model, console):
    registered_model("drive_1_1", 0.4)
    registered_model("drive_1_2", 0.3)
    _open(page, url, "models")
    # TO7: every model of the db
    expect(page.locator("#models tbody tr")).to_have_count(2)
    expect(page.locator("tr[data-model=drive_1_1] td").nth(2)).to_contain_text("tub_1_26-01-01")
    expect(page.locator("tr[data-model=drive_1_1] td").nth(4)).to_contain_text("flip 0.5")
    # TO8a: the edit page holds the name, the comment, the origin datasets and the parameters
    page.locator("tr[data-model=drive_1_1] [data-action=edit]").click()
    expect(page.locator("input[name=name]")).to_have_value("drive_1_1")
    expect(page.locator("#model-info")).to_contain_text("tub_1_26-01-01")
    expect(page.locator("#model-info")).to_contain_text("lr 0.001")
    page.wait_for_function("document.querySelector('#model-curves')._uplot.data[0].length === 3")
    # TO8b: updated in the table, renamed on disk (the registry `vehicle models` reads too)
    page.fill("input[name=name]", "decent_driver")
    page.fill("textarea[name=comment]", "Works well on track 1")
    page.click("#update")
    expect(page.locator("tr[data-model=decent_driver] .model-comment")).to_have_text("Works well on track 1")
    assert (car / "models" / "decent_driver.pt").is_file() and not (car / "models" / "drive_1_1.pt").exists()
    assert console.db.get("decent_driver").comment == "Works well on track 1"
    # a comment set with `vehicle models comment` shows in the console
    from vehicle.app.cli import main

    assert main(["models", "comment", "drive_1_2", "from the CLI", "--car", str(car)]) == 0
    page.reload()
    expect(page.locator("tr[data-model=drive_1_2] .model-comment")).to_have_text("from the CLI")
    # TO9: deleted from the table and from the disk
    page.locator("tr[data-model=decent_driver] [data-action=delete]").click()
    page.check("#delete-files")  # the files go only when asked (issue 27)
    page.click("#modal-ok")
    expect(page.locator("tr[data-model=decent_driver]")).to_have_count(0)
    assert not (car / "models" / "decent_driver.pt").exists()


def test_to5a_training_setup_loads_the_car_defaults(page, url):
    _open(page, url, "train")
    expect(page.locator("#hp-batch_size")).to_have_value("8")  # myconfig.py: BATCH_SIZE = 8
    expect(page.locator("#hp-epochs")).to_have_value("3")  # MAX_EPOCHS = 3
    expect(page.locator("#hp-learning_rate")).to_have_value("0.001")  # the package default
    expect(page.locator("#hp-val_share")).to_have_value("0.2")  # 1 - TRAIN_TEST_SPLIT
    expect(page.locator("input[name=model_type][value=linear]")).to_be_checked()
    for name in ("3d", "behavior", "categorical", "inferred", "memory", "pilotnet", "rnn"):
        expect(page.locator(f"#model-types [data-type='{name}'] li").first).to_be_visible()
    expect(page.locator("#model-types [data-type=behavior]")).to_contain_text("behavior/one_hot_state_array")


# -- TV: validation --------------------------------------------------------------------------------------
TV3 = [  # field, normal, extreme, erroneous (Track Driver AI's table)
    ("balance_bins", "25", "100", "-21"),
    ("max_per_bin", "400", "1500", "True"),
    ("val_share", "0.2", "1", "3.5"),
    ("aug_flip_p", "0.5", "1", "yes"),
    ("batch_size", "100", "1", "0"),
    ("learning_rate", "0.001", "100", "foo"),
    ("epochs", "10", "1", "-3"),
    ("steps_per_epoch", "300", "1", "bar"),
    ("val_steps", "200", "1", "-30"),
]


def test_tv3_training_setup_validation(page, url):
    _open(page, url, "train?datasets=1")
    for name, normal, extreme, bad in TV3:
        err = page.locator(f"[data-err={name}]")
        page.fill(f"#hp-{name}", bad)
        expect(err).not_to_be_empty()
        expect(page.locator(f"#hp-{name}")).to_have_class(re.compile("invalid"))
        page.fill(f"#hp-{name}", normal)
        expect(err).to_be_empty()
        page.fill(f"#hp-{name}", extreme)
        expect(err).to_be_empty()
    # erroneous values are refused by the server on submit too, with the reason next to the field
    page.fill("#hp-learning_rate", "foo")
    page.fill("#hp-epochs", "-3")
    page.click("#start-training")
    expect(page.locator("[data-err=learning_rate]")).to_have_text(
        "must be a number > 0 (got 'foo'): a step of size 0 or less never learns")
    expect(page.locator("[data-err=epochs]")).to_contain_text("training needs at least one epoch")
    _heading(page, "Training setup")


def test_tv3_the_cli_refuses_what_the_console_refuses(car, capsys):
    from vehicle.app.cli import main

    assert main(["train", "--car", str(car), "--lr", "foo", "--epochs", "-3"]) == 2
    err = capsys.readouterr().err
    assert "--lr foo: must be a number > 0 (got 'foo'): a step of size 0 or less never learns" in err
    assert "--epochs -3: must be a whole number ≥ 1 (got '-3'): training needs at least one epoch" in err


@pytest.mark.parametrize("label,ok", [("2", True), ("3", True), ("abc", True), ("x" * 61, False)])
def test_tv1_add_dataset_validation(page, url, car, label, ok):
    _open(page, url, "datasets/add")
    page.fill("input[name=name]", "")
    page.click("#submit")
    expect(page.locator("[data-err=name]")).to_contain_text("must not be empty")  # TV1a erroneous
    page.fill("input[name=name]", "tub_1_26-01-01" if label == "2" else "test_drive_abc")  # in / not in data/
    page.fill("input[name=label]", label)
    page.click("#submit")
    if ok:
        _heading(page, "^Datasets$")
    else:
        expect(page.locator("[data-err=label]")).to_contain_text("at most 60 characters")


def test_tv2_tv4_edit_validation(page, url, registered_model, console):
    registered_model("drive_1_1")
    console.datasets.sync()
    _open(page, url, "datasets/1/edit")
    page.fill("input[name=name]", "")
    page.click("#update")
    expect(page.locator("[data-err=name]")).to_contain_text("must not be empty")  # TV2a erroneous
    page.fill("input[name=name]", "test_drive_abc")
    page.fill("input[name=label]", "1")
    page.click("#update")
    _heading(page, "^Datasets$")
    # TV4: model names (Track Driver AI's .h5 names become file names as they are, with .pt after them)
    for name, ok in (("", False), ("decent_driver.h5", True), ("b_2_3-3_123.h5", True)):
        current = console.db.names()[0]
        _open(page, url, f"models/{current}/edit")
        page.fill("input[name=name]", name)
        page.click("#update")
        if ok:
            _heading(page, "^Models$")
            expect(page.locator(f"tr[data-model='{name}']")).to_have_count(1)
        else:
            expect(page.locator("[data-err=name]")).to_contain_text("must not be empty")


# -- a real training, watched from two browsers, reloaded, cancelled -------------------------------------
@pytest.mark.slow
def test_training_from_the_wizard_live_two_browsers_reload_cancel(page_factory, url, car, console):
    a = _open(page_factory(), url, "datasets")
    a.locator("[data-select]").nth(0).check()
    a.locator("[data-select]").nth(1).check()
    a.click("#train-selected")  # "train on this" with two datasets
    _heading(a, "Training setup")
    expect(a.locator("#train-datasets input:checked")).to_have_count(2)
    expect(a.locator("#aug-preview")).to_have_attribute("src", re.compile("^blob:"))  # the live preview grid
    a.fill("#hp-epochs", "100000")  # never reached: the cancel must find it running
    a.fill("#hp-batch_size", "4")
    a.fill("#hp-steps_per_epoch", "1")
    a.fill("#hp-val_steps", "1")
    a.select_option("#hp-early_stop", "false")
    a.fill("#model-name", "live_run")
    a.click("#start-training")  # TN6
    _heading(a, "^Training$")  # "result" once it has one
    # epochs drawn (0 while the page is still loading)
    points = "((document.querySelector('#loss-chart') || {})._uplot?.data[1] || []).filter(v => v != null).length"
    a.wait_for_function(f"{points} >= 2", timeout=120000)
    expect(a.locator("#run-status")).to_contain_text("running")  # points arrive while it runs
    expect(a.locator("#stat-sps")).not_to_have_text("–")
    expect(a.locator("#run-log")).to_contain_text("training linear model")
    # a second browser sees the same run and its new epochs
    b = page_factory(390, 844)
    b.goto(a.url)
    b.wait_for_function(f"{points} >= 2")
    seen = b.evaluate(points)
    b.wait_for_function(f"{points} > {seen}", timeout=60000)
    # a reload keeps the curve and the log
    a.reload()
    a.wait_for_function(f"{points} >= {seen}")
    expect(a.locator("#run-log")).to_contain_text("epoch 1/100000")
    # cancel from the second browser: both see it end, the best model so far is kept
    b.click("#cancel-run")
    b.click("#modal-ok")
    for p in (a, b):
        expect(p.locator("#run-status")).to_contain_text("cancelled", timeout=60000)
        expect(p.locator("#run-result")).to_contain_text("the best model so far was kept")
        _heading(p, "^Training result$")
    epochs_done = a.evaluate(points)
    assert 2 <= epochs_done < 100000
    a.click("#finish")  # TN7
    _heading(a, "^Models$")
    expect(a.locator("tr[data-model=live_run] td").nth(1)).to_have_text("linear")  # TO6c
    entry = ModelDB.for_models_dir(car / "models").get("live_run")
    assert entry.exists and entry.metrics["cancelled"] is True
    assert entry.parameters["batch_size"] == 4 and entry.parameters["steps_per_epoch"] == 1  # TO5b
    assert len(entry.metrics["train_loss"]) == entry.metrics["epochs"] >= 2
    assert sorted(Path(d).name for d in entry.datasets) == ["tub_1_26-01-01", "tub_2_26-01-02"]
    assert (car / "models" / "live_run.loss.png").is_file()


@pytest.mark.slow
def test_evaluation_from_the_model_manager(page, url, car, registered_model):
    registered_model("eval_me")
    _open(page, url, "models/eval_me")
    expect(page.locator("#no-evaluations")).to_be_visible()
    expect(page.locator("#evaluate-form input[name=tracks]")).to_have_value("101")
    page.fill("#evaluate-form input[name=laps]", "0")
    page.click("#evaluate")
    expect(page.locator("#evaluate-form [data-err=laps]")).to_contain_text("from 1 to 20")
    page.fill("#evaluate-form input[name=laps]", "1")
    page.click("#evaluate")
    _heading(page, "Evaluation")
    expect(page.locator("#run-status")).to_contain_text("done", timeout=120000)
    expect(page.locator("#run-result .stat").first).to_contain_text("score")  # what ranks it, then driven %
    expect(page.locator("#run-result .stat").nth(2)).to_contain_text("autonomy")
    page.click("#finish")
    _heading(page, "Model eval_me")
    card = page.locator(".evaluation").first
    expect(card).to_contain_text("Tracks 101")
    expect(card.locator("img.eval-pic")).to_be_visible()
    assert page.evaluate("document.querySelector('.eval-pic').naturalWidth") > 100
    [ev] = ModelDB.for_models_dir(car / "models").evaluations("eval_me")
    assert ev.tracks == (101,) and ev.laps == 1 and 0.0 <= ev.overall["autonomy"] <= 100.0


def _report(autonomy, cte, laps=1, seeds=(101, 102)):
    overall = {"autonomy": autonomy, "mean_abs_cte": cte, "laps_completed": laps, "mean_speed": 1.0,
               "interventions": 0}
    return {"seeds": list(seeds), "laps": 1, "overall": overall, "settings": {},
            "tracks": [{"seed": s, "autonomy": autonomy, "trajectory": [[0, 0]]} for s in seeds]}


def test_leaderboard_order(page, url, registered_model, console):
    for name in ("slow", "best", "wobbly", "other_tracks"):
        registered_model(name)
    reg = console.db
    reg.add_evaluation("slow", _report(80.0, 0.10))
    reg.add_evaluation("best", _report(50.0, 0.30))
    reg.add_evaluation("best", _report(100.0, 0.20, laps=2))  # the latest evaluation counts
    reg.add_evaluation("wobbly", _report(100.0, 0.25, laps=2))
    reg.add_evaluation("other_tracks", _report(100.0, 0.01, seeds=(7,)))
    _open(page, url, "leaderboard?tracks=101,102")
    rows = page.locator("#leaderboard tbody tr")
    expect(rows).to_have_count(3)
    assert rows.evaluate_all("rs => rs.map(r => r.dataset.model)") == ["best", "wobbly", "slow"]
    expect(rows.first.locator("td").nth(4)).to_have_text("100.0 %")  # autonomy, after score and driven
    page.select_option("#track-set", "tracks=7&laps=1")
    expect(page.locator("#leaderboard tbody tr")).to_have_count(1)
    expect(page.locator("#leaderboard tbody tr").first).to_have_attribute("data-model", "other_tracks")


def test_a_pilot_that_stood_still_reads_score_0_everywhere(page, url, registered_model, console):
    """Item 22: autonomy 100 % with none of its laps driven reads score 0 and 0 % driven beside it
    in the models table, the evaluation card and the leaderboard, whose caption says the score ranks."""
    for name in ("still", "drove"):
        registered_model(name)
    still = _report(100.0, 0.0, laps=0)
    still["overall"].update(completion=0.0, score=0.0)
    drove = _report(90.0, 0.1, laps=2)
    drove["overall"].update(completion=1.0, score=90.0)
    console.db.add_evaluation("still", still)
    console.db.add_evaluation("drove", drove)
    _open(page, url, "models")
    expect(page.locator("#models tr[data-model=still] td").nth(6)).to_have_text(
        "score 0.0 · driven 0 % · autonomy 100.0 % on 101,102")
    _open(page, url, "models/still")
    stats = page.locator(".evaluation .stat")
    assert stats.evaluate_all("ss => ss.slice(0, 3).map(s => s.textContent)") == [
        "0.0score", "0 %driven", "100.0 %autonomy"]
    _open(page, url, "leaderboard?tracks=101,102")
    rows = page.locator("#leaderboard tbody tr")
    assert rows.evaluate_all("rs => rs.map(r => r.dataset.model)") == ["drove", "still"]
    heads = page.locator("#leaderboard thead th").evaluate_all("hs => hs.map(h => h.textContent)")
    assert heads[:6] == ["#", "Model", "Score", "Driven", "Autonomy", "Laps"]
    assert rows.nth(1).locator("td").evaluate_all("ds => ds.slice(2, 5).map(d => d.textContent)") == [
        "0.0", "0 %", "100.0 %"]
    caption = page.locator("#leaderboard-rank").inner_text()
    assert caption.startswith("Models ranked by their latest evaluation on the same tracks: score first (autonomy")
    assert "autonomy first" not in caption


@pytest.mark.slow
def test_the_loss_chart_moves_within_an_epoch(page, url, console):
    """The running loss of the batches is drawn as it comes: a long epoch does not leave the chart empty;
    a reload keeps those points."""
    import json
    import urllib.request

    with urllib.request.urlopen(f"{url}api/datasets", timeout=30) as resp:
        ids = [d["id"] for d in json.loads(resp.read())]
    body = {"datasets": ids, "name": "slow_epochs",
            "hyper": {"epochs": "100000", "batch_size": "1", "early_stop": "false"}}
    req = urllib.request.Request(f"{url}api/jobs/train", data=json.dumps(body).encode(), method="POST",
                                 headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=30) as resp:
        job = json.loads(resp.read())
    _open(page, url, f"runs/{job['id']}")
    within = ("(() => { const d = (document.querySelector('#loss-chart') || {})._uplot?.data;"
              " return d ? d[0].filter((x, i) => d[3][i] != null && !Number.isInteger(x)).length : 0; })()")
    page.wait_for_function(f"{within} >= 3", timeout=120000)
    seen = page.evaluate(within)
    page.reload()
    page.wait_for_function(f"{within} >= {seen}")
    expect(page.locator("#loss-chart .u-legend")).to_contain_text("running loss")
    req = urllib.request.Request(f"{url}api/jobs/{job['id']}/cancel", method="POST")
    urllib.request.urlopen(req, timeout=30).close()
    expect(page.locator("#run-status")).to_contain_text("cancelled", timeout=60000)


def test_a_recipe_preset_fills_the_form_and_none_gives_the_car_back(page, url):
    _open(page, url, "train")
    page.select_option("#recipe", "udacity-bc")
    expect(page.locator("#hp-epochs")).to_have_value("10")  # model.fit(epochs=10)
    expect(page.locator("#hp-batch_size")).to_have_value("32")  # Keras's default batch
    expect(page.locator("#hp-flip_copy")).to_have_value("true")  # every image and its mirror
    expect(page.locator("#hp-split_by")).to_have_value("random")
    expect(page.locator("input[name=model_type][value=pilotnet]")).to_be_checked()
    expect(page.locator("#hp-augmentations input:checked")).to_have_count(0)
    expect(page.locator("#recipe-note")).to_contain_text("320x160")
    page.select_option("#recipe", "")
    expect(page.locator("#hp-epochs")).to_have_value("3")  # the car's MAX_EPOCHS again
    expect(page.locator("input[name=model_type][value=linear]")).to_be_checked()
