"""The SQLite database of trained models and the ``vehicle models`` command."""

from __future__ import annotations

import hashlib
import json
import sqlite3
from datetime import UTC, datetime

import pytest

from training.model_db import DB_FILENAME, ModelChanged, ModelDB, ModelDBError, register_model
from vehicle.app.cli import main


@pytest.fixture
def car(tmp_path):
    """A car folder with an empty myconfig.py and a models folder."""
    (tmp_path / "myconfig.py").write_text("# overrides\n")
    (tmp_path / "models").mkdir()
    return tmp_path


def test_register_round_trip(car):
    reg = ModelDB.for_models_dir(car / "models")
    model = car / "models" / "pilot_a.pt"
    model.write_bytes(b"weights")
    tubs = [car / "data" / "tub_1", car / "data" / "tub_2"]
    entry = reg.register(model, model_type="linear", datasets=tubs,
                         parameters={"learning_rate": 1e-3, "epochs": 10}, metrics={"val_loss": 0.0123},
                         comment="first try", created=datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC))
    assert (car / "models" / DB_FILENAME).is_file()
    again = ModelDB(car / "models" / DB_FILENAME).get("pilot_a")
    assert again == entry
    assert again.path == model.resolve() and again.exists
    assert again.type == "linear"
    assert [p.split("/")[-1] for p in again.datasets] == ["tub_1", "tub_2"]
    assert again.parameters == {"epochs": 10, "learning_rate": 1e-3}
    assert again.metrics == {"val_loss": 0.0123}
    assert again.created == "2026-01-02T03:04:05+00:00"
    # stored relative to the models folder, so the car folder can move
    with sqlite3.connect(car / "models" / DB_FILENAME) as conn:
        assert conn.execute("SELECT path FROM models").fetchone()[0] == "pilot_a.pt"


def test_reregistering_replaces_the_entry_and_keeps_the_comment(car):
    reg = ModelDB.for_models_dir(car / "models")
    reg.register(car / "models" / "m.pt", model_type="linear", comment="keep me", metrics={"val_loss": 1.0})
    reg.register(car / "models" / "m.pt", model_type="categorical", metrics={"val_loss": 0.5})
    entries = reg.list()
    assert len(entries) == 1
    assert (entries[0].type, entries[0].metrics, entries[0].comment) == ("categorical", {"val_loss": 0.5},
                                                                         "keep me")


def test_register_model_reads_the_model_file_metadata(car):
    meta = {"type": "pilotnet", "datasets": [str(car / "data" / "tub_9")], "training": {"epochs": 3},
            "metrics": {"best_val_loss": 0.25}}
    entry = register_model(car / "models" / "p.pt", meta, comment="from training")
    assert entry.type == "pilotnet" and entry.parameters == {"epochs": 3}
    assert entry.comment == "from training"
    assert ModelDB.for_models_dir(car / "models").names() == ["p"]
    with pytest.raises(ValueError, match="model type is unknown"):
        register_model(car / "models" / "q.pt", {})


def test_lookup_errors_suggest_names(car):
    reg = ModelDB.for_models_dir(car / "models")
    with pytest.raises(ModelDBError, match="model database is empty"):
        reg.get("anything")
    assert not (car / "models" / DB_FILENAME).exists()  # reading never creates the file
    reg.register(car / "models" / "speedy.pt", model_type="linear")
    with pytest.raises(ModelDBError, match="Did you mean speedy"):
        reg.get("speedie")
    assert reg.get("speedy.pt").name == "speedy"
    assert reg.get(car / "models" / "speedy.pt").name == "speedy"


def test_remove_with_and_without_files(car):
    reg = ModelDB.for_models_dir(car / "models")
    for name in ("a", "b"):
        for suffix in (".pt", ".onnx", ".loss.png", ".metrics.json"):
            (car / "models" / f"{name}{suffix}").write_bytes(b"x")
        reg.register(car / "models" / f"{name}.pt", model_type="linear", datasets=[car / "data" / name])
    assert reg.remove("a") == []
    assert (car / "models" / "a.pt").exists()
    deleted = reg.remove("b", delete_files=True)
    assert sorted(p.name for p in deleted) == ["b.loss.png", "b.metrics.json", "b.onnx", "b.pt"]
    assert reg.list() == []
    with sqlite3.connect(car / "models" / DB_FILENAME) as conn:
        assert conn.execute("SELECT COUNT(*) FROM datasets").fetchone()[0] == 0  # orphans removed


def test_not_a_model_database_is_a_clear_error(car):
    (car / "models" / DB_FILENAME).write_text("this is not sqlite")
    with pytest.raises(ModelDBError, match="is not a model database"):
        ModelDB.for_models_dir(car / "models").list()


def test_cli_list_show_comment_rm(car, capsys):
    reg = ModelDB.for_models_dir(car / "models")
    (car / "models" / "fast.pt").write_bytes(b"x")
    reg.register(car / "models" / "fast.pt", model_type="linear", datasets=[car / "data" / "tub_1"],
                 metrics={"val_loss": 0.01234, "epochs": 7, "train_loss": [0.5, 0.2]})
    reg.register(car / "models" / "gone.pt", model_type="pilotnet")

    assert main(["models", "--car", str(car)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:3] == ["NAME", "TYPE", "CREATED"]
    assert lines[1].split()[:2] == ["fast", "linear"]
    assert "tub_1" in lines[1] and "val_loss=0.01234" in lines[1] and "epochs=7" in lines[1]
    assert "train_loss" not in lines[1]  # lists stay out of the table
    assert lines[2].startswith("gone (missing)")

    assert main(["models", "comment", "fast", "good on track 3", "--car", str(car)]) == 0
    capsys.readouterr()
    assert main(["models", "show", "fast", "--car", str(car)]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["comment"] == "good on track 3" and shown["type"] == "linear" and shown["exists"]

    assert main(["models", "--car", str(car), "list", "--json"]) == 0
    assert [m["name"] for m in json.loads(capsys.readouterr().out)] == ["fast", "gone"]

    assert main(["models", "rm", "gone", "--car", str(car)]) == 0
    assert reg.names() == ["fast"]
    assert main(["models", "show", "nope", "--car", str(car)]) == 2
    assert "no model 'nope'" in capsys.readouterr().err


def test_cli_empty_registry_and_bad_car(tmp_path, capsys):
    assert main(["models", "--car", str(tmp_path)]) == 0
    assert "no models registered" in capsys.readouterr().out
    assert main(["models", "--car", str(tmp_path / "nowhere")]) == 2
    assert "no such folder" in capsys.readouterr().err


# -- schema 2: migration, datasets, evaluations, rename (the console shares this database) ---------------
_V1 = """
CREATE TABLE models (id INTEGER PRIMARY KEY AUTOINCREMENT, name TEXT NOT NULL UNIQUE, path TEXT NOT NULL,
    type TEXT NOT NULL, parameters TEXT NOT NULL DEFAULT '{}', metrics TEXT NOT NULL DEFAULT '{}', comment TEXT,
    transfer TEXT, created TEXT NOT NULL);
CREATE TABLE datasets (id INTEGER PRIMARY KEY AUTOINCREMENT, path TEXT NOT NULL UNIQUE);
CREATE TABLE model_datasets (model_id INTEGER NOT NULL REFERENCES models(id) ON DELETE CASCADE,
    dataset_id INTEGER NOT NULL REFERENCES datasets(id) ON DELETE CASCADE, PRIMARY KEY (model_id, dataset_id));
INSERT INTO models (name, path, type, parameters, metrics, comment, created)
    VALUES ('old', 'old.pt', 'linear', '{"epochs": 4}', '{"best_val_loss": 0.2}', 'kept', '2025-01-01T00:00:00+00:00');
INSERT INTO datasets (path) VALUES ('/cars/c/data/tub_1');
INSERT INTO model_datasets VALUES (1, 1);
PRAGMA user_version = 1;
"""


def test_a_schema_1_registry_is_upgraded_in_place(car):
    db = car / "models" / DB_FILENAME
    with sqlite3.connect(db) as conn:
        conn.executescript(_V1)
    reg = ModelDB(db)
    [entry] = reg.list()
    assert (entry.name, entry.comment, entry.parameters, entry.datasets) == ("old", "kept", {"epochs": 4},
                                                                              ("/cars/c/data/tub_1",))
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 3
        cols = {r[1] for r in conn.execute("PRAGMA table_info(datasets)")}
        assert {"label", "comment", "added", "origin", "deleted", "kept_deleted"} <= cols
        assert "sha256" in {r[1] for r in conn.execute("PRAGMA table_info(models)")}
        assert conn.execute("SELECT count(*) FROM evaluations").fetchone()[0] == 0
    assert entry.sha256 is None  # registered before hashes were kept: nothing to check it against
    (car / "models" / "old.pt").write_bytes(b"whatever is there")
    assert reg.check_file(car / "models" / "old.pt") == entry  # an old entry never refuses its file
    assert reg.datasets() == []  # a training reference is not a managed dataset
    ModelDB(db).list()  # opening again changes nothing


_V2 = _V1.replace("PRAGMA user_version = 1;", """ALTER TABLE datasets ADD COLUMN label TEXT;
ALTER TABLE datasets ADD COLUMN comment TEXT; ALTER TABLE datasets ADD COLUMN added TEXT;
ALTER TABLE datasets ADD COLUMN origin TEXT; ALTER TABLE datasets ADD COLUMN deleted TEXT;
ALTER TABLE datasets ADD COLUMN kept_deleted TEXT;
CREATE TABLE evaluations (id INTEGER PRIMARY KEY AUTOINCREMENT, model_id INTEGER NOT NULL REFERENCES models(id)
    ON DELETE CASCADE, tracks TEXT NOT NULL, laps INTEGER NOT NULL, created TEXT NOT NULL,
    overall TEXT NOT NULL DEFAULT '{}', per_track TEXT NOT NULL DEFAULT '[]', settings TEXT NOT NULL DEFAULT '{}',
    picture BLOB);
PRAGMA user_version = 2;""")


def test_a_schema_2_database_gets_the_hash_column_and_hashes_what_is_registered_after(car):
    db = car / "models" / DB_FILENAME
    with sqlite3.connect(db) as conn:
        conn.executescript(_V2)
    (car / "models" / "new.pt").write_bytes(b"new weights")
    reg = ModelDB(db)
    assert [e.sha256 for e in reg.list()] == [None]
    entry = reg.register(car / "models" / "new.pt", model_type="linear")
    assert entry.sha256 == hashlib.sha256(b"new weights").hexdigest()
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 3


def test_the_hash_is_recorded_at_registration_and_checked(car):
    reg = ModelDB.for_models_dir(car / "models")
    model = car / "models" / "m.pt"
    model.write_bytes(b"weights one")
    entry = reg.register(model, model_type="linear")
    assert entry.sha256 == hashlib.sha256(b"weights one").hexdigest()
    assert reg.get("m").sha256 == entry.sha256 and reg.get("m").as_dict()["sha256"] == entry.sha256
    assert reg.check_file(model) == entry  # untouched: checked and accepted
    assert reg.check_file(car / "models" / "other.pt") is None  # not registered: nothing to check
    model.write_bytes(b"weights two")  # another file under the same name
    with pytest.raises(ModelChanged) as err:
        reg.check_file(model)
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"{model.resolve()}: changed since it was registered as model 'm'")
    assert "vehicle models rehash m" in message
    # the rename keeps the hash (the same bytes under a new name)
    model.write_bytes(b"weights one")
    assert reg.rename("m", "n").sha256 == entry.sha256
    # registered before the file was written: no hash to compare yet
    assert reg.register(car / "models" / "later.pt", model_type="linear").sha256 is None


def test_rehash_accepts_the_file_as_it_is_now(car, capsys):
    reg = ModelDB.for_models_dir(car / "models")
    model = car / "models" / "m.pt"
    model.write_bytes(b"weights one")
    reg.register(model, model_type="linear", comment="kept")
    model.write_bytes(b"weights two")
    assert main(["models", "rehash", "m", "--car", str(car)]) == 0
    assert "m: the model database now holds the SHA-256 of" in capsys.readouterr().out
    entry = reg.check_file(model)
    assert entry.sha256 == hashlib.sha256(b"weights two").hexdigest() and entry.comment == "kept"
    model.unlink()
    assert main(["models", "rehash", "m", "--car", str(car)]) == 2
    assert f"model m: its file {model.resolve()} is missing" in capsys.readouterr().err


def test_a_newer_schema_is_refused(car):
    db = car / "models" / DB_FILENAME
    with sqlite3.connect(db) as conn:
        conn.executescript(_V1.replace("user_version = 1", "user_version = 9"))
    with pytest.raises(ModelDBError, match="newer version"):
        ModelDB(db).list()


def _report(autonomy, cte, seeds=(1, 2), laps=1, completed=2):
    return {"seeds": list(seeds), "laps": laps, "settings": {"dt": 0.05},
            "overall": {"autonomy": autonomy, "mean_abs_cte": cte, "laps_completed": completed, "mean_speed": 1.0},
            "tracks": [{"seed": s, "autonomy": autonomy, "trajectory": [[0.0, 0.0]] * 3, "off_track_at": []}
                       for s in seeds]}


def test_evaluations_and_the_leaderboard(car):
    reg = ModelDB.for_models_dir(car / "models")
    for name in ("a", "b", "c"):
        reg.register(car / "models" / f"{name}.pt", model_type="linear")
    reg.add_evaluation("a", _report(90.0, 0.2), picture=b"\x89PNG...")
    reg.add_evaluation("b", _report(90.0, 0.1))
    reg.add_evaluation("c", _report(100.0, 0.5, completed=1))
    reg.add_evaluation("c", _report(20.0, 0.5, seeds=(2, 1)))  # latest on the same tracks (order ignored)
    reg.add_evaluation("a", _report(100.0, 0.0, seeds=(7,)))
    assert [e.model for e in reg.leaderboard([2, 1])] == ["b", "a", "c"]
    assert [e.model for e in reg.leaderboard([7])] == ["a"]
    assert reg.leaderboard([1, 2], laps=3) == []
    ev = reg.evaluations("a")[1]
    assert ev.tracks == (1, 2) and ev.has_picture and reg.evaluation_picture(ev.id) == b"\x89PNG..."
    assert "trajectory" not in ev.per_track[0] and ev.per_track[0]["autonomy"] == 90.0
    assert reg.track_sets() == [((1, 2), 1, 3), ((7,), 1, 1)]
    # a pilot that stood still (100 % autonomy, none of its laps) ranks below every one that drove
    reg.register(car / "models" / "still.pt", model_type="linear")
    still = _report(100.0, 0.0, completed=0)
    still["overall"].update(completion=0.0, score=0.0)
    reg.add_evaluation("still", still)
    assert [e.model for e in reg.leaderboard([2, 1])] == ["b", "a", "c", "still"]
    reg.remove("still")
    # retraining a model to the same name drops its evaluations (they judged other weights)
    reg.register(car / "models" / "c.pt", model_type="linear")
    assert reg.evaluations("c") == []
    reg.remove("a")
    assert [e.model for e in reg.evaluations()] == ["b"]


def test_rename_moves_the_files_and_keeps_everything_else(car):
    reg = ModelDB.for_models_dir(car / "models")
    for suffix in (".pt", ".onnx", ".loss.png"):
        (car / "models" / f"m{suffix}").write_bytes(suffix.encode())
    reg.register(car / "models" / "m.pt", model_type="linear", comment="c", datasets=[car / "data" / "t"])
    reg.add_evaluation("m", _report(50.0, 0.1))
    entry = reg.rename("m", "better.pt")
    assert entry.name == "better" and entry.path == (car / "models" / "better.pt").resolve()
    assert sorted(p.name for p in (car / "models").glob("better*")) == ["better.loss.png", "better.onnx", "better.pt"]
    assert not list((car / "models").glob("m.*"))
    assert entry.comment == "c" and len(entry.datasets) == 1 and len(reg.evaluations("better")) == 1
    reg.register(car / "models" / "x.pt", model_type="linear")
    with pytest.raises(ModelDBError, match="already registered"):
        reg.rename("better", "x")
    with pytest.raises(ModelDBError, match="must not be empty"):
        reg.rename("better", "")
    with pytest.raises(ModelDBError, match="letters, digits"):
        reg.rename("better", "../escape")
    (car / "models" / "taken.onnx").write_bytes(b"someone else's")
    with pytest.raises(ModelDBError, match="taken.onnx exists"):
        reg.rename("better", "taken")
    assert (car / "models" / "better.pt").is_file()  # nothing moved
    assert main(["models", "rename", "better", "best", "--car", str(car)]) == 0
    assert reg.names() == ["best", "x"]


def test_managed_datasets_survive_the_removal_of_their_models(car):
    reg = ModelDB.for_models_dir(car / "models")
    tub = car / "data" / "tub_1"
    reg.register(car / "models" / "m.pt", model_type="linear", datasets=[tub, car / "data" / "tub_2"])
    managed = reg.add_dataset(tub, "found", label="3")
    assert [d.id for d in reg.datasets()] == [managed.id] and reg.models_of_dataset(managed.id) == ["m"]
    reg.remove("m")
    assert [d.path for d in reg.datasets()] == [tub.resolve()]
    with sqlite3.connect(reg.db_path) as conn:  # the bare reference of tub_2 went with its model
        assert conn.execute("SELECT count(*) FROM datasets").fetchone()[0] == 1
    moved = reg.update_dataset(managed.id, path=car / "data" / "renamed", comment="x")
    assert moved.name == "renamed" and moved.comment == "x" and moved.label == "3"
    reg.forget_dataset(managed.id)
    assert reg.datasets() == []


def test_the_models_leaderboard_command(car, capsys):
    reg = ModelDB.for_models_dir(car / "models")
    reg.register(car / "models" / "a.pt", model_type="linear")
    reg.add_evaluation("a", _report(75.5, 0.123, seeds=(101, 102, 103)))
    assert main(["models", "leaderboard", "--car", str(car)]) == 0
    out = capsys.readouterr().out
    assert "tracks 101,102,103" in out and "75.5%" in out and "0.123 m" in out
    assert main(["models", "leaderboard", "--car", str(car), "--tracks", "5"]) == 0
    assert "no evaluations on tracks 5; evaluated track sets: --tracks 101,102,103 --laps 1" in capsys.readouterr().out
    assert main(["models", "--car", str(car)]) == 0
    assert "autonomy 75.5% on 101,102,103" in capsys.readouterr().out  # stored before the score: no score shown


def test_a_pilot_that_stood_still_reads_score_0_in_the_models_table_and_the_leaderboard(car, capsys):
    """Item 22: autonomy 100 % with none of its laps driven shows score 0 and 0 % driven beside it."""
    reg = ModelDB.for_models_dir(car / "models")
    for name in ("still", "drove"):
        (car / "models" / f"{name}.pt").write_bytes(name.encode())
        reg.register(car / "models" / f"{name}.pt", model_type="linear")
    still = _report(100.0, 0.0, seeds=(101,), completed=0)
    still["overall"].update(completion=0.0, score=0.0, interventions=0)
    drove = _report(90.0, 0.1, seeds=(101,), completed=1)
    drove["overall"].update(completion=1.0, score=90.0, interventions=1)
    reg.add_evaluation("still", still)
    reg.add_evaluation("drove", drove)
    assert main(["models", "--car", str(car)]) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[1:]}
    assert "score 0.0, driven 0%, autonomy 100.0% on 101" in rows["still"]
    assert "score 90.0, driven 100%, autonomy 90.0% on 101" in rows["drove"]
    assert main(["models", "leaderboard", "--car", str(car), "--tracks", "101"]) == 0
    header, first, second = capsys.readouterr().out.splitlines()[1:]
    assert header.split()[:6] == ["#", "MODEL", "SCORE", "DRIVEN", "AUTONOMY", "LAPS"]
    assert first.split()[:6] == ["1", "drove", "90.0", "100%", "90.0%", "1"]
    assert second.split()[:6] == ["2", "still", "0.0", "0%", "100.0%", "0"]
