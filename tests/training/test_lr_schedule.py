"""TRAIN_LR_SCHEDULE: a constant learning rate, or one cycle (warm-up, then a cosine to ~0) over the run."""

from __future__ import annotations

import pytest
import torch

from parts.pilots.modelfile import load_model
from training.fit import FitSettings, make_scheduler
from training.trainer import train
from vehicle.config import Config, ConfigError


def _lrs(settings: FitSettings, steps: int) -> list[float]:
    param = torch.nn.Parameter(torch.zeros(1))
    optimizer = torch.optim.Adam([param], lr=settings.learning_rate)
    scheduler = make_scheduler(optimizer, settings, steps)
    seen = []
    for _ in range(steps):
        seen.append(optimizer.param_groups[0]["lr"])
        optimizer.step()
        if scheduler is not None:
            scheduler.step()
    return seen


def test_constant_keeps_the_learning_rate():
    assert _lrs(FitSettings(learning_rate=0.002), 10) == [0.002] * 10


def test_one_cycle_warms_up_to_the_learning_rate_then_anneals_to_about_zero():
    lrs = _lrs(FitSettings(learning_rate=0.002, lr_schedule="one_cycle", warmup=0.2), 100)
    assert lrs[0] == pytest.approx(0.002 / 25)  # starts at a 25th
    peak = max(range(100), key=lrs.__getitem__)
    assert 18 <= peak <= 21 and lrs[peak] == pytest.approx(0.002, rel=1e-3)  # the peak after 20 % of the steps
    assert all(a <= b for a, b in zip(lrs[:peak], lrs[1:peak + 1], strict=True))  # rises, then
    assert all(a >= b for a, b in zip(lrs[peak:], lrs[peak + 1:], strict=False))  # only falls
    assert lrs[-1] < 0.002 / 1000  # ~0 at the last step


def test_an_unknown_schedule_is_refused():
    with pytest.raises(ValueError, match="TRAIN_LR_SCHEDULE = 'step'"):
        _lrs(FitSettings(lr_schedule="step"), 3)
    with pytest.raises(ConfigError, match="TRAIN_LR_SCHEDULE"):
        Config.defaults(TRAIN_LR_SCHEDULE="step")
    with pytest.raises(ConfigError, match="TRAIN_WARMUP"):
        Config.defaults(TRAIN_WARMUP=1.0)


def test_training_with_one_cycle_runs_the_whole_cycle_and_records_it(tiny_tub, tmp_path, torch_one_thread):
    cfg = Config.defaults(CAR_PATH=str(tmp_path), BATCH_SIZE=8, USE_EARLY_STOP=False, SHOW_PLOT=False,
                          AUGMENTATIONS=[], TRAIN_LR_SCHEDULE="one_cycle", TRAIN_WARMUP=0.3,
                          TRAIN_STEPS_PER_EPOCH=3)
    metrics = train(cfg, [tiny_tub], tmp_path / "m.pt", epochs=2, register=False)
    assert metrics["epochs"] == 2 and metrics["epoch_samples"] == [24, 24]  # OneCycleLR stepped 6 of 6 times
    training = load_model(tmp_path / "m.pt")[1]["training"]
    assert training["lr_schedule"] == "one_cycle" and training["warmup"] == 0.3
