"""The hyper-parameter table: Track Driver AI's validation rules, shared by the CLI and the console."""

from __future__ import annotations

import pytest

from training import hyperparams as hp
from vehicle.config import Config

# Track Driver AI's "Validation Tests" of the training setup: field, normal, extreme, erroneous
SEED = [
    ("balance_bins", "25", "100", "-21", 25),
    ("max_per_bin", "400", "1500", "True", 400),
    ("val_share", "0.2", "1", "3.5", 0.2),
    ("aug_flip_p", "0.5", "1", "yes", 0.5),
    ("batch_size", "100", "1", "0", 100),
    ("learning_rate", "0.001", "100", "foo", 0.001),
    ("epochs", "10", "1", "-3", 10),
    ("steps_per_epoch", "300", "1", "bar", 300),
    ("val_steps", "200", "1", "-30", 200),
]


@pytest.mark.parametrize("name,normal,extreme,bad,value", SEED)
def test_the_track_driver_ai_table(name, normal, extreme, bad, value):
    clean, errors = hp.parse({name: normal})
    assert errors == {} and clean == {name: value}
    assert hp.parse({name: extreme})[1] == {}
    clean, errors = hp.parse({name: bad})
    assert clean == {} and set(errors) == {name}
    p = hp.by_name(name)
    assert errors[name].startswith(f"must be {p.rule()} (got {bad!r})") and p.why in errors[name]


def test_typed_values_and_bools():
    clean, errors = hp.parse({"epochs": 5, "learning_rate": 1, "balance": "on", "early_stop": False,
                              "augmentations": "flip, shift", "modes": ["user"], "device": "cuda:1",
                              "steps_per_epoch": ""})
    assert errors == {}
    assert clean == {"epochs": 5, "learning_rate": 1.0, "balance": True, "early_stop": False,
                     "augmentations": ["flip", "shift"], "modes": ["user"], "device": "cuda:1",
                     "steps_per_epoch": None}
    _, errors = hp.parse({"epochs": True, "batch_size": 2.5, "learning_rate": float("nan"), "modes": [],
                          "augmentations": ["mirror"], "device": "tpu", "split_by": "frames", "balance": "maybe",
                          "epoch": 3})
    assert set(errors) == {"epochs", "batch_size", "learning_rate", "modes", "augmentations", "device",
                           "split_by", "balance", "epoch"}
    assert errors["epoch"] == "unknown hyper-parameter; did you mean epochs?"
    assert errors["modes"] == ("choose at least 1 of user, local_angle, local: training needs at least one mode "
                               "to read records from")
    assert errors["split_by"] == "must be one of session, block, random (got 'frames')"


def test_model_types_are_checked_against_the_registered_ones():
    assert hp.parse({"model_type": "pilotnet"}, model_types=["linear", "pilotnet"]) == (
        {"model_type": "pilotnet"}, {})
    _, errors = hp.parse({"model_type": "pilotnt"}, model_types=["linear", "pilotnet"])
    assert errors["model_type"] == "must be one of linear, pilotnet (got 'pilotnt'); did you mean pilotnet?"


def test_settings_and_defaults_map_to_the_config():
    clean, _ = hp.parse({"val_share": "0.25", "epochs": "7", "augmentations": ""})
    assert hp.settings_for(clean) == {"TRAIN_TEST_SPLIT": 0.75, "MAX_EPOCHS": 7, "AUGMENTATIONS": []}
    cfg = Config.defaults(TRAIN_TEST_SPLIT=0.9, BATCH_SIZE=16)
    d = hp.defaults(cfg)
    assert d["val_share"] == pytest.approx(0.1) and d["batch_size"] == 16 and d["steps_per_epoch"] is None
    # every field's default passes its own rule, and maps back to the same settings
    clean, errors = hp.parse(d)
    assert errors == {}
    settings = hp.settings_for(clean)
    assert all(settings[k] == pytest.approx(getattr(cfg, k)) if isinstance(settings[k], float)
               else settings[k] == list(getattr(cfg, k)) if isinstance(settings[k], list)
               else settings[k] == getattr(cfg, k) for k in settings)
    cfg.replace(**settings)  # every setting exists and has the right type


def test_check_config_names_the_settings():
    from types import SimpleNamespace

    from vehicle.config import ConfigError

    hp.check_config(Config.defaults())
    with pytest.raises(ConfigError, match="MAX_EPOCHS = 0 is out of range"):
        Config.defaults(MAX_EPOCHS=0)  # a car's config refuses them already, with the same bounds
    bad = SimpleNamespace(**{**dict(Config.defaults()), "MAX_EPOCHS": 0, "AUG_FLIP_P": 1.5})
    with pytest.raises(hp.HyperParamError) as info:
        hp.check_config(bad)
    assert str(info.value).startswith("MAX_EPOCHS = 0: must be a whole number ≥ 1 (got 0)")
    assert "AUG_FLIP_P = 1.5: must be a number in [0, 1] (got 1.5): it is a probability" in str(info.value)


def test_describe_gives_every_field_with_its_default():
    items = hp.describe(Config.defaults(), model_types=["linear"])
    assert [i["name"] for i in items] == [p.name for p in hp.HYPERPARAMS]
    by = {i["name"]: i for i in items}
    assert by["model_type"]["choices"] == ["linear"] and by["learning_rate"]["flag"] == "--lr"
    assert by["epochs"]["default"] == 100 and by["epochs"]["rule"] == "a whole number ≥ 1"
