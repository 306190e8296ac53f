"""Training hyper-parameters: one table and one validation for every way of starting a training.

``vehicle train``, ``manage.py train`` and the trainer console all describe and check their
options here: each :class:`HyperParam` names the car setting it overrides (``MAX_EPOCHS`` ...),
its command-line flag, its kind and bounds and the reason for the bounds. :func:`parse` turns user
input (typed values, or the strings of a web form) into checked values with one message per bad
field; :func:`settings_for` maps them onto config settings for ``cfg.replace(...)``;
:func:`check_config` applies the same rules to a car's own myconfig.py values before training.

>>> clean, errors = parse({"epochs": "10", "learning_rate": "foo"})
>>> clean, errors["learning_rate"]
({'epochs': 10}, "must be a number > 0 (got 'foo'): a step of size 0 or less never learns")

Nothing here imports torch: the console's web server validates with it.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = ["HYPERPARAMS", "HyperParam", "HyperParamError", "by_name", "check_config", "defaults", "describe",
           "for_setting", "parse", "settings_for"]

AUGMENTATION_CHOICES = ("flip", "brightness", "multiply", "shadow", "shift", "zoom", "blur", "hue")
MODE_CHOICES = ("user", "local_angle", "local")
_DEVICE_RE = re.compile(r"^(auto|cpu|mps|cuda(:\d+)?)$")
_INT_RE = re.compile(r"^[+-]?\d+$")


class HyperParamError(ValueError):
    """Some hyper-parameters are invalid; ``errors`` maps each field name to its message."""

    def __init__(self, errors: Mapping[str, str], names: Callable[[str], str] | None = None) -> None:
        self.errors = dict(errors)
        show = names or (lambda n: n)
        super().__init__("; ".join(f"{show(k)}: {v}" for k, v in self.errors.items()))


@dataclass(frozen=True)
class HyperParam:
    """One hyper-parameter: how it is named, bounded, explained and mapped to a car setting.

    ``kind`` is ``int``, ``float``, ``bool``, ``choice`` (one of ``choices``), ``multi`` (a list of
    ``choices``) or ``device``. ``low``/``high`` are inclusive bounds (``low_open``: low excluded).
    ``optional``: blank/None is allowed and keeps the setting's None meaning. ``scale``: the field
    shows ``1 - setting`` (the validation share of TRAIN_TEST_SPLIT).
    """

    name: str
    setting: str
    label: str
    group: str
    kind: str
    help: str
    why: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    optional: bool = False
    choices: tuple[str, ...] = ()
    complement: bool = False
    flag: str = ""
    min_items: int = 0

    @property
    def cli_flag(self) -> str:
        """The command-line option (``--epochs``)."""
        return self.flag or "--" + self.name.replace("_", "-")

    def rule(self) -> str:
        """The rule in words ("a whole number >= 1")."""
        if self.kind in ("int", "float"):
            noun = "a whole number" if self.kind == "int" else "a number"
            if self.low is not None and self.high is not None:
                text = f"{noun} in [{_num(self.low)}, {_num(self.high)}]"
            elif self.low is not None:
                text = f"{noun} {'>' if self.low_open else '≥'} {_num(self.low)}"
            elif self.high is not None:
                text = f"{noun} ≤ {_num(self.high)}"
            else:
                text = noun
            return text + (" or blank" if self.optional else "")
        if self.kind == "bool":
            return "true or false"
        if self.kind == "choice":
            return "one of " + ", ".join(self.choices) if self.choices else "a registered model type"
        if self.kind == "multi":
            least = f"at least {self.min_items} of " if self.min_items else "any of "
            return least + ", ".join(self.choices)
        if self.kind == "device":
            return "auto, cpu, mps, cuda or cuda:N"
        return "a value"

    def to_setting(self, value: Any) -> Any:
        """The config value for a checked field value."""
        if self.complement and value is not None:
            return round(1.0 - float(value), 12)
        return list(value) if isinstance(value, tuple) else value

    def from_setting(self, value: Any) -> Any:
        """The field value for a config value."""
        if self.complement and value is not None:
            return round(1.0 - float(value), 12)
        return list(value) if isinstance(value, tuple) else value


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


def _p(name: str, what: str) -> HyperParam:
    return HyperParam(f"aug_{name}_p", f"AUG_{name.upper()}_P", f"{name.capitalize()} probability",
                      "Augmentation", "float", f"Chance that a training frame gets {what}.",
                      "it is a probability", 0.0, 1.0)


#: Every hyper-parameter, in the order forms and ``--help`` show them.
HYPERPARAMS: tuple[HyperParam, ...] = (
    HyperParam("model_type", "DEFAULT_MODEL_TYPE", "Model type", "Model", "choice",
               "Architecture to train (see the model types for what each needs).",
               "only registered model types can be built", flag="--type"),
    HyperParam("seq_length", "SEQUENCE_LENGTH", "Sequence length", "Model", "int",
               "Frames (rnn, 3d) or previous commands (memory) a sequence model sees.",
               "a sequence holds at least one frame", 1, 100),
    HyperParam("epochs", "MAX_EPOCHS", "Epochs", "Optimisation", "int",
               "Most passes over the training data (early stopping may end sooner).",
               "training needs at least one epoch", 1),
    HyperParam("batch_size", "BATCH_SIZE", "Batch size", "Optimisation", "int",
               "Samples per training step.", "a step needs at least one sample", 1),
    HyperParam("learning_rate", "LEARNING_RATE", "Learning rate", "Optimisation", "float",
               "Adam step size; lower it if the loss jumps or becomes NaN.",
               "a step of size 0 or less never learns", 0.0, low_open=True, flag="--lr"),
    HyperParam("weight_decay", "TRAIN_WEIGHT_DECAY", "Weight decay", "Optimisation", "float",
               "L2 penalty on the weights (0 = off).", "a negative penalty would reward large weights", 0.0),
    HyperParam("steps_per_epoch", "TRAIN_STEPS_PER_EPOCH", "Steps per epoch", "Optimisation", "int",
               "Batches per epoch; blank = every training sample once per epoch.",
               "an epoch needs at least one step", 1, optional=True),
    HyperParam("val_steps", "TRAIN_VAL_STEPS", "Validation steps", "Optimisation", "int",
               "Validation batches per epoch; blank = every validation sample.",
               "validation needs at least one batch", 1, optional=True),
    HyperParam("early_stop", "USE_EARLY_STOP", "Early stopping", "Optimisation", "bool",
               "Stop when the validation loss stops improving; the best epoch's model is kept."),
    HyperParam("patience", "EARLY_STOP_PATIENCE", "Patience", "Optimisation", "int",
               "Epochs without improvement before early stopping.",
               "at least one epoch must be allowed to improve", 1),
    HyperParam("min_delta", "MIN_DELTA", "Minimum improvement", "Optimisation", "float",
               "Smallest drop of the validation loss that counts as an improvement.",
               "an improvement cannot be negative", 0.0),
    HyperParam("val_share", "TRAIN_TEST_SPLIT", "Validation share", "Data", "float",
               "Share of the records held out for validation (whole sessions or blocks, never "
               "single frames; at least one block always trains).", "it is a share of the records",
               0.0, 1.0, complement=True),
    HyperParam("split_by", "TRAIN_SPLIT_BY", "Split by", "Data", "choice",
               "Hold out whole recording sessions, contiguous blocks of records, or random records "
               "(as the source documents' scikit-learn/Keras splits do).",
               "only these splits exist", choices=("block", "session", "random")),
    HyperParam("split_block", "TRAIN_SPLIT_BLOCK", "Block length", "Data", "int",
               "Records per block of the block split (100 = 5 s at 20 Hz).",
               "a block holds at least one record", 1),
    HyperParam("modes", "TRAIN_MODES", "Drive modes", "Data", "multi",
               "Train only on records driven in these modes (pilot-driven records teach nothing new).",
               "training needs at least one mode to read records from", choices=MODE_CHOICES, min_items=1),
    HyperParam("flip_copy", "TRAIN_FLIP_COPY", "Mirrored copy", "Data", "bool",
               "Add a mirrored copy of every frame (steering negated), doubling the data."),
    HyperParam("balance", "TRAIN_BALANCE", "Balance by steering", "Data", "bool",
               "Keep at most 'samples per bin' records per steering bin (straight driving otherwise "
               "dominates)."),
    HyperParam("balance_bins", "TRAIN_BALANCE_BINS", "Number of bins", "Data", "int",
               "Equal-width steering bins for balancing.", "balancing needs at least one bin", 1),
    HyperParam("max_per_bin", "TRAIN_BALANCE_MAX_PER_BIN", "Samples per bin", "Data", "int",
               "Most training records kept per steering bin.", "a bin must keep at least one record", 1),
    HyperParam("seed", "TRAIN_SEED", "Random seed", "Data", "int",
               "Seed of the split, balancing, shuffling and augmentations (same seed, same run).",
               "random generators take seeds ≥ 0", 0),
    HyperParam("augmentations", "AUGMENTATIONS", "Augmentations", "Augmentation", "multi",
               "Training-only image changes; none = train on the frames as recorded.",
               "only these augmentations exist", choices=AUGMENTATION_CHOICES, flag="--aug"),
    _p("flip", "mirrored (steering negated)"),
    _p("brightness", "a brightness/contrast change"),
    HyperParam("aug_brightness_range", "AUG_BRIGHTNESS_RANGE", "Brightness range", "Augmentation", "float",
               "Largest brightness change, fraction of full scale (0.2 = ±20 %).",
               "it is a fraction of full scale", 0.0, 1.0),
    _p("multiply", "its brightness multiplied by one random factor"),
    HyperParam("aug_contrast_range", "AUG_CONTRAST_RANGE", "Contrast range", "Augmentation", "float",
               "Largest contrast change (0.2 = ×0.8 to ×1.2).", "a contrast below 0 inverts the image", 0.0, 1.0),
    _p("shadow", "a shadow"),
    HyperParam("aug_shadow_darkness", "AUG_SHADOW_DARKNESS", "Shadow darkness", "Augmentation", "float",
               "Darkest factor a shadow multiplies pixels by.", "it is a brightness factor", 0.0, 1.0),
    _p("shift", "shifted (panned, steering corrected)"),
    HyperParam("aug_shift_x", "AUG_SHIFT_X", "Shift x", "Augmentation", "float",
               "Largest horizontal shift, fraction of the frame width.", "it is a fraction of the width",
               0.0, 1.0),
    HyperParam("aug_shift_y", "AUG_SHIFT_Y", "Shift y", "Augmentation", "float",
               "Largest vertical shift, fraction of the frame height.", "it is a fraction of the height",
               0.0, 1.0),
    HyperParam("aug_shift_steering", "AUG_SHIFT_STEERING", "Shift steering", "Augmentation", "float",
               "Steering added per full frame width of horizontal shift.",
               "a shift to the right must steer right, not left", 0.0),
    _p("zoom", "a centred zoom in"),
    HyperParam("aug_zoom_range", "AUG_ZOOM_RANGE", "Zoom range", "Augmentation", "float",
               "Largest zoom in, as a fraction (0.3 = up to 130 %).", "it is a fraction of the size", 0.0, 1.0),
    _p("blur", "a Gaussian blur"),
    _p("hue", "its colours turned round the colour wheel"),
    HyperParam("aug_hue_range", "AUG_HUE_RANGE", "Hue range", "Augmentation", "float",
               "Largest hue turn in degrees (180 = any colour).",
               "half the colour wheel reaches every colour", 0.0, 180.0),
    HyperParam("device", "TRAIN_DEVICE", "Device", "Hardware", "device",
               "Where to train: auto = the GPU when there is one.", "torch knows these devices"),
    HyperParam("workers", "TRAIN_NUM_WORKERS", "Data workers", "Hardware", "int",
               "DataLoader worker processes (0 = load in the training process).",
               "a count of processes cannot be negative", 0, 64),
    HyperParam("precision", "TRAIN_PRECISION", "Precision", "Hardware", "choice",
               "Arithmetic precision: auto = bf16 where the CPU or GPU computes it natively, fp16 "
               "on older GPUs, fp32 elsewhere; fp32 forces full precision.",
               "only these precisions are implemented", choices=("auto", "fp32", "bf16", "fp16")),
    HyperParam("compile", "TRAIN_COMPILE", "Compile", "Hardware", "bool",
               "Compile the model with torch.compile first (needs a C++ compiler on CPUs); pays "
               "only on long trainings."),
)

_BY_NAME = {p.name: p for p in HYPERPARAMS}
_BY_SETTING = {p.setting: p for p in HYPERPARAMS}


def by_name(name: str) -> HyperParam:
    """The hyper-parameter called ``name``."""
    return _BY_NAME[name]


def _text(value: Any) -> str:
    return value.strip() if isinstance(value, str) else ""


def _blank(value: Any) -> bool:
    return value is None or (isinstance(value, str) and not value.strip())


def _parse_one(p: HyperParam, value: Any, model_types: Sequence[str] | None) -> Any:
    """The checked value, or raise ValueError with the message shown next to the field."""
    why = f": {p.why}" if p.why else ""
    if p.kind in ("int", "float"):
        if _blank(value):
            if p.optional:
                return None
            raise ValueError(f"must be {p.rule()} (got nothing){why}")
        bad = ValueError(f"must be {p.rule()} (got {value!r}){why}")
        if isinstance(value, bool):
            raise bad
        if p.kind == "int":
            if isinstance(value, int):
                number: float = value
            elif isinstance(value, float) and value.is_integer():
                number = int(value)
            elif isinstance(value, str) and _INT_RE.match(value.strip()):
                number = int(value.strip())
            else:
                raise bad
        else:
            if isinstance(value, int | float):
                number = float(value)
            elif isinstance(value, str):
                try:
                    number = float(value.strip())
                except ValueError:
                    raise bad from None
            else:
                raise bad
            if not math.isfinite(number):
                raise bad
        if p.low is not None and (number <= p.low if p.low_open else number < p.low):
            raise bad
        if p.high is not None and number > p.high:
            raise bad
        return number
    if p.kind == "bool":
        if isinstance(value, bool):
            return value
        text = _text(value).lower()
        if text in ("true", "1", "yes", "on"):
            return True
        if text in ("false", "0", "no", "off"):
            return False
        raise ValueError(f"must be true or false (got {value!r})")
    if p.kind == "choice":
        choices = tuple(model_types) if p.name == "model_type" and model_types is not None else p.choices
        text = _text(value) if isinstance(value, str) else value
        if not isinstance(text, str) or not text:
            raise ValueError(f"must be one of {', '.join(choices)} (got {value!r})")
        if choices and text not in choices:
            close = difflib.get_close_matches(text, choices, n=1)
            hint = f"; did you mean {close[0]}?" if close else ""
            raise ValueError(f"must be one of {', '.join(choices)} (got {text!r}){hint}")
        return text
    if p.kind == "multi":
        if _blank(value):
            items: list[Any] = []
        elif isinstance(value, str):
            items = [v for v in re.split(r"[,\s]+", value.strip()) if v]
        elif isinstance(value, list | tuple):
            items = list(value)
        else:
            raise ValueError(f"must be a list of {', '.join(p.choices)} (got {value!r})")
        out: list[str] = []
        for item in items:
            if not isinstance(item, str) or item.strip().lower() not in p.choices:
                raise ValueError(f"{item!r} is not one of {', '.join(p.choices)}")
            if item.strip().lower() not in out:
                out.append(item.strip().lower())
        if len(out) < p.min_items:
            raise ValueError(f"choose {p.rule()}{why}")
        return out
    if p.kind == "device":
        text = _text(value).lower()
        if not _DEVICE_RE.match(text):
            raise ValueError(f"must be auto, cpu, mps, cuda or cuda:N (got {value!r})")
        return text
    raise AssertionError(f"unknown kind {p.kind!r}")  # pragma: no cover - a table bug


def parse(values: Mapping[str, Any], *, model_types: Sequence[str] | None = None
          ) -> tuple[dict[str, Any], dict[str, str]]:
    """Check the given fields; returns (checked values, messages of the bad fields).

    Only the fields present in ``values`` are checked (absent ones keep the car's settings).
    Strings are parsed as a form would send them ("10", "0.5", "true", "flip,shift"); typed values
    are accepted as they are, but a bool is never a number. ``model_types``: the registered model
    type names (the model type is then checked against them).
    """
    clean: dict[str, Any] = {}
    errors: dict[str, str] = {}
    for name, value in values.items():
        p = _BY_NAME.get(name)
        if p is None:
            close = difflib.get_close_matches(name, _BY_NAME, n=1)
            errors[name] = "unknown hyper-parameter" + (f"; did you mean {close[0]}?" if close else "")
            continue
        try:
            clean[name] = _parse_one(p, value, model_types)
        except ValueError as exc:
            errors[name] = str(exc)
    return clean, errors


def settings_for(clean: Mapping[str, Any]) -> dict[str, Any]:
    """Config overrides (``{"MAX_EPOCHS": 10, ...}``) for values returned by :func:`parse`."""
    return {_BY_NAME[n].setting: _BY_NAME[n].to_setting(v) for n, v in clean.items()}


def defaults(cfg: Any) -> dict[str, Any]:
    """Every field's value in the car's config (the form's defaults)."""
    return {p.name: p.from_setting(getattr(cfg, p.setting)) for p in HYPERPARAMS}


def check_config(cfg: Any, model_types: Sequence[str] | None = None) -> None:
    """Apply the same rules to a config's values; ValueError names every bad setting."""
    values = {p.name: p.from_setting(getattr(cfg, p.setting)) for p in HYPERPARAMS}
    _clean, errors = parse(values, model_types=model_types)
    if errors:
        raise HyperParamError({_BY_NAME[n].setting: m for n, m in errors.items()},
                              names=lambda s: f"{s} = {getattr(cfg, s)!r}")


def describe(cfg: Any = None, model_types: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """The table as plain values for a form: name, label, group, kind, bounds, help, rule, flag,
    setting, choices and (with ``cfg``) the car's default."""
    out = []
    for p in HYPERPARAMS:
        choices = list(model_types) if p.name == "model_type" and model_types is not None else list(p.choices)
        item = {"name": p.name, "setting": p.setting, "label": p.label, "group": p.group, "kind": p.kind,
                "help": p.help, "why": p.why, "rule": p.rule(), "low": p.low, "high": p.high,
                "low_open": p.low_open, "optional": p.optional, "choices": choices, "flag": p.cli_flag}
        if cfg is not None:
            item["default"] = p.from_setting(getattr(cfg, p.setting))
        out.append(item)
    return out


def for_setting(setting: str) -> HyperParam | None:
    """The hyper-parameter that overrides ``setting`` (None if none does)."""
    return _BY_SETTING.get(setting)
