"""Background batch prefetching and DataLoader workers."""

from __future__ import annotations

import threading

import pytest

from training.prefetch import Prefetcher
from training.trainer import train
from vehicle.config import Config


def test_prefetcher_yields_everything_in_order():
    with Prefetcher(range(50), depth=3) as p:
        assert list(p) == list(range(50))


def test_prefetcher_forwards_errors_and_stops_early():
    def broken():
        yield 1
        raise RuntimeError("bad frame")

    p = Prefetcher(broken())
    assert next(p) == 1
    with pytest.raises(RuntimeError, match="bad frame"):
        next(p)
    p.close()
    endless = Prefetcher(iter(int, 1), depth=2)  # an infinite source
    assert next(endless) == 0
    endless.close()
    assert not any(t.name == "batch-prefetch" and t.is_alive() for t in threading.enumerate())
    with pytest.raises(ValueError, match="depth"):
        Prefetcher([], depth=0)


def test_training_with_dataloader_workers(tiny_tub, tmp_path, torch_one_thread):
    cfg = Config.defaults(BATCH_SIZE=32, MAX_EPOCHS=2, TRAIN_SEED=0)
    metrics = train(cfg, [tiny_tub], tmp_path / "w.pt", workers=1, register=False)
    assert metrics["epoch_samples"] == [96, 96]


def test_workers_see_each_epochs_augmentation_draws(tiny_tub):
    import numpy as np
    import torch

    from parts.pilots.preprocess import Preprocess
    from training.augment import Augmenter, AugmentSettings
    from training.dataset import PilotDataset, build_samples, read_drive_data
    from training.distributed import DistInfo
    from training.fit import plain_plan
    from training.framecache import FrameCache
    from training.trainer import PreparedData, _loaders

    data = read_drive_data([tiny_tub])
    cache = FrameCache(data.records, ["cam/image_array"])
    cache.fill(np.arange(len(data)))
    aug = Augmenter(AugmentSettings(names=("brightness",), brightness_p=1.0))
    ds = PilotDataset(data, build_samples(data, np.arange(8)), cache, Preprocess(), augmenter=aug)
    prep = PreparedData(data, ds, None, Preprocess(), (64, 64, 3), {})
    loader, _ = _loaders(prep, 8, 1, DistInfo(), plain_plan(torch.device("cpu")), seed=0)
    batches = []
    for epoch in range(2):
        ds.set_epoch(epoch)
        batches.append(next(iter(loader))[0])
    # the batch holds all 8 samples (shuffled): equal sums would mean the same brightness draws
    assert batches[0].double().sum() != batches[1].double().sum()
