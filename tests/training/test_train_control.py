"""Training under control: steps per epoch, validation steps, progress events, a clean stop that keeps
the best model so far (what the trainer console's worker relies on)."""

from __future__ import annotations

import pytest

from parts.pilots.modelfile import load_model
from training.model_db import ModelDB
from training.trainer import train
from vehicle.config import Config


@pytest.fixture
def cfg(tmp_path):
    return Config.defaults(CAR_PATH=str(tmp_path), BATCH_SIZE=8, USE_EARLY_STOP=False, SHOW_PLOT=False,
                           AUGMENTATIONS=[], TRAIN_NUM_WORKERS=0)


def test_steps_per_epoch_events_and_validation_steps(cfg, tiny_tub, tmp_path, torch_one_thread):
    events = []
    cfg = cfg.replace(TRAIN_STEPS_PER_EPOCH=2, TRAIN_VAL_STEPS=1)
    metrics = train(cfg, [tiny_tub], tmp_path / "m.pt", epochs=3, register=False, on_event=events.append)
    assert metrics["epoch_samples"] == [16, 16, 16]  # 2 steps of 8 samples per epoch
    kinds = [e["event"] for e in events]
    assert kinds[:4] == ["phase", "phase", "start", "phase"]
    assert [e["phase"] for e in events if e["event"] == "phase"] == ["reading", "preparing", "training"]
    start = next(e for e in events if e["event"] == "start")
    assert start["batches"] == 2 and start["epochs"] == 3 and start["train_samples"] > 16
    batches = [e for e in events if e["event"] == "batch"]
    assert [(b["epoch"], b["batch"]) for b in batches] == [(1, 1), (1, 2), (2, 1), (2, 2), (3, 1), (3, 2)]
    assert all(b["batches"] == 2 and b["samples_per_s"] > 0 for b in batches)
    epochs = [e for e in events if e["event"] == "epoch"]
    assert [e["epoch"] for e in epochs] == [1, 2, 3]
    assert [e["train_loss"] for e in epochs] == pytest.approx(metrics["train_loss"])
    assert load_model(tmp_path / "m.pt")[1]["training"]["steps_per_epoch"] == 2


def test_a_stop_request_keeps_the_best_model_so_far(cfg, tiny_tub, tmp_path, torch_one_thread):
    epochs_seen = []

    def on_event(event):
        if event["event"] == "epoch":
            epochs_seen.append(event["epoch"])

    model = tmp_path / "models" / "stopped.pt"
    metrics = train(cfg.replace(TRAIN_STEPS_PER_EPOCH=1), [tiny_tub], model, epochs=50, on_event=on_event,
                    should_stop=lambda: len(epochs_seen) >= 2)
    assert metrics["cancelled"] is True and metrics["epochs"] == 2 and epochs_seen == [1, 2]
    assert model.is_file() and load_model(model)[1]["metrics"]["cancelled"] is True
    entry = ModelDB.for_models_dir(model.parent).get("stopped")
    assert entry.metrics["cancelled"] is True and entry.metrics["best_epoch"] in (1, 2)


def test_a_stop_before_the_first_epoch_saves_nothing(cfg, tiny_tub, tmp_path, torch_one_thread):
    with pytest.raises(ValueError, match="cancelled before its first epoch ended: no model was saved"):
        train(cfg, [tiny_tub], tmp_path / "never.pt", epochs=5, register=False, should_stop=lambda: True)
    assert not (tmp_path / "never.pt").exists()


def test_the_config_is_checked_with_the_console_rules(cfg, tiny_tub, tmp_path):
    # the car's config refuses it with the console's bound (a form is checked by training.hyperparams)
    with pytest.raises(ValueError, match=r"TRAIN_BALANCE_BINS = 0 is out of range; valid: at least 1"):
        train(cfg.replace(TRAIN_BALANCE_BINS=0), [tiny_tub], tmp_path / "m.pt", register=False)


def test_a_validation_share_of_one_still_trains_on_one_block(cfg, tiny_tub, tmp_path, torch_one_thread):
    metrics = train(cfg.replace(TRAIN_TEST_SPLIT=0.0, TRAIN_STEPS_PER_EPOCH=1), [tiny_tub], tmp_path / "m.pt",
                    epochs=1, register=False)
    assert 0 < metrics["train_samples"] < metrics["val_samples"]


def test_a_stopped_run_keeps_the_model_the_user_had(cfg, tiny_tub, tmp_path, torch_one_thread):
    """Hardening item 27: Ctrl-C in epoch 2 of 3 replaced an existing models/pilot.pt with the
    interrupted run's best and reported "best epoch 1 of 1"."""
    model = tmp_path / "models" / "pilot.pt"
    cfg = cfg.replace(TRAIN_STEPS_PER_EPOCH=2)
    train(cfg, [tiny_tub], model, epochs=1, register=False)
    before = model.read_bytes()
    batches = []

    def on_event(event):
        if event["event"] == "batch":
            batches.append(event["epoch"])

    metrics = train(cfg, [tiny_tub], model, epochs=3, register=False, on_event=on_event,
                    should_stop=lambda: len(batches) >= 3)  # in epoch 2, after its first batch
    assert model.read_bytes() == before  # the user's model is kept
    interrupted = tmp_path / "models" / "pilot.interrupted.pt"
    assert metrics["model_file"] == str(interrupted) and metrics["kept_model"] == str(model)
    assert load_model(interrupted)[1]["metrics"]["cancelled"] is True
    assert (metrics["stopped_in_epoch"], metrics["epochs_planned"], metrics["epochs"], metrics["best_epoch"]) == \
        (2, 3, 1, 1)
    from training.train_report import train_summary

    said = train_summary(metrics, model)
    assert said.startswith(f"stopped by Ctrl-C in epoch 2 of 3: saved {interrupted} (best epoch 1, 1 of 3 epochs run")
    assert f"kept your {model} (a stopped run does not replace it)" in said
    finished = train(cfg, [tiny_tub], model, epochs=1, register=False)  # a finished run replaces it
    assert model.read_bytes() != before and finished["model_file"] == str(model) and finished["kept_model"] is None
