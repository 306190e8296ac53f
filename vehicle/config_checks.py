"""What makes a setting's value valid: a range next to each setting, and rules across settings.

A setting (see :mod:`vehicle.config`) declares its range in its annotation::

    DRIVE_LOOP_HZ: Annotated[int, Range(1, 1000, unit="Hz")] = 20
    WEB_TOKEN: Annotated[str | None, Length(min=8, secret=True)] = None

Settings that are only valid together (a PWM pulse width depends on the PWM frequency; the servo
and the ESC need their own channels; the actuator watchdog must outlast a loop) are checked by the
functions in the ``RULES`` of the settings module that declares them. The loader
(:mod:`vehicle.config`) runs both after the user's overrides and reports the first problem as one
line that names the file, the line, the setting and what is valid. Nothing here imports anything
beyond the standard library.
"""

from __future__ import annotations

import math
import string
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any


def number_text(x: float) -> str:
    """A number as a person writes it: 1000, 0.5, 25000000 (no exponent for whole numbers)."""
    if isinstance(x, float) and x.is_integer() and abs(x) < 1e16:
        return str(int(x))
    return f"{x:g}" if isinstance(x, float) else str(x)


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _numbers(value: Any) -> list[Any]:
    """The numbers in a value: itself, or those of a list, tuple or dict, however nested."""
    if _is_number(value):
        return [value]
    if isinstance(value, dict):
        value = list(value.values())
    if isinstance(value, list | tuple):
        return [x for item in value for x in _numbers(item)]
    return []


@dataclass(frozen=True)
class Range:
    """Numbers from ``lo`` to ``hi`` (None: unbounded); ``lo_open``/``hi_open`` exclude the bound.

    A list, tuple or dict value is checked number by number (nested ones too). ``None`` passes
    (the type says whether it is allowed); ``note`` is added to the description (e.g. what None
    means).
    """

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    unit: str = ""
    note: str = ""

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is invalid, or None."""
        items = _numbers(value)
        for item in items:
            why = self._item_problem(item)
            if why:
                return why if items == [value] else f"holds {number_text(item)}, which {why}"
        return None

    def _item_problem(self, x: float) -> str | None:
        if not math.isfinite(x):
            return "is not a finite number"
        below = self.lo is not None and (x <= self.lo if self.lo_open else x < self.lo)
        above = self.hi is not None and (x >= self.hi if self.hi_open else x > self.hi)
        return "is out of range" if below or above else None

    def describe(self) -> str:
        """What is valid, e.g. ``1 to 1000 Hz`` or ``above 0 and at most 1 s``."""
        unit = f" {self.unit}" if self.unit else ""
        lo, hi = self.lo, self.hi
        if lo is not None and hi is not None and not (self.lo_open or self.hi_open):
            text = f"{number_text(lo)} to {number_text(hi)}{unit}"
        else:
            parts = []
            if lo is not None:
                parts.append(f"{'above' if self.lo_open else 'at least'} {number_text(lo)}")
            if hi is not None:
                parts.append(f"{'below' if self.hi_open else 'at most'} {number_text(hi)}")
            text = (" and ".join(parts) or "any finite number") + unit
        return f"{text}; {self.note}" if self.note else text

    def show(self, name: str, value: Any) -> str:
        """How the value appears in a message."""
        return f"{name} = {value!r}"


def secret_bits(text: str) -> float:
    """A rough guess of a secret's strength in bits: its length (at most twice its distinct
    characters, so ``aaaa...`` counts little) times log2 of the alphabets it draws from (digits,
    lower case, upper case, anything else)."""
    pools = ((string.digits, 10), (string.ascii_lowercase, 26), (string.ascii_uppercase, 26))
    size = sum(n for chars, n in pools if any(c in chars for c in text))
    if any(not any(c in chars for chars, _n in pools) for c in text):
        size += 32
    length = min(len(text), 2 * len(set(text)))
    return length * math.log2(size) if size else 0.0


@dataclass(frozen=True)
class Length:
    """A string or list of ``min`` to ``max`` items; ``secret`` values are never printed and, with
    ``min_bits``, must be that hard to guess (:func:`secret_bits`)."""

    min: int | None = None
    max: int | None = None
    secret: bool = False
    note: str = ""
    min_bits: int | None = None

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is invalid, or None."""
        if value is None or not hasattr(value, "__len__"):
            return None
        n = len(value)
        if self.min is not None and n < self.min:
            return "is empty" if n == 0 else "is too short"
        if self.max is not None and n > self.max:
            return "is too long"
        if self.min_bits is not None and isinstance(value, str) and (bits := secret_bits(value)) < self.min_bits:
            return f"is too weak (about {bits:.0f} bits of guessing)"
        return None

    def describe(self) -> str:
        """What is valid, e.g. ``at least 8 characters``."""
        what = "characters" if self.secret else "items"
        if self.min is not None and self.max is not None:
            text = f"{self.min} to {self.max} {what}"
        elif self.min is not None:
            text = f"at least {self.min} {what}" if not (self.min == 1 and what == "items") \
                else "at least one item"
        else:
            text = f"at most {self.max} {what}"
        if self.min_bits is not None:
            text += (f" and about {self.min_bits} bits (e.g. 16 random letters and digits; repeated characters "
                     "and a single kind of character count little)")
        return f"{text}; {self.note}" if self.note else text

    def show(self, name: str, value: Any) -> str:
        """How the value appears in a message (a secret shows only its length)."""
        if self.secret and isinstance(value, str):
            return f"{name} ({len(value)} characters)"
        return f"{name} = {value!r}"


@dataclass(frozen=True)
class Checked:
    """A setting whose valid values depend on other settings: a rule of :data:`RULES` checks it;
    ``valid`` says what for the reference."""

    valid: str

    def problem(self, value: Any) -> str | None:
        """Never a problem on its own (the rule decides)."""
        return None

    def describe(self) -> str:
        """What is valid."""
        return self.valid

    def show(self, name: str, value: Any) -> str:
        """How the value appears in a message."""
        return f"{name} = {value!r}"


@dataclass(frozen=True)
class OneOf:
    """One of a set of names: a family's table (:class:`vehicle.registry.Registry`) or any iterable of
    strings, read when checked, so a row registered later is valid too. A list or tuple value is
    checked item by item (``list[str]`` settings such as TUB_TYPES)."""

    choices: Any

    def names(self) -> list[str]:
        """The valid names, in table order."""
        return list(self.choices)

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is invalid, or None."""
        names = self.names()
        if isinstance(value, list | tuple):
            unknown = [item for item in value if item not in names]
            return f"holds {unknown[0]!r}, which is unknown" if unknown else None
        return None if value in names else "is unknown"

    def describe(self) -> str:
        """What is valid, e.g. ``one of "PICAM", "MOCK"``."""
        return "one of " + ", ".join(f'"{n}"' for n in self.names())

    def show(self, name: str, value: Any) -> str:
        """How the value appears in a message."""
        return f"{name} = {value!r}"


Constraint = Range | Length | Checked | OneOf


@dataclass(frozen=True)
class Problem:
    """A rule's finding: the setting it is about, the whole message, and the other settings
    involved (the loader points at the line of whichever of them the user set)."""

    setting: str
    message: str
    related: tuple[str, ...] = ()


Rule = Callable[[Mapping[str, Any]], Iterator[Problem]]


def ordered_pair(name: str) -> Rule:
    """A rule: setting ``name`` is a (low, high) pair."""
    def rule(v: Mapping[str, Any]) -> Iterator[Problem]:
        lo, hi = v[name]
        if lo > hi:
            yield Problem(name, f"{name} = {v[name]!r} is (high, low); valid: (low, high) with "
                          "low <= high")
    return rule
