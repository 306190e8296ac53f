"""Load a car's settings: package defaults, then the car's ``myconfig.py`` overrides, validated.

>>> cfg = Config.defaults(DRIVE_LOOP_HZ=50)
>>> cfg.DRIVE_LOOP_HZ, cfg.CAMERA_FRAMERATE
(50, 50)
"""

from __future__ import annotations

import ast
import difflib
import logging
import os
import types
import typing
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from enum import Enum
from functools import cache
from pathlib import Path
from typing import Any

from vehicle.errors import VehicleError
from vehicle.keys import Mode

logger = logging.getLogger(__name__)

DEFAULTS_MODULE = Path(__file__).with_name("config_defaults.py")

#: DonkeyCar settings that have another name here, so a copied myconfig.py gets a precise hint
RENAMED: dict[str, str] = {"WEB_INIT_MODE": "DEFAULT_MODE"}


class ConfigError(VehicleError, ValueError):
    """A setting is unknown, of the wrong type, or the override file cannot be read."""


@dataclass(frozen=True)
class Setting:
    """One setting of config_defaults.py: its type, default expression and documentation."""

    name: str
    annotation: str
    expression: ast.expr
    doc: str
    section: str
    line: int


@cache
def settings() -> dict[str, Setting]:
    """Parse config_defaults.py into its settings, in file order."""
    source = DEFAULTS_MODULE.read_text()
    lines = source.splitlines()
    found: dict[str, Setting] = {}
    section = ""
    section_at = {i: ln.strip()[4:-3].strip() for i, ln in enumerate(lines, 1) if _is_section(ln)}
    for node in ast.parse(source).body:
        if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
            continue
        name = node.target.id
        if not name.isupper():
            continue
        section = next((section_at[i] for i in range(node.lineno, 0, -1) if i in section_at), section)
        doc: list[str] = []
        i = node.lineno - 2
        while i >= 0 and lines[i].lstrip().startswith("#") and not _is_section(lines[i]):
            doc.insert(0, lines[i].strip().lstrip("#").strip())
            i -= 1
        found[name] = Setting(name, ast.unparse(node.annotation), node.value, " ".join(doc), section,
                              node.lineno)
    return found


def _is_section(line: str) -> bool:
    s = line.strip()
    return s.startswith("# ==") and s.endswith("==")


_TYPE_NAMESPACE = {"Literal": typing.Literal, "Callable": Callable, "Any": Any, "Mode": Mode}


@cache
def _type_of(annotation: str) -> Any:
    return eval(annotation, dict(_TYPE_NAMESPACE))  # noqa: S307 - our own module's annotations


def _matches(value: Any, tp: Any) -> bool:
    """Whether ``value`` fits the annotation ``tp`` (the subset of typing used by the defaults)."""
    if tp is Any:
        return True
    if tp is None or tp is type(None):
        return value is None
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return any(_matches(value, a) for a in args)
    if origin is typing.Literal:
        return value in args
    if isinstance(tp, type) and issubclass(tp, Enum):
        return isinstance(value, str) and value in {m.value for m in tp}
    if tp is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if tp is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if origin is Callable or tp is Callable:
        return callable(value)
    if origin in (list, tuple):
        if not isinstance(value, list | tuple):
            return False
        if origin is tuple and args and args[-1] is not Ellipsis:
            return len(value) == len(args) and all(_matches(v, a) for v, a in zip(value, args, strict=True))
        inner = args[0] if args else Any
        return all(_matches(v, inner) for v in value)
    if origin is dict:
        if not isinstance(value, dict):
            return False
        kt, vt = args or (Any, Any)
        return all(_matches(k, kt) and _matches(v, vt) for k, v in value.items())
    return isinstance(value, origin or tp)


def describe_type(annotation: str) -> str:
    """The annotation as users read it: the drive-mode type spelt as its values."""
    modes = " | ".join(f'"{m.value}"' for m in Mode)
    return annotation.replace("list[Mode]", f"list[{modes}]").replace("Mode", modes)


def check_value(name: str, value: Any, where: str = "") -> None:
    """Raise ConfigError unless ``name`` is a known setting and ``value`` fits its type."""
    known = settings()
    if name not in known:
        close = [RENAMED[name]] if name in RENAMED else difflib.get_close_matches(name, known, n=1)
        hint = f" Did you mean {close[0]}?" if close else ""
        raise ConfigError(f"{where}unknown setting {name}.{hint} "
                          "See docs/config.md for every setting.")
    setting = known[name]
    if not _matches(value, _type_of(setting.annotation)):
        raise ConfigError(f"{where}{name} = {value!r} has type {type(value).__name__}, "
                          f"expected {describe_type(setting.annotation)}.")


class Config(Mapping[str, Any]):
    """The settings of one car, read as attributes (``cfg.DRIVE_LOOP_HZ``) like DonkeyCar's."""

    def __init__(self, values: dict[str, Any], overridden: frozenset[str] = frozenset(),
                 source: Path | None = None) -> None:
        object.__setattr__(self, "_values", values)
        object.__setattr__(self, "overridden", overridden)
        object.__setattr__(self, "source", source)

    @classmethod
    def defaults(cls, **overrides: Any) -> Config:
        """The package defaults with ``overrides`` applied and validated (for code and tests)."""
        for name, value in overrides.items():
            check_value(name, value)
        return cls(_evaluate(overrides), frozenset(overrides))

    def __getattr__(self, name: str) -> Any:
        try:
            return self._values[name]
        except KeyError:
            close = difflib.get_close_matches(name, self._values, n=1)
            hint = f"; did you mean {close[0]}?" if close else ""
            raise AttributeError(f"no setting {name}{hint}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        check_value(name, value)
        self._values[name] = value

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def path(self, name: str) -> Path:
        """A path setting resolved against CAR_PATH (absolute settings stay as they are)."""
        return Path(self.CAR_PATH) / os.path.expanduser(self._values[name])

    def replace(self, **overrides: Any) -> Config:
        """A copy with more overrides; derived settings are recomputed."""
        for name, value in overrides.items():
            check_value(name, value)
        merged = {n: self._values[n] for n in self.overridden} | overrides
        return Config(_evaluate(merged), self.overridden | frozenset(overrides), self.source)


def _evaluate(overrides: dict[str, Any]) -> dict[str, Any]:
    """Evaluate the defaults in file order, taking overrides where given, so derived values follow."""
    namespace: dict[str, Any] = {}
    for name, setting in settings().items():
        if name in overrides:
            namespace[name] = overrides[name]
        else:
            code = compile(ast.Expression(setting.expression), str(DEFAULTS_MODULE), "eval")
            namespace[name] = eval(code, {"__builtins__": __builtins__}, dict(namespace))  # noqa: S307
    return namespace


def read_overrides(path: Path) -> dict[str, Any]:
    """Run a myconfig.py file and return its UPPERCASE names, each validated with its line number."""
    try:
        source = path.read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the config file ({exc.strerror}).") from exc
    try:
        tree = ast.parse(source, filename=str(path))
    except SyntaxError as exc:
        raise ConfigError(f"{path}, line {exc.lineno}: invalid Python: {exc.msg}.") from exc
    lines: dict[str, int] = {}
    for node in ast.walk(tree):
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        for t in targets:
            if isinstance(t, ast.Name) and t.id.isupper():
                lines.setdefault(t.id, t.lineno)
        if isinstance(node, ast.FunctionDef | ast.ClassDef) and node.name.isupper():
            lines.setdefault(node.name, node.lineno)
    namespace: dict[str, Any] = {"__file__": str(path), "__name__": "myconfig"}
    try:
        exec(compile(tree, str(path), "exec"), namespace)  # noqa: S102 - the user's own config file
    except Exception as exc:
        raise ConfigError(f"{path}: running the config file failed: {type(exc).__name__}: {exc}") from exc
    overrides = {k: v for k, v in namespace.items() if k.isupper()}
    for name, value in overrides.items():
        where = f"{path}, line {lines[name]}: " if name in lines else f"{path}: "
        check_value(name, value, where)
    return overrides


def load_config(myconfig: str | os.PathLike[str] | None = None,
                car_path: str | os.PathLike[str] | None = None) -> Config:
    """Load defaults plus a car's overrides.

    Args:
        myconfig: the override file; default ``<car_path>/myconfig.py``. A relative path is taken
            relative to ``car_path``.
        car_path: the car folder; default the folder of ``myconfig``, else the current directory.

    Raises:
        ConfigError: the file is missing or invalid, a name is unknown or a value has the wrong type.
    """
    if car_path is None:
        car_path = Path(myconfig).resolve().parent if myconfig else Path.cwd()
    car = Path(car_path).resolve()
    path = car / (myconfig or "myconfig.py")
    if not path.is_file():
        if myconfig is not None:
            raise ConfigError(f"{path}: no such config file. Pass an existing file to --myconfig.")
        logger.warning("%s not found: using the default settings", path)
        overrides: dict[str, Any] = {}
    else:
        overrides = read_overrides(path)
    overrides.setdefault("CAR_PATH", str(car))
    return Config(_evaluate(overrides), frozenset(overrides), path)
