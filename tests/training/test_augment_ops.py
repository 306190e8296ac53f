"""Augmentations: each operation, its steering correction, probabilities, and the preview grid."""

from __future__ import annotations

import numpy as np
import pytest

from training.augment import Augmenter, AugmentSettings, preview_grid
from vehicle.config import Config


def _only(name: str, **kw) -> Augmenter:
    return Augmenter(AugmentSettings(names=(name,), **{f"{name}_p": 1.0, **kw}))


@pytest.fixture
def image() -> np.ndarray:
    img = np.full((60, 80, 3), 60, np.uint8)
    img[:, 10:20] = 250  # a bright bar on the left
    return img


def test_flip_mirrors_and_negates_steering(image):
    out, angle = _only("flip")(image, 0.4, np.random.default_rng(0))
    assert np.array_equal(out, image[:, ::-1])
    assert angle == pytest.approx(-0.4)


def test_shift_moves_the_image_and_corrects_steering(image):
    aug = _only("shift", shift_x=0.1, shift_y=0.0, shift_steering=1.0)
    rng = np.random.default_rng(3)
    ops = aug.draw(rng)
    dx = ops[0][1]["dx"]
    out = aug.apply(image, ops)
    bar = np.flatnonzero(out[30, :, 0] > 200)
    assert bar.mean() == pytest.approx(14.5 + dx * 80, abs=1.0)  # moved by dx of the width
    # shifted right = the car is left of its path = steer right (+)
    assert aug.steering(0.1, ops) == pytest.approx(0.1 + dx)
    assert aug.steering(0.99, [("shift", {"dx": 0.1, "dy": 0.0})]) == 1.0  # clipped to [-1, 1]


def test_brightness_contrast_shadow_zoom_blur_change_pixels_not_steering(image):
    rng = np.random.default_rng(1)
    for name in ("brightness", "shadow", "zoom", "blur"):
        aug = _only(name)
        ops = aug.draw(rng)
        out = aug.apply(image, ops)
        assert out.shape == image.shape and out.dtype == np.uint8
        assert not np.array_equal(out, image), name
        assert aug.steering(0.3, ops) == pytest.approx(0.3), name
    shadow = _only("shadow", shadow_darkness=0.5)
    out = shadow.apply(image, [("shadow", {"top": 0.5, "bottom": 0.5, "side": 0.0, "factor": 0.5})])
    assert out[:, :40].max() == 125 and np.array_equal(out[:, 40:], image[:, 40:])
    bright = _only("brightness").apply(image, [("brightness", {"beta": 51.0, "alpha": 1.0})])
    assert int(bright[0, 0, 0]) == 111 and int(bright[0, 15, 0]) == 255  # +20 %, saturating


def test_hue_turns_colours_and_keeps_greys_and_steering():
    img = np.full((20, 30, 3), 90, np.uint8)
    img[:, :10] = (240, 200, 40)  # yellow tape on a grey floor
    aug = _only("hue")
    out = aug.apply(img, [("hue", {"degrees": 180.0})])
    r, g, b = (int(v) for v in out[5, 5])
    assert b > 200 and r < 90 and abs(g - 80) < 50  # yellow turned to blue
    assert np.array_equal(out[:, 10:], img[:, 10:])  # grey stays grey
    assert np.array_equal(aug.apply(img, [("hue", {"degrees": 0.0})]), img)
    ops = aug.draw(np.random.default_rng(2))
    assert ops[0][0] == "hue" and -180.0 <= ops[0][1]["degrees"] <= 180.0 and aug.steering(-0.2, ops) == -0.2
    with pytest.raises(ValueError, match="AUG_HUE_RANGE"):
        AugmentSettings(hue_range=200.0)


def test_probabilities_and_input_untouched(image):
    none = Augmenter(AugmentSettings(names=AugmentSettings().names, flip_p=0, brightness_p=0, shadow_p=0,
                                     shift_p=0))
    rng = np.random.default_rng(0)
    assert all(none.draw(rng) == [] for _ in range(20))
    half = _only("flip", flip_p=0.5)
    flips = sum(bool(half.draw(rng)) for _ in range(400))
    assert 150 < flips < 250
    copy = image.copy()
    _only("flip").apply(image, [("flip", {})])
    assert np.array_equal(image, copy)


def test_settings_from_config_and_validation():
    cfg = Config.defaults(AUGMENTATIONS=["zoom", "blur"], AUG_ZOOM_P=0.7)
    s = AugmentSettings.from_config(cfg)
    assert s.names == ("zoom", "blur") and s.zoom_p == 0.7
    assert AugmentSettings.from_config(cfg, []).names == ()
    with pytest.raises(ValueError, match="unknown augmentation"):
        AugmentSettings(names=("rotate",))
    with pytest.raises(ValueError, match="AUG_FLIP_P"):
        AugmentSettings(flip_p=1.5)


def test_preview_grid_layout(image):
    grid = preview_grid([image, image], [0.2, -0.5], _only("flip"), variants=3, scale=2)
    assert grid.shape == (2 * 120, 4 * 160, 3)
    # second column = flipped copy of the first (away from the text labels)
    assert np.array_equal(grid[40:80, 160 + 40:160 + 80], np.ascontiguousarray(grid[40:80, 80:120][:, ::-1]))


def test_preview_aug_command_writes_png(tiny_tub, tmp_path):
    import cv2

    from vehicle.app.cli import main

    out = tmp_path / "aug.png"
    assert main(["train", "preview-aug", "--tubs", str(tiny_tub), "--out", str(out), "--rows", "3",
                 "--variants", "4", "--car", str(tmp_path)]) == 0
    png = cv2.imread(str(out))
    assert png.shape == (3 * 128, 5 * 128, 3)


def test_every_augmentation_is_a_hyperparameter_choice():
    from training.augment import AUGMENTATION_NAMES
    from training.hyperparams import by_name

    assert by_name("augmentations").choices == AUGMENTATION_NAMES  # the console and the CLI offer what training does
    assert by_name("aug_hue_p").setting == "AUG_HUE_P" and by_name("aug_hue_range").high == 180.0


@pytest.mark.parametrize("side", [0.0, 1.0])
def test_shadow_darkens_exactly_one_side_of_the_band(image, side):
    params = {"top": 0.2, "bottom": 0.9, "side": side, "factor": 0.63}
    out = _only("shadow").apply(image, [("shadow", params)])
    h, w = image.shape[:2]
    # the definition: x left of (side 0) or right of (side 1) the line from top to bottom, scaled
    # by factor in float32 and rounded
    edge = (0.2 + 0.7 * np.arange(h, dtype=np.float32)[:, None] / (h - 1)) * w
    xs = np.arange(w, dtype=np.float32)[None, :]
    mask = (xs < edge) if side < 0.5 else (xs >= edge)
    want = np.where(mask[:, :, None], np.rint(image.astype(np.float32) * np.float32(0.63)), image)
    assert np.array_equal(out, want.astype(np.uint8))
    assert out is not image and not np.shares_memory(out, image)
