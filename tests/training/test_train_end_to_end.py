"""train(): data -> model file with metrics, loss plot and database entry; early stop; transfer; CLIs."""

from __future__ import annotations

import argparse
import json

import pytest
import torch

from parts.pilots.modelfile import ModelFileError, load_model
from training.distributed import resolve_device
from training.trainer import train
from vehicle.app.commands.train import add_train_arguments
from vehicle.config import Config

FAST = {"BATCH_SIZE": 16, "MAX_EPOCHS": 3, "AUGMENTATIONS": [], "TRAIN_SEED": 0}


def test_train_writes_model_metrics_plot_and_registry(tiny_tub, tmp_path, torch_one_thread):
    cfg = Config.defaults(**FAST, CAR_PATH=str(tmp_path))
    path = tmp_path / "models" / "pilot.pt"
    metrics = train(cfg, [tiny_tub], path, comment="first try")
    assert metrics["epochs"] == 3 and 1 <= metrics["best_epoch"] <= 3
    assert metrics["train_loss"][-1] < metrics["train_loss"][0]
    assert metrics["train_samples"] == 96 and metrics["val_samples"] == 24  # 0.8 / 0.2 of 120 records
    model, meta = load_model(path)
    assert meta["type"] == "linear" and meta["model"]["input_shape"] == [3, 64, 64]
    assert meta["datasets"] == [str(tiny_tub)]
    assert meta["preprocess"]["image_shape"] == [64, 64, 3]
    assert meta["training"]["batch_size"] == 16 and meta["training"]["learning_rate"] == 1e-3
    assert meta["metrics"]["best_val_loss"] == pytest.approx(min(metrics["val_loss"]))
    saved = json.loads((tmp_path / "models" / "pilot.metrics.json").read_text())
    assert saved["val_loss"] == pytest.approx(metrics["val_loss"]) and saved["type"] == "linear"
    png = (tmp_path / "models" / "pilot.loss.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    from training.model_db import ModelDB

    entry = ModelDB.for_models_dir(tmp_path / "models").get("pilot")
    assert entry.type == "linear" and entry.comment == "first try"


@pytest.mark.parametrize("name", ["categorical", "behavior", "rnn", "lanes"])
def test_other_types_train_through_the_whole_pipeline(name, tiny_tub, tmp_path, torch_one_thread):
    cfg = Config.defaults(**{**FAST, "MAX_EPOCHS": 1, "SEQUENCE_LENGTH": 2})
    train(cfg, [tiny_tub], tmp_path / "m.pt", model_type_name=name, register=False)
    model, meta = load_model(tmp_path / "m.pt")
    assert meta["type"] == name
    if name in ("behavior", "lanes"):
        assert model.num_behaviors == 2  # read from the records' one-hot arrays
    if name == "lanes":  # the lane image is made by the preprocessing, stored with the model
        assert meta["preprocess"]["lanes"]["s_threshold"] == [65, 255]
        assert meta["preprocess"]["normalize"] == "unit" and model.input_shape[0] == 4
    if name == "rnn":
        assert model.frames == 2


def test_early_stopping_stops_after_patience(tiny_tub, tmp_path, torch_one_thread):
    # min_delta larger than any loss: only the first epoch counts as an improvement
    cfg = Config.defaults(**{**FAST, "MAX_EPOCHS": 10, "EARLY_STOP_PATIENCE": 2, "MIN_DELTA": 100.0})
    metrics = train(cfg, [tiny_tub], tmp_path / "m.pt", register=False)
    assert metrics["epochs"] == 3 and metrics["stopped_early"]
    # the model kept is the lowest validation loss, even where it fell by less than MIN_DELTA
    losses = metrics["val_loss"]
    assert metrics["best_epoch"] == 1 + losses.index(min(losses))


def test_the_best_model_is_the_lowest_loss_while_patience_needs_min_delta():
    from training.fit import Patience

    # the demo's validation losses (MIN_DELTA 0.0005): epoch 6 is the best model although it beat
    # epoch 2 by less than MIN_DELTA; patience ran out after epoch 7 (5 epochs without a real drop)
    watch = Patience(0.0005)
    kept = [watch.update(v) for v in (0.00705, 0.00196, 0.00273, 0.00198, 0.00193, 0.00169, 0.00181)]
    assert kept == [True, True, False, False, True, True, False]
    assert watch.best == 0.00169 and watch.waited == 5
    assert watch.update(0.0011) and watch.waited == 0  # a real drop resets the wait


def test_transfer_continues_from_an_earlier_model(tiny_tub, tmp_path, torch_one_thread):
    cfg = Config.defaults(**{**FAST, "MAX_EPOCHS": 1})
    train(cfg, [tiny_tub], tmp_path / "old.pt", model_type_name="inferred", register=False)
    old, _ = load_model(tmp_path / "old.pt")
    # a learning rate of ~0 keeps the weights: the new model starts from the old one
    train(cfg, [tiny_tub], tmp_path / "new.pt", transfer=tmp_path / "old.pt", learning_rate=1e-12,
          register=False)
    new, meta = load_model(tmp_path / "new.pt")
    assert meta["type"] == "inferred" and meta["transfer"] == str(tmp_path / "old.pt")
    for (k, a), b in zip(old.state_dict().items(), new.state_dict().values(), strict=True):
        assert torch.allclose(a, b, atol=1e-6), k
    with pytest.raises(ValueError, match="is a 'inferred' model but --type linear"):
        train(cfg, [tiny_tub], tmp_path / "x.pt", transfer=tmp_path / "old.pt", model_type_name="linear")
    (tmp_path / "bad.pt").write_bytes(b"junk")
    with pytest.raises(ModelFileError):
        train(cfg, [tiny_tub], tmp_path / "x.pt", transfer=tmp_path / "bad.pt")


def test_bad_arguments_are_explained(tiny_tub, tmp_path):
    cfg = Config.defaults(**FAST)
    with pytest.raises(ValueError, match=r"must end in \.pt"):
        train(cfg, [tiny_tub], tmp_path / "m.h5")
    with pytest.raises(ValueError, match="unknown model type"):
        train(cfg, [tiny_tub], tmp_path / "m.pt", model_type_name="resnet")
    with pytest.raises(ValueError, match="MAX_EPOCHS = 0 is out of range; valid: at least 1"):
        train(cfg, [tiny_tub], tmp_path / "m.pt", epochs=0)
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="no CUDA GPU"):
            resolve_device("cuda")


def test_progress_bar_shows_live_loss_when_asked(tiny_tub, tmp_path, capsys, torch_one_thread):
    cfg = Config.defaults(**{**FAST, "MAX_EPOCHS": 1, "SHOW_PLOT": False})
    train(cfg, [tiny_tub], tmp_path / "m.pt", register=False, progress=True)
    err = capsys.readouterr().err
    assert "epoch 1/1" in err and "loss=" in err
    train(cfg, [tiny_tub], tmp_path / "m.pt", register=False)  # not a terminal: no bar
    assert "epoch 1/1" not in capsys.readouterr().err


def test_manage_py_and_vehicle_train_share_arguments(tiny_tub, tmp_path, capsys, torch_one_thread):
    from vehicle.app.cli import main
    from vehicle.app.commands.train import train_car as assembly_train

    (tmp_path / "data").mkdir()
    parser = argparse.ArgumentParser()
    add_train_arguments(parser)
    args = parser.parse_args(["--tubs", str(tiny_tub), "--model", str(tmp_path / "a.pt"), "--epochs", "1",
                              "--batch-size", "32", "--aug", "--no-register"])
    cfg = Config.defaults(CAR_PATH=str(tmp_path))
    assert assembly_train(cfg, args) == 0
    assert load_model(tmp_path / "a.pt")[1]["training"]["batch_size"] == 32
    assert main(["train", "--car", str(tmp_path), "--tubs", str(tiny_tub), "--model", str(tmp_path / "b.pt"),
                 "--epochs", "1", "--type", "inferred", "--aug", "flip", "--no-register"]) == 0
    assert "saved" in capsys.readouterr().out
    meta = load_model(tmp_path / "b.pt")[1]
    assert meta["type"] == "inferred" and meta["training"]["augmentations"]["names"] == ["flip"]
    assert main(["train", "--car", str(tmp_path), "--tubs", str(tiny_tub), "--model", str(tmp_path / "c.pt"),
                 "--type", "lstm"]) == 2
    assert "--type lstm: must be one of 3d, behavior, categorical" in capsys.readouterr().err


def test_training_without_validation_split_monitors_training_loss(tiny_tub, tmp_path, torch_one_thread):
    cfg = Config.defaults(**{**FAST, "MAX_EPOCHS": 2, "TRAIN_TEST_SPLIT": 1.0})
    metrics = train(cfg, [tiny_tub], tmp_path / "m.pt", register=False)
    assert metrics["val_samples"] == 0 and metrics["train_samples"] == 120
    assert metrics["best_epoch"] >= 1 and metrics["best_loss"] == pytest.approx(min(metrics["train_loss"]))
    saved = json.loads((tmp_path / "m.metrics.json").read_text())
    assert saved["val_loss"] == [None, None]  # NaN is not JSON: written as null


def test_ctrl_c_ends_a_command_line_training_with_its_best_model_registered(tiny_tub, tmp_path, capsys,
                                                                           torch_one_thread):
    # acceptance: Ctrl-C in `manage.py train` said "vehicle stopped by Ctrl-C: throttle set to
    # neutral" and left a model without its metrics, plot or database entry
    import os
    import signal
    import threading
    import time

    from training.model_db import ModelDB
    from vehicle.app.cli import main

    model = tmp_path / "models" / "p.pt"

    def press_ctrl_c_after_the_first_saved_epoch() -> None:
        end = time.monotonic() + 120
        while not model.exists() and time.monotonic() < end:
            time.sleep(0.02)
        os.kill(os.getpid(), signal.SIGINT)

    presser = threading.Thread(target=press_ctrl_c_after_the_first_saved_epoch, daemon=True)
    presser.start()
    rc = main(["train", "--car", str(tmp_path), "--tubs", str(tiny_tub), "--model", str(model),
               "--epochs", "10000", "--no-early-stop", "--batch-size", "16"])
    presser.join()
    assert rc == 130
    out = capsys.readouterr().out
    assert "stopped by Ctrl-C in epoch " in out and ": saved " in out
    metrics = json.loads((tmp_path / "models" / "p.metrics.json").read_text())
    assert metrics["cancelled"] and 1 <= metrics["best_epoch"] < 10000
    assert ModelDB.for_models_dir(tmp_path / "models").get("p").type == "linear"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the handler is put back
