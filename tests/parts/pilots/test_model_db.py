"""The SQLite registry of trained models and the ``vehicle models`` command."""

from __future__ import annotations

import json
import sqlite3
from datetime import UTC, datetime

import pytest

from parts.pilots.model_db import DB_FILENAME, ModelRegistry, RegistryError, register_model
from vehicle.app.cli import main


@pytest.fixture
def car(tmp_path):
    """A car folder with an empty myconfig.py and a models folder."""
    (tmp_path / "myconfig.py").write_text("# overrides\n")
    (tmp_path / "models").mkdir()
    return tmp_path


def test_register_round_trip(car):
    reg = ModelRegistry.for_models_dir(car / "models")
    model = car / "models" / "pilot_a.pt"
    model.write_bytes(b"weights")
    tubs = [car / "data" / "tub_1", car / "data" / "tub_2"]
    entry = reg.register(model, model_type="linear", datasets=tubs,
                         parameters={"learning_rate": 1e-3, "epochs": 10}, metrics={"val_loss": 0.0123},
                         comment="first try", created=datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC))
    assert (car / "models" / DB_FILENAME).is_file()
    again = ModelRegistry(car / "models" / DB_FILENAME).get("pilot_a")
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
    reg = ModelRegistry.for_models_dir(car / "models")
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
    assert ModelRegistry.for_models_dir(car / "models").names() == ["p"]
    with pytest.raises(ValueError, match="model type is unknown"):
        register_model(car / "models" / "q.pt", {})


def test_lookup_errors_suggest_names(car):
    reg = ModelRegistry.for_models_dir(car / "models")
    with pytest.raises(RegistryError, match="registry is empty"):
        reg.get("anything")
    assert not (car / "models" / DB_FILENAME).exists()  # reading never creates the file
    reg.register(car / "models" / "speedy.pt", model_type="linear")
    with pytest.raises(RegistryError, match="Did you mean speedy"):
        reg.get("speedie")
    assert reg.get("speedy.pt").name == "speedy"
    assert reg.get(car / "models" / "speedy.pt").name == "speedy"


def test_remove_with_and_without_files(car):
    reg = ModelRegistry.for_models_dir(car / "models")
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


def test_not_a_registry_is_a_clear_error(car):
    (car / "models" / DB_FILENAME).write_text("this is not sqlite")
    with pytest.raises(RegistryError, match="is not a model registry"):
        ModelRegistry.for_models_dir(car / "models").list()


def test_cli_list_show_comment_rm(car, capsys):
    reg = ModelRegistry.for_models_dir(car / "models")
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
