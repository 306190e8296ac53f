"""Training hyper-parameters: one table and one validation for every way of starting a training.

``vehicle train``, ``manage.py train`` and the trainer console all describe and check their
options here: each :class:`HyperParam` is derived from the one declaration of the car setting it
overrides (``MAX_EPOCHS`` ..., in :mod:`training.settings`, marked ``Form(...)``): its command-line
flag, label and group, its kind and bounds (the setting's type and range), its help (the setting's
comment) and the reason for the bounds. :func:`parse` turns user
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
import types
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from functools import cache
from typing import Annotated, Any

from training.form import Form
from vehicle.config import setting_type, settings
from vehicle.config_checks import Length, Range

__all__ = ["HyperParam", "HyperParamError", "by_name", "check_config", "defaults", "describe",
           "for_setting", "hyperparams", "parse", "settings_for"]

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


#: the form's groups, in the order forms and ``--help`` show them
GROUPS = ("Model", "Optimisation", "Data", "Augmentation", "Hardware")


def from_setting(setting: Any, form: Form) -> HyperParam:
    """The hyper-parameter a setting declares with ``Form(...)`` in its annotation: kind, bounds and
    choices from its type and range, help from its comment."""
    tp = setting_type(setting.name)
    meta: tuple[Any, ...] = ()
    if typing.get_origin(tp) is Annotated:
        tp, meta = typing.get_args(tp)[0], tp.__metadata__
    args = typing.get_args(tp)
    optional = typing.get_origin(tp) in (typing.Union, types.UnionType) and type(None) in args
    if optional:
        tp = next(a for a in args if a is not type(None))
    rng = next((m for m in meta if isinstance(m, Range)), Range())
    least = next((m.min for m in meta if isinstance(m, Length) and m.min), 0)
    choices: tuple[str, ...] = ()
    kind = form.kind
    if not kind:
        if typing.get_origin(tp) is list:
            kind, choices = "multi", _choices(typing.get_args(tp)[0])
        elif typing.get_origin(tp) is typing.Literal:
            kind, choices = "choice", _choices(tp)
        else:
            kind = {bool: "bool", int: "int", float: "float"}[tp]
    return HyperParam(form.name, setting.name, form.label, form.group, kind, form.help or setting.doc, form.why,
                      rng.lo, rng.hi, rng.lo_open, optional, choices, form.complement, form.flag, least)


def _choices(tp: Any) -> tuple[str, ...]:
    if isinstance(tp, type) and issubclass(tp, Enum):
        return tuple(m.value for m in tp)
    return tuple(str(a) for a in typing.get_args(tp))


@cache
def hyperparams() -> tuple[HyperParam, ...]:
    """Every setting declared with ``Form(...)``, by group (:data:`GROUPS`), then in declaration order."""
    found = [from_setting(s, form) for s in settings().values()
             for form in typing.get_args(setting_type(s.name))[1:] if isinstance(form, Form)]
    return tuple(sorted(found, key=lambda p: GROUPS.index(p.group)))


def __getattr__(name: str) -> Any:
    if name == "HYPERPARAMS":  # built on first use from the settings (no work at import time)
        return hyperparams()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _by_name() -> dict[str, HyperParam]:
    return {p.name: p for p in hyperparams()}


def by_name(name: str) -> HyperParam:
    """The hyper-parameter called ``name``."""
    return _by_name()[name]


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
    known = _by_name()
    for name, value in values.items():
        p = known.get(name)
        if p is None:
            close = difflib.get_close_matches(name, known, n=1)
            errors[name] = "unknown hyper-parameter" + (f"; did you mean {close[0]}?" if close else "")
            continue
        try:
            clean[name] = _parse_one(p, value, model_types)
        except ValueError as exc:
            errors[name] = str(exc)
    return clean, errors


def settings_for(clean: Mapping[str, Any]) -> dict[str, Any]:
    """Config overrides (``{"MAX_EPOCHS": 10, ...}``) for values returned by :func:`parse`."""
    known = _by_name()
    return {known[n].setting: known[n].to_setting(v) for n, v in clean.items()}


def defaults(cfg: Any) -> dict[str, Any]:
    """Every field's value in the car's config (the form's defaults)."""
    return {p.name: p.from_setting(getattr(cfg, p.setting)) for p in hyperparams()}


def check_config(cfg: Any, model_types: Sequence[str] | None = None) -> None:
    """Apply the same rules to a config's values; ValueError names every bad setting."""
    values = {p.name: p.from_setting(getattr(cfg, p.setting)) for p in hyperparams()}
    _clean, errors = parse(values, model_types=model_types)
    if errors:
        known = _by_name()
        raise HyperParamError({known[n].setting: m for n, m in errors.items()},
                              names=lambda s: f"{s} = {getattr(cfg, s)!r}")


def describe(cfg: Any = None, model_types: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """The table as plain values for a form: name, label, group, kind, bounds, help, rule, flag,
    setting, choices and (with ``cfg``) the car's default."""
    out = []
    for p in hyperparams():
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
    return next((p for p in hyperparams() if p.setting == setting), None)
