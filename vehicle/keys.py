"""The vocabulary parts share: memory keys, how they are declared and collected, and the drive modes.

Names follow DonkeyCar where it has one, so tubs and parts interoperate. New keys get a
namespace (``sim/...``, ``web/...``): ``<namespace>/<name>`` in lower case. A user's own parts
may use any key that follows the rule; the standard keys are the ones the library itself produces
or consumes, each declared once with its type and meaning, ``KEY: KeyInfo(type, meaning)``:

- the kernel's own (the loop's health, written by :class:`vehicle.Vehicle`) in :data:`KEYS` here;
- each family's in a ``keys.py`` of its package holding ``KEYS: dict[str, KeyInfo]`` (and, for
  keys that were renamed, ``ALIASES: dict[str, str]`` of old name -> standard name), e.g.
  ``parts/sensors/keys.py``. They are found by the same walk as the families' ``settings.py``
  (:func:`vehicle.discovery.family_modules`), so a new family adds its ``keys.py`` and edits no
  list; :data:`STANDARD_KEYS` holds them all, collected on first use. docs/keys.md is generated
  from them (``python -m vehicle.config_docs``).

Part classes declare the keys they read and write once, as class attributes that are tuples of
key strings, ``INPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array",)`` and ``OUTPUTS`` (and
``OPTIONAL_INPUTS`` / ``FEEDBACK``, see :meth:`vehicle.Vehicle.add`); a part whose keys depend on
how it was built (which sensors, how many cameras) declares them as a read-only property returning
such a tuple. A car that needs other keys renames them when it adds the part, with :func:`rename`,
never through the part's constructor.
"""

from __future__ import annotations

import importlib
import logging
import re
from collections.abc import Iterator, Mapping, Sequence
from enum import StrEnum
from functools import cache
from typing import NamedTuple

from vehicle.discovery import family_modules
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)


class Mode(StrEnum):
    """The three drive modes; values are DonkeyCar's strings, as recorded in tubs (``user/mode``)."""

    USER = "user"  # the human steers and sets the throttle
    LOCAL_ANGLE = "local_angle"  # the pilot steers, the human sets the throttle
    LOCAL = "local"  # the pilot steers and sets the throttle

    def next(self) -> Mode:
        """The mode after this one, cycling user -> local_angle -> local -> user."""
        order = list(Mode)
        return order[(order.index(self) + 1) % len(order)]


#: the drive modes' strings, in cycling order
MODES: tuple[str, ...] = tuple(m.value for m in Mode)


def parse_mode(value: object) -> Mode:
    """Mode from a stored value; unknown or missing values mean user mode (the safe choice)."""
    try:
        return Mode(value)
    except ValueError:
        if value is not None:
            logger.warning("unknown drive mode %r: using user mode", value)
        return Mode.USER


class KeyInfo(NamedTuple):
    """What a memory key holds."""

    type: str
    meaning: str


class KeyDeclarationError(VehicleError, ValueError):
    """Two families declare the same memory key, or a ``keys.py`` is malformed."""


#: the keys the kernel itself writes: :class:`vehicle.Vehicle` updates them every loop
KEYS: dict[str, KeyInfo] = {
    "loop/rate_hz": KeyInfo("float, Hz", "achieved loop rate over the last second"),
    "loop/overruns": KeyInfo("int", "loops that started late so far"),
    "loop/count": KeyInfo("int", "loops run so far"),
}


class KeyTable(NamedTuple):
    """The standard keys collected from the kernel and every family's ``keys.py``."""

    keys: dict[str, KeyInfo]  # key -> what it holds, module by module, each in file order
    module: dict[str, str]  # key -> the module that declares it
    aliases: dict[str, str]  # old name -> standard name


def collect_keys(roots: Sequence[str] | None = None) -> KeyTable:
    """The kernel's :data:`KEYS`, then those of every ``keys.py`` in a package under ``roots``
    (default: the installed families, :func:`vehicle.discovery.family_roots`).

    Raises:
        KeyDeclarationError: a key (or an old name) is declared twice, a ``KEYS`` entry is not a
            :class:`KeyInfo`, or an alias does not lead from an old name to a declared key; the
            message names the modules.
    """
    table = KeyTable(dict(KEYS), dict.fromkeys(KEYS, __name__), {})
    alias_file: dict[str, str] = {}  # old name -> the file that declares the alias
    for name in family_modules("keys.py", roots):
        module = importlib.import_module(name)
        declared = getattr(module, "KEYS", None)
        if not isinstance(declared, dict):
            raise KeyDeclarationError(f"{module.__file__}: define KEYS: dict[str, KeyInfo] = {{...}} "
                                      "(the memory keys this family declares)")
        for key, info in declared.items():
            if key in table.keys:
                raise KeyDeclarationError(f"{module.__file__}: memory key {key!r} is already declared in "
                                          f"{table.module[key]}; declare each key once, in the family that "
                                          "writes it")
            if not (isinstance(key, str) and isinstance(info, KeyInfo)):
                raise KeyDeclarationError(f"{module.__file__}: KEYS[{key!r}] must map a key string to "
                                          "KeyInfo(type, meaning)")
            table.keys[key], table.module[key] = info, name
        for old, new in getattr(module, "ALIASES", {}).items():
            if old in table.aliases:
                raise KeyDeclarationError(f"{module.__file__}: old key name {old!r} is already an alias of "
                                          f"{table.aliases[old]!r}; declare each alias once")
            table.aliases[old], alias_file[old] = new, str(module.__file__)
    for old, new in table.aliases.items():
        if new not in table.keys or old in table.keys:
            raise KeyDeclarationError(f"{alias_file[old]}: ALIASES {old!r} -> {new!r} must map an old name to a "
                                      "declared standard key")
    return table


@cache
def _collected() -> KeyTable:
    return collect_keys()


class _StandardKeys(Mapping[str, KeyInfo]):
    """Every standard key -> :class:`KeyInfo`, collected on first use (importing this module
    imports no family)."""

    def __getitem__(self, key: str) -> KeyInfo:
        return _collected().keys[key]

    def __iter__(self) -> Iterator[str]:
        return iter(_collected().keys)

    def __len__(self) -> int:
        return len(_collected().keys)

    def __repr__(self) -> str:
        return f"STANDARD_KEYS({len(self)} keys)"


#: every standard key: the kernel's and each family's (see the module docstring)
STANDARD_KEYS: Mapping[str, KeyInfo] = _StandardKeys()


def describe(key: str) -> KeyInfo | None:
    """Return what ``key`` holds, or None for a key outside the standard list."""
    return STANDARD_KEYS.get(key)


def key_names(key: str) -> tuple[str, ...]:
    """``key`` followed by the other names of the same key (its standard name or its old names,
    from the families' ``ALIASES``)."""
    aliases = _collected().aliases
    standard = aliases.get(key, key)
    others = [standard] + [old for old, new in aliases.items() if new == standard]
    return (key, *(k for k in others if k != key))


_NAMESPACED = re.compile(r"^[a-z][a-z0-9_]*(/[a-z0-9_]+)+$")


def is_valid_key(key: str) -> bool:
    """Whether ``key`` is a standard key or follows the namespace rule (``sim/cte``, ``web/angle``)."""
    return key in STANDARD_KEYS or bool(_NAMESPACED.match(key))


def rename(keys: Sequence[str], mapping: Mapping[str, str]) -> tuple[str, ...]:
    """``keys`` with some renamed, for a car that wires a part to other keys.

    >>> rename(("user/angle", "user/throttle", "tub/erase"), {"user/angle": "js/angle"})
    ('js/angle', 'user/throttle', 'tub/erase')

    Raises:
        ValueError: a key of ``mapping`` is not among ``keys`` (a typo would silently do nothing).
    """
    stray = [k for k in mapping if k not in keys]
    if stray:
        raise ValueError(f"cannot rename {stray}: not among the keys {list(keys)}")
    return tuple(mapping.get(k, k) for k in keys)
