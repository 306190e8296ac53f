"""The source documents' training recipes, by name: every value a document states, as settings.

``vehicle train --recipe NAME`` (and ``manage.py train --recipe NAME``, and the trainer console's
preset) applies a recipe's settings over the car's own before training; options given on the
command line still win. docs/training.md ("Recipes") maps every number of each document to the
setting that holds it, and tests/parts/pilots/test_recipes.py checks the preprocessing and the
augmentations against references written from the documents' text.

Nothing here imports torch: the console's web server lists the recipes.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

__all__ = ["RECIPES", "Recipe", "recipe", "recipe_names"]

#: Udacity's side cameras as `vehicle tub import-udacity` records them
LEFT_KEY, RIGHT_KEY = "cam/image_array_left", "cam/image_array_right"


@dataclass(frozen=True)
class Recipe:
    """A document's training recipe.

    Attributes:
        name: the name ``--recipe`` takes.
        document: which source document, and where in it.
        summary: one line for listings.
        settings: config settings the recipe sets (``cfg.replace(**settings)``).
        frame_shape: (height, width) of the camera frames the document's numbers (crop rows)
            were written for; training on other frames is refused.
        name_by_dataset: without ``--model``, name the model ``[dataset]_[N].pt`` (Track Driver AI's
            naming) instead of ``pilot_[date]_[N].pt``.
        drive_settings: the settings that drive as the document's driver does (not stored in the
            model: they are the car's; `vehicle train --recipe` names them).
        notes: where the document is ambiguous or our reading differs, and why.
    """

    name: str
    document: str
    summary: str
    settings: Mapping[str, Any]
    frame_shape: tuple[int, int]
    name_by_dataset: bool = False
    drive_settings: Mapping[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        object.__setattr__(self, "settings", MappingProxyType(dict(self.settings)))
        object.__setattr__(self, "drive_settings", MappingProxyType(dict(self.drive_settings)))

    @property
    def model_type(self) -> str:
        return str(self.settings["DEFAULT_MODEL_TYPE"])

    def check_frames(self, shape: tuple[int, ...]) -> None:
        """ValueError when frames of ``shape`` (H, W[, C]) are not the document's."""
        h, w = int(shape[0]), int(shape[1])
        if (h, w) != self.frame_shape:
            fh, fw = self.frame_shape
            raise ValueError(f"recipe {self.name} is written for {fw}x{fh} frames (its crop rows are the "
                             f"document's) but the tubs hold {w}x{h} frames: record with SIM_CAMERA_W = {fw} "
                             f"and SIM_CAMERA_H = {fh} (or IMAGE_W/IMAGE_H for a camera), or train without "
                             "--recipe")


_NO_AUGMENTATION: dict[str, Any] = {"AUGMENTATIONS": []}

RECIPES: dict[str, Recipe] = {r.name: r for r in (
    Recipe(
        name="track-driver-ai",
        document="seed 000, Track Driver AI: Preprocessing, Augmenter, Batch Generator, Model, Drive",
        summary="DAVE-2 with ELU on YUV 66x200, zoom/pan/brightness/flip augmenter, 10 x 300 steps of 100",
        frame_shape=(160, 320),
        name_by_dataset=True,
        settings={
            "DEFAULT_MODEL_TYPE": "pilotnet",
            "MODEL_OPTIONS": {"activation": "elu", "dropout": 0.0},
            # preprocess_image: image[60:135], RGB2YUV, GaussianBlur 3x3, resize (200, 66), /255
            "ROI_CROP_TOP": 60, "ROI_CROP_BOTTOM": 25, "ROI_CROP_LEFT": 0, "ROI_CROP_RIGHT": 0,
            "PREPROCESS_COLOR": "yuv", "PREPROCESS_COLOR_FIRST": True, "PREPROCESS_BLUR": 3,
            "PREPROCESS_RESIZE": (66, 200), "PREPROCESS_INTERPOLATION": "linear", "PREPROCESS_NORMALIZE": "unit",
            # Augmenter.random_augment: pan, zoom, brightness, flip, each with p = 0.5
            "AUGMENTATIONS": ["shift", "zoom", "multiply", "flip"],
            "AUG_SHIFT_P": 0.5, "AUG_SHIFT_X": 0.1, "AUG_SHIFT_Y": 0.1, "AUG_SHIFT_STEERING": 0.0,
            "AUG_ZOOM_P": 0.5, "AUG_ZOOM_RANGE": 0.3,
            "AUG_MULTIPLY_P": 0.5, "AUG_MULTIPLY_RANGE": (0.2, 1.2),
            "AUG_FLIP_P": 0.5, "AUG_BORDER": "constant",
            # training parameters: Adam 1e-3, MSE, 10 epochs of 300 steps, 200 validation steps, batch 100
            "LEARNING_RATE": 1e-3, "MAX_EPOCHS": 10, "TRAIN_STEPS_PER_EPOCH": 300, "TRAIN_VAL_STEPS": 200,
            "BATCH_SIZE": 100, "USE_EARLY_STOP": False, "TRAIN_WEIGHT_DECAY": 0.0,
            # balancing: 25 bins, at most 400 per bin; train_test_split(test_size=0.2)
            "TRAIN_BALANCE": True, "TRAIN_BALANCE_BINS": 25, "TRAIN_BALANCE_MAX_PER_BIN": 400,
            "TRAIN_TEST_SPLIT": 0.8, "TRAIN_SPLIT_BY": "random", "TRAIN_FLIP_COPY": False,
            # side cameras +-0.15
            "TRAIN_SIDE_CAMERAS": {LEFT_KEY: 0.15, RIGHT_KEY: -0.15},
        },
        # Drive (its later version): throttle = 1 - speed / (speed_limit * 1.25)
        drive_settings={"PILOT_SPEED_CONTROL": "limit", "PILOT_SPEED_LIMIT_HEADROOM": 1.25},
        notes=("Keras's generator draws random records with replacement; here each epoch is 300 batches of "
               "a fresh random order (TRAIN_STEPS_PER_EPOCH).",),
    ),
    Recipe(
        name="udacity-bc",
        document="seed 001, Udacity behavioural cloning: model.py and drive.py",
        summary="PilotNet (ReLU, dropout 0.5) on crop 50/20, YUV 66x200, x/127-1, mirrored copies, 10 epochs",
        frame_shape=(160, 320),
        settings={
            "DEFAULT_MODEL_TYPE": "pilotnet",
            "MODEL_OPTIONS": {"activation": "relu", "dropout": 0.5},
            # Cropping2D(((50, 20), (0, 0))), resize to 66x200, YUV, x / 127 - 1
            "ROI_CROP_TOP": 50, "ROI_CROP_BOTTOM": 20, "ROI_CROP_LEFT": 0, "ROI_CROP_RIGHT": 0,
            "PREPROCESS_COLOR": "yuv", "PREPROCESS_COLOR_FIRST": False, "PREPROCESS_BLUR": 0,
            "PREPROCESS_RESIZE": (66, 200), "PREPROCESS_INTERPOLATION": "linear",
            "PREPROCESS_NORMALIZE": "symmetric127",
            # every image and its mirror (steering * -1); no random augmentation
            **_NO_AUGMENTATION, "TRAIN_FLIP_COPY": True,
            # model.compile(loss="mse", optimizer="adam"); fit(validation_split=0.2, shuffle=True, epochs=10)
            # (Keras's defaults: learning rate 1e-3, batch size 32)
            "LEARNING_RATE": 1e-3, "MAX_EPOCHS": 10, "BATCH_SIZE": 32, "TRAIN_STEPS_PER_EPOCH": None,
            "TRAIN_VAL_STEPS": None, "USE_EARLY_STOP": False, "TRAIN_WEIGHT_DECAY": 0.0,
            "TRAIN_TEST_SPLIT": 0.8, "TRAIN_SPLIT_BY": "random", "TRAIN_BALANCE": False,
            # sa_cor = 0.2
            "TRAIN_SIDE_CAMERAS": {LEFT_KEY: 0.2, RIGHT_KEY: -0.2},
        },
        # drive.py: SimplePIController(0.1, 0.002) at set_speed 9 mph, in its own units
        # (`vehicle udacity drive --drive-py`)
        drive_settings={"PILOT_SPEED_CONTROL": "drivepy", "PILOT_SPEED_LIMIT": 9 * 0.44704},
        notes=("Keras's validation_split takes the last 20 % of the samples before shuffling; the document's "
               "text calls it an 80/20 split, which TRAIN_SPLIT_BY = 'random' reproduces without the order "
               "dependence.",),
    ),
    Recipe(
        name="donkey-thesis",
        document="seed 002, the thesis: §8.5.1 (NVIDIA model for Donkey), §8.6 (training practice)",
        summary="the thesis's NVIDIA variant on DonkeyCar's 120x160 frames, steering and throttle, early stopping",
        frame_shape=(120, 160),
        settings={
            "DEFAULT_MODEL_TYPE": "nvidia",
            "MODEL_OPTIONS": {"dropout": 0.1, "batch_norm": False},
            # DonkeyCar's preprocessing: the whole frame, scaled to [0, 1]
            "ROI_CROP_TOP": 0, "ROI_CROP_BOTTOM": 0, "ROI_CROP_LEFT": 0, "ROI_CROP_RIGHT": 0,
            "PREPROCESS_COLOR": "rgb", "PREPROCESS_COLOR_FIRST": False, "PREPROCESS_BLUR": 0,
            "PREPROCESS_RESIZE": None, "PREPROCESS_NORMALIZE": "unit", "PREPROCESS_INTERPOLATION": "area",
            # §8.6.6: mirrored copies of all the images (no other augmentation)
            **_NO_AUGMENTATION, "TRAIN_FLIP_COPY": True,
            # optimizer="adam", loss="mse"; DonkeyCar 3's defaults the thesis trained with: batch 128,
            # 100 epochs at most, early stopping (§8.6.7) with patience 5, 80/20 split
            "LEARNING_RATE": 1e-3, "BATCH_SIZE": 128, "MAX_EPOCHS": 100, "USE_EARLY_STOP": True,
            "EARLY_STOP_PATIENCE": 5, "MIN_DELTA": 0.0005, "TRAIN_STEPS_PER_EPOCH": None, "TRAIN_VAL_STEPS": None,
            "TRAIN_WEIGHT_DECAY": 0.0, "TRAIN_TEST_SPLIT": 0.8, "TRAIN_SPLIT_BY": "random",
            "TRAIN_BALANCE": False, "TRAIN_SIDE_CAMERAS": {},
        },
        notes=("§8.6.1.2's 60/20/20 split keeps a test set apart; `vehicle sim eval` on held-out tracks is "
               "the test here, so 80 % trains and 20 % validates.",),
    ),
)}


def describe() -> list[dict[str, Any]]:
    """Every recipe as plain values for the trainer console's preset: name, document, summary, the
    model type, and ``values``: the training form's fields the recipe sets (the form shows them;
    the recipe's other settings, such as its preprocessing, travel with its name)."""
    from training.hyperparams import for_setting

    out = []
    for r in RECIPES.values():
        values = {}
        for setting, value in r.settings.items():
            p = for_setting(setting)
            if p is not None and p.name != "model_type":
                values[p.name] = p.from_setting(value)
        others = sorted(s for s in r.settings if for_setting(s) is None)
        out.append({"name": r.name, "document": r.document, "summary": r.summary, "model_type": r.model_type,
                    "values": values, "other_settings": others,
                    "frames": f"{r.frame_shape[1]}x{r.frame_shape[0]}"})
    return out


def recipe_names() -> list[str]:
    """Every recipe's name."""
    return sorted(RECIPES)


def recipe(name: str) -> Recipe:
    """The recipe called ``name``; ValueError naming the known ones otherwise."""
    try:
        return RECIPES[name]
    except KeyError:
        close = difflib.get_close_matches(str(name), RECIPES, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ValueError(f"unknown recipe {name!r}.{hint} Known recipes: {', '.join(recipe_names())}") from None
