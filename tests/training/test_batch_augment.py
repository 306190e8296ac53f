"""Batch-tensor augmentations (training.batch_augment): shape, dtype, seeding, what each one changes,
settings, and that training applies them to training batches only."""

from __future__ import annotations

import pytest
import torch

from training.augment import BATCH_AUGMENTATIONS, Augmenter, AugmentSettings
from training.batch_augment import BatchAugmenter
from training.trainer import train
from vehicle.config import Config


def only(name: str, seed: int = 0, **kw) -> BatchAugmenter:
    """One batch augmentation, always applied (p = 1)."""
    return BatchAugmenter(AugmentSettings(names=(name,), **{f"{name}_p": 1.0, **kw}), seed)


def batch(n: int = 8, h: int = 12, w: int = 16, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.randint(40, 216, (n, 3, h, w), generator=g, dtype=torch.uint8)


@pytest.mark.parametrize("name", BATCH_AUGMENTATIONS)
def test_shape_dtype_and_seeded_draws(name):
    x = batch()
    a, b = only(name, seed=3), only(name, seed=3)
    y = a(x)
    assert y.shape == x.shape and y.dtype == torch.uint8 and y.device == x.device
    assert not torch.equal(y, x), f"{name} with p=1 changed nothing"
    assert torch.equal(b(x), y)  # same seed, same epoch: the same draws
    b.set_epoch(2)
    assert not torch.equal(b(x), y)  # another epoch draws anew
    b.set_epoch(0)
    assert torch.equal(b(x), y)
    assert torch.equal(x, batch())  # the input is never changed


@pytest.mark.parametrize("name", BATCH_AUGMENTATIONS)
def test_probability_zero_changes_nothing(name):
    x = batch()
    assert torch.equal(BatchAugmenter(AugmentSettings(names=(name,), **{f"{name}_p": 0.0}))(x), x)


def test_light_moves_brightness_by_the_drawn_amount():
    x = torch.full((64, 3, 4, 4), 128, dtype=torch.uint8)
    y = only("light", light_contrast=0.0, light_curve=0.0, light_brightness=0.2)(x).float()
    shift = y.mean(dim=(1, 2, 3)) - 128.0
    assert shift.abs().max() <= 0.2 * 255 + 1 and shift.abs().max() > 0.1 * 255  # up to +-20 % of full scale
    assert (shift > 0).any() and (shift < 0).any()
    assert (y.std(dim=(1, 2, 3)) == 0).all()  # a flat frame stays flat: brightness only
    black_white = torch.tensor([0, 255], dtype=torch.uint8).repeat(8, 3, 1, 1)
    curved = only("light", light_contrast=0.0, light_brightness=0.0, light_curve=1.0)(black_white)
    assert torch.equal(curved, black_white)  # the tone curve keeps black and white


def test_colour_keeps_grey_and_turns_colours():
    grey = torch.full((16, 3, 4, 4), 100, dtype=torch.uint8)
    assert (only("colour")(grey).int() - 100).abs().max() <= 1  # hue and saturation leave grey alone
    red = torch.zeros((16, 3, 4, 4), dtype=torch.uint8)
    red[:, 0] = 200
    y = only("colour", colour_saturation=0.0, colour_hue=90.0)(red).float()
    assert (y[:, 1:].amax(dim=(1, 2, 3)) > 20).any()  # some red turned towards green or blue
    luma = lambda t: (0.299 * t[:, 0] + 0.587 * t[:, 1] + 0.114 * t[:, 2]).mean(dim=(1, 2))  # noqa: E731
    brown = torch.tensor([150, 110, 90], dtype=torch.uint8).view(1, 3, 1, 1).repeat(16, 1, 4, 4)
    sat = only("colour", colour_hue=0.0, colour_saturation=0.5)(brown).float()
    assert (luma(sat) - luma(brown.float())).abs().max() < 1  # saturation keeps the luma (unclipped)
    spread = (sat.amax(dim=1) - sat.amin(dim=1)).mean(dim=(1, 2))  # 60 before: x0.5 .. x1.5
    assert spread.min() >= 29 and spread.max() <= 91 and (spread < 55).any() and (spread > 65).any()


def test_noise_adds_zero_mean_noise_up_to_sigma():
    x = torch.full((32, 3, 24, 32), 128, dtype=torch.uint8)
    y = only("noise", noise_sigma=10.0)(x).float()
    std = y.std(dim=(1, 2, 3))
    assert std.max() <= 11 and std.max() > 3
    assert (y.mean(dim=(1, 2, 3)) - 128).abs().max() < 1.5


def test_cutout_fills_one_flat_rectangle_shared_by_the_frames_of_a_sample():
    x = batch(n=4, h=20, w=20).unsqueeze(1).repeat(1, 3, 1, 1, 1)  # (N, T, C, H, W): 3 equal frames
    y = only("cutout", cutout_size=0.5)(x)
    assert y.shape == x.shape
    changed = (y != x).any(dim=2)  # (N, T, H, W)
    assert changed.any(dim=(1, 2, 3)).all()  # every sample got its rectangle
    assert torch.equal(changed[:, 0], changed[:, 2]) and torch.equal(y[:, 0], y[:, 1])  # one draw per sample
    for n in range(4):
        rows, cols = changed[n, 0].nonzero(as_tuple=True)
        box = y[n, 0, :, rows.min():rows.max() + 1, cols.min():cols.max() + 1]
        assert (box == box[:, :1, :1]).all()  # a flat grey box
        assert rows.max() - rows.min() + 1 <= 10 and cols.max() - cols.min() + 1 <= 10  # at most half a side


def test_batch_augmenter_refuses_non_rgb_batches():
    with pytest.raises(ValueError, match="RGB"):
        only("light")(torch.zeros((2, 1, 4, 4), dtype=torch.uint8))
    with pytest.raises(TypeError, match="uint8"):
        only("light")(torch.zeros((2, 3, 4, 4)))


def test_settings_validation_and_split_between_frame_and_batch():
    for bad in ({"light_curve": 1.5}, {"colour_hue": 200.0}, {"noise_sigma": -1.0}, {"cutout_size": 2.0},
                {"light_p": 1.2}):
        with pytest.raises(ValueError, match="AUG_"):
            AugmentSettings(**bad)
    s = AugmentSettings(names=("flip", "light", "noise"), flip_p=1.0, light_p=1.0, noise_p=1.0)
    assert [n for n, _ in Augmenter(s).draw(__import__("numpy").random.default_rng(0))] == ["flip"]
    assert BatchAugmenter(s).names == ("light", "noise") and not BatchAugmenter(AugmentSettings(names=("flip",)))
    cfg = Config.defaults()
    assert AugmentSettings.from_config(cfg, ["cutout"]).cutout_size == cfg.AUG_CUTOUT_SIZE == 0.3


def test_training_applies_batch_augmentations_to_training_batches_only(tiny_tub, tmp_path, torch_one_thread,
                                                                       monkeypatch):
    seen: list[int] = []
    real = BatchAugmenter.__call__

    def counting(self, x):
        seen.append(len(x))
        return real(self, x)

    monkeypatch.setattr(BatchAugmenter, "__call__", counting)
    cfg = Config.defaults(BATCH_SIZE=32, MAX_EPOCHS=2, TRAIN_SEED=0)
    metrics = train(cfg, [tiny_tub], tmp_path / "a.pt", register=False, augmentations=["light", "cutout"])
    assert sum(seen) == sum(metrics["epoch_samples"])  # every training sample, no validation sample
    seen.clear()
    train(cfg.replace(PREPROCESS_COLOR="yuv"), [tiny_tub], tmp_path / "b.pt", register=False,
          augmentations=["light"])
    assert seen == []  # RGB-only augmentations are left out of a YUV model
