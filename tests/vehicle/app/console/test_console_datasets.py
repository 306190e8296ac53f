"""The console's datasets: discovery, statistics, soft delete and restore, renames, record ranges."""

from __future__ import annotations

import os
import time

import pytest

from parts.tub.tub import Tub
from training.model_db import ModelDB
from vehicle.app.console.datasets import DatasetError, DatasetStore


@pytest.fixture
def store(config):
    return DatasetStore(config, ModelDB.for_models_dir(config.path("MODELS_PATH")))


def _age(path, seconds=60):
    """Make a tub look as if its last recording ended ``seconds`` ago (edits wait for a recording)."""
    past = time.time() - seconds
    for p in path.iterdir():
        os.utime(p, (past, past))


def test_sync_finds_the_tubs_of_the_data_folder_with_their_statistics(store, car):
    entries = store.sync()
    assert [e.name for e in entries] == ["tub_1_26-01-01", "tub_2_26-01-02"]
    assert {e.origin for e in entries} == {"found"}
    s = store.summary(entries[0])["stats"]
    assert (s["records"], s["deleted_records"], s["sessions"]) == (60, 0, 2)
    assert s["duration_s"] == pytest.approx(59 * 0.05, abs=0.05)  # timestamps 50 ms apart
    # angles go linearly from -1 to 1: every histogram bin holds about 60 / 21 records
    assert sum(s["histogram"]) == 60 and min(s["histogram"]) >= 2
    assert len(s["thumbnails"]) == 6 and s["thumbnails"][0] == 0 and s["thumbnails"][-1] == 59
    assert s["size_bytes"] > 60 * 1000
    assert store.sync() == entries  # idempotent


def test_soft_delete_keeps_earlier_record_deletes_on_restore(store, car):
    entry = store.sync()[0]
    _age(entry.path)
    store.mark_records(entry.id, 10, 14, delete=True)
    _age(entry.path)
    store.soft_delete(entry.id)
    assert Tub(entry.path, read_only=True).manifest.deleted_indexes == set(range(60))
    assert store.get(entry.id).deleted is not None
    assert store.summary(store.get(entry.id))["stats"]["records"] == 0
    _age(entry.path)
    store.restore(entry.id)
    assert Tub(entry.path, read_only=True).manifest.deleted_indexes == set(range(10, 15))
    assert store.get(entry.id).deleted is None


def test_purge_needs_a_soft_delete_first_and_removes_the_folder(store, car):
    entry = store.sync()[1]
    _age(entry.path)
    with pytest.raises(DatasetError, match="not deleted yet"):
        store.purge(entry.id)
    store.soft_delete(entry.id)
    _age(entry.path)
    store.purge(entry.id)
    assert not entry.path.exists()
    assert [e.name for e in store.sync()] == ["tub_1_26-01-01"]


def test_rename_moves_the_folder_and_keeps_model_links(store, car, config):
    entry = store.sync()[0]
    db = store.db
    model = config.path("MODELS_PATH") / "m.pt"
    db.register(model, model_type="linear", datasets=[entry.path])
    _age(entry.path)
    renamed = store.edit(entry.id, name="oval_laps", label="3", comment="smooth")
    assert renamed.path == car / "data" / "oval_laps" and renamed.path.is_dir()
    assert not (car / "data" / "tub_1_26-01-01").exists()
    assert (renamed.label, renamed.comment) == ("3", "smooth")
    assert db.get("m").datasets == (str(renamed.path),)
    with pytest.raises(DatasetError, match="exists already"):
        store.edit(entry.id, name="tub_2_26-01-02")
    with pytest.raises(DatasetError, match="must not be empty"):
        store.edit(entry.id, name="")


def test_a_tub_being_recorded_into_is_left_alone(store, car):
    entry = store.sync()[0]
    (entry.path / "catalog_0.catalog").touch()  # written just now
    with pytest.raises(DatasetError, match="recording into it"):
        store.soft_delete(entry.id)


def test_create_an_empty_tub_or_register_an_existing_one(store, car, tmp_path, config):
    created = store.create("test_drive_abc", label="2", comment="to record into")
    # a folder to record into: the tub appears with its first record (never one DonkeyCar cannot open)
    assert created.origin == "created" and list((car / "data" / "test_drive_abc").iterdir()) == []
    stats = store.summary(created)["stats"]
    assert stats["records"] == 0 and stats["inputs"] == list(config.TUB_INPUTS)
    # an existing tub of the data folder by name: registered as it is (Track Driver AI's "in the folder")
    again = store.create("tub_2_26-01-02", label="1")
    assert again.path == (car / "data" / "tub_2_26-01-02").resolve() and again.label == "1"
    # a tub elsewhere, by path
    from fixtures.tubs import build_donkey_tub

    build_donkey_tub(tmp_path / "elsewhere" / "old_tub", 5)
    [outside] = store.register(str(tmp_path / "elsewhere"))
    assert outside.origin == "registered" and store.summary(outside)["in_data_folder"] is False
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match="holds no tub"):
        store.register(str(tmp_path / "empty"))
    for bad in ("", "a/b", "../up", ".hidden"):
        with pytest.raises(DatasetError):
            store.create(bad)


def test_record_ranges_are_checked(store, car):
    entry = store.sync()[1]
    _age(entry.path)
    with pytest.raises(DatasetError, match="numbered 0 to 39"):
        store.mark_records(entry.id, 30, 40, delete=True)
    with pytest.raises(DatasetError, match="after end"):
        store.mark_records(entry.id, 5, 2, delete=True)
    out = store.mark_records(entry.id, 0, 9, delete=True)
    assert out["dataset"]["stats"]["records"] == 30
    series = store.series(store.get(entry.id))
    assert series["deleted"][:10] == [True] * 10 and not any(series["deleted"][10:])
    assert series["angle"][0] == -1.0 and series["angle"][-1] == 1.0


def test_udacity_import(store, car, tmp_path):
    import cv2
    import numpy as np

    src = tmp_path / "udacity"
    (src / "IMG").mkdir(parents=True)
    lines = []
    for i in range(4):
        name = f"center_2026_01_01_10_00_0{i}_000.jpg"
        cv2.imwrite(str(src / "IMG" / name), np.full((160, 320, 3), 40 * i, np.uint8))
        lines.append(f"{src / 'IMG' / name}, , ,{i / 10},0.5,0,{i}")
    (src / "driving_log.csv").write_text("\n".join(lines) + "\n")
    entry = store.import_udacity(str(src), "udacity_1", label="lake")
    assert entry.origin == "udacity" and entry.label == "lake"
    assert store.summary(entry)["stats"]["records"] == 4
    with pytest.raises(DatasetError, match="exists already"):
        store.import_udacity(str(src), "udacity_1")
    with pytest.raises(DatasetError, match="no such file"):
        store.import_udacity(str(tmp_path / "nothing"), "udacity_2")
