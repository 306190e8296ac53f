"""Training's progress where no bar can be drawn (output to a file or a pipe): a log line at a
steady interval between the epoch lines."""

from __future__ import annotations

import logging

import pytest


def _batch(step: int, epoch: int = 1) -> dict:
    return {"event": "batch", "epoch": epoch, "epochs": 10, "batch": step, "batches": 400, "loss": 0.25,
            "samples": 64 * step, "samples_per_s": 320.0}


def test_progress_is_logged_once_per_interval_and_forwarded(caplog):
    from training.progress_log import ProgressLog

    now = [0.0]
    seen = []
    log = ProgressLog(seen.append, every_s=30.0, clock=lambda: now[0])
    with caplog.at_level(logging.INFO, logger="training.progress_log"):
        for t, step in ((10, 1), (29, 2), (31, 3), (45, 4), (61, 5), (62, 6)):
            now[0] = t
            log(_batch(step))
        now[0] = 80
        log({"event": "epoch", "epoch": 1})  # an epoch line was just written: the interval restarts
        now[0] = 100
        log(_batch(1, epoch=2))
    lines = [r.getMessage() for r in caplog.records]
    assert lines == ["epoch 1/10: batch 3 of 400, loss 0.25000, 320 samples/s",
                     "epoch 1/10: batch 5 of 400, loss 0.25000, 320 samples/s"]
    assert len(seen) == 8  # every event still reaches the sink it wraps (the console's live view)


@pytest.mark.slow
def test_training_without_a_terminal_logs_progress_between_epochs(tiny_tub, tmp_path, caplog, monkeypatch,
                                                                  torch_one_thread):
    # issue 27: with output not a terminal, training printed nothing between epoch lines for minutes
    from training import progress_log
    from training.trainer import train
    from vehicle.config import Config

    monkeypatch.setattr(progress_log, "PROGRESS_LOG_S", 0.0)  # every step: no waiting in a test
    cfg = Config.defaults(CAR_PATH=str(tmp_path), SHOW_PLOT=False, BATCH_SIZE=16)
    with caplog.at_level(logging.INFO):
        train(cfg, [tiny_tub], tmp_path / "p.pt", epochs=1, progress=False, register=False)
    assert any(r.getMessage().startswith("epoch 1/1: batch 1 of ") for r in caplog.records), caplog.text
