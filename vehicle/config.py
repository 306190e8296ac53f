"""Load a car's settings: the declared defaults, then the car's ``myconfig.py`` overrides, validated.

Settings are declared beside what they configure: the kernel's in :mod:`vehicle.settings`, every
family's in a ``settings.py`` of its own package (``parts/cameras/settings.py``, ...), found under
:func:`vehicle.discovery.family_roots` with no list to keep (the same walk finds the families'
``keys.py``). Each such module follows the rules below; the loader
reads it by its syntax tree (for the documentation and the derived values) and imports it (for
the names its annotations use, and its ``RULES`` across settings):

- one annotated assignment per setting, ``NAME: type = value``, UPPERCASE names;
- the comment lines right above a setting document it (units and reasons);
- a value may be an expression of other settings (``CAMERA_FRAMERATE: int = DRIVE_LOOP_HZ``, the
  name imported from the module that declares it): derived values are recomputed after the
  user's overrides unless the user set them too;
- section headers are comment lines of the form ``# == Title ==``;
- ``RULES``, a tuple of functions ``rule(values) -> Iterator[Problem]``, checks settings that are
  only valid together (see :mod:`vehicle.config_checks`).

docs/config.md is generated from them (``python -m vehicle.config_docs``) and a test keeps it in sync.

>>> cfg = Config.defaults(DRIVE_LOOP_HZ=50)
>>> cfg.DRIVE_LOOP_HZ, cfg.CAMERA_FRAMERATE
(50, 50)
"""

from __future__ import annotations

import ast
import difflib
import importlib
import logging
import os
import types
import typing
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from functools import cache
from pathlib import Path
from typing import Annotated, Any

from vehicle.config_checks import Checked, Constraint, Length, OneOf, Range, Rule
from vehicle.discovery import family_modules
from vehicle.errors import VehicleError
from vehicle.keys import Mode

logger = logging.getLogger(__name__)

#: the kernel's own settings (paths and the loop), always first
KERNEL_SETTINGS = "vehicle.settings"
#: DonkeyCar settings that have another name here, so a copied myconfig.py gets a precise hint
RENAMED: dict[str, str] = {
    "WEB_INIT_MODE": "DEFAULT_MODE",
    # DonkeyCar's setting for its simulator, which a copied myconfig.py brings along; the closest
    # name by spelling (DONKEY_GYM_ENV_NAME) misleads
    "DONKEY_GYM": 'SIM_TYPE = "donkey"',
}


class ConfigError(VehicleError, ValueError):
    """A setting is unknown, of the wrong type or out of range, or the override file cannot be
    read. The message is one line: file, line, setting, what is valid."""


class SettingTypeError(ConfigError, TypeError):
    """A setting's value has the wrong type (a TypeError too, for code that builds parts)."""


@dataclass(frozen=True)
class Setting:
    """One declared setting: its type, default expression, documentation and where it is declared."""

    name: str
    annotation: str
    expression: ast.expr
    doc: str
    section: str
    line: int
    module: str = KERNEL_SETTINGS  # the settings module that declares it

    @property
    def path(self) -> Path:
        """The file that declares it."""
        return Path(_module(self.module).__file__ or "")


def settings_modules(roots: Sequence[str] | None = None) -> list[str]:
    """The settings modules: the kernel's, then every ``settings.py`` in a package under ``roots``
    (:func:`vehicle.discovery.family_modules`). A new family adds its own settings.py."""
    return [KERNEL_SETTINGS, *family_modules("settings.py", roots)]


@cache
def _module(name: str) -> types.ModuleType:
    return importlib.import_module(name)


@cache
def settings() -> dict[str, Setting]:
    """Every declared setting, module by module (:func:`settings_modules`), each in file order."""
    found: dict[str, Setting] = {}
    for module in settings_modules():
        for name, setting in parse_settings(module).items():
            if name in found:
                raise RuntimeError(f"{setting.path}, line {setting.line}: setting {name} is already declared "
                                   f"in {found[name].path}, line {found[name].line}; declare each setting once")
            found[name] = setting
    return found


def parse_settings(module: str) -> dict[str, Setting]:
    """The settings one settings module declares, in file order."""
    source = Path(_module(module).__file__ or "").read_text()
    lines = source.splitlines()
    found: dict[str, Setting] = {}
    section = ""
    section_at = {i: ln.strip()[4:-3].strip() for i, ln in enumerate(lines, 1) if _is_section(ln)}
    for node in ast.parse(source).body:
        if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
            continue
        name = node.target.id
        if not name.isupper() or name == "RULES" or node.value is None:
            continue
        section = next((section_at[i] for i in range(node.lineno, 0, -1) if i in section_at), section)
        doc: list[str] = []
        i = node.lineno - 2
        while i >= 0 and lines[i].lstrip().startswith("#") and not _is_section(lines[i]):
            doc.insert(0, lines[i].strip().lstrip("#").strip())
            i -= 1
        found[name] = Setting(name, ast.unparse(node.annotation), node.value, " ".join(doc), section,
                              node.lineno, module)
    return found


@cache
def rules() -> tuple[Rule, ...]:
    """The rules across settings: each settings module's ``RULES``, in module order."""
    return tuple(rule for module in settings_modules() for rule in getattr(_module(module), "RULES", ()))


@cache
def _evaluation_order() -> tuple[str, ...]:
    """Settings ordered so that every derived one comes after the settings its expression names."""
    known = settings()
    done: dict[str, None] = {}
    visiting: set[str] = set()

    def visit(name: str) -> None:
        if name in done:
            return
        if name in visiting:
            raise RuntimeError(f"setting {name} is derived from itself through {sorted(visiting)}")
        visiting.add(name)
        for n in ast.walk(known[name].expression):
            if isinstance(n, ast.Name) and n.id in known and n.id != name:
                visit(n.id)
        visiting.discard(name)
        done[name] = None

    for name in known:
        visit(name)
    return tuple(done)


def _is_section(line: str) -> bool:
    s = line.strip()
    return s.startswith("# ==") and s.endswith("==")


@cache
def _type_of(name: str) -> Any:
    """The annotation of setting ``name``, evaluated in the namespace of the module declaring it."""
    setting = settings()[name]
    return eval(setting.annotation, dict(vars(_module(setting.module))))  # noqa: S307 - our own declarations


def _matches(value: Any, tp: Any) -> bool:
    """Whether ``value`` fits the annotation ``tp`` (the subset of typing used by the defaults)."""
    if tp is Any:
        return True
    if tp is None or tp is type(None):
        return value is None
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin is Annotated:
        return _matches(value, args[0])
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
    """The annotation as users read it: without its range, the drive-mode type spelt as its values."""
    modes = " | ".join(f'"{m.value}"' for m in Mode)
    return type_text(annotation).replace("list[Mode]", f"list[{modes}]").replace("Mode", modes)


def setting_type(name: str) -> Any:
    """The annotation of setting ``name``, evaluated (``Annotated[int, Range(1)]``: with its metadata)."""
    return _type_of(name)


@cache
def constraints(name: str) -> tuple[Constraint, ...]:
    """The ranges a setting declares in its annotation (``Annotated[int, Range(1, 1000)]``)."""
    tp = _type_of(name)
    if typing.get_origin(tp) is not Annotated:
        return ()
    return tuple(m for m in tp.__metadata__ if isinstance(m, Range | Length | Checked | OneOf))


def check_range(name: str, value: Any, where: str = "") -> None:
    """Raise ConfigError when ``value`` is outside the range ``name`` declares."""
    for c in constraints(name):
        why = c.problem(value)
        if why:
            raise ConfigError(f"{where}{c.show(name, value)} {why}; valid: {c.describe()}.")


def check_value(name: str, value: Any, where: str = "") -> None:
    """Raise ConfigError unless ``name`` is a known setting and ``value`` fits its type and range."""
    known = settings()
    if name not in known:
        close = _closest(name)
        hint = f" Did you mean {close}?" if close else ""
        raise ConfigError(f"{where}unknown setting {name}.{hint} "
                          "See docs/config.md for every setting.")
    setting = known[name]
    if not _matches(value, _type_of(name)):
        raise SettingTypeError(f"{where}{name} = {value!r} has type {type(value).__name__}, "
                               f"expected {describe_type(setting.annotation)}.")
    check_range(name, value, where)


def check_settings(**values: Any) -> None:
    """Raise ConfigError unless each value fits the setting it is named for (its type and range).

    A part's constructor checks its arguments with it, ``check_settings(LIDAR_BINS=bins)``, so a
    bound is written once, in the setting's annotation, and a part built from code fails with the
    same one-line message as a bad myconfig.py. A value in another unit than the setting's is
    passed converted (``MM_PER_TICK=m_per_tick * 1000``).
    """
    for name, value in values.items():
        if type(value).__module__ == "numpy" and hasattr(value, "item"):
            value = value.item()  # a numpy number is the number it holds
        if isinstance(value, float) and value.is_integer() and name in settings() \
                and not _matches(value, _type_of(name)):
            value = int(value)  # 20.0 frames per second for an int setting: the same number
        check_value(name, value)


def _closest(name: str) -> str | None:
    """The setting an unknown ``name`` most likely means (a DonkeyCar rename, else by spelling)."""
    if name in RENAMED:
        return RENAMED[name]
    close = difflib.get_close_matches(name, settings(), n=1)
    return close[0] if close else None


def _check_known(path: Path, names: Sequence[str], lines: Mapping[str, int]) -> None:
    """Name every unknown setting of a config file in one message (a myconfig.py copied from
    DonkeyCar brings several: fixing them one run at a time would be tedious)."""
    unknown = [n for n in names if n not in settings()]
    if len(unknown) < 2:
        return  # none, or one: check_value says it with its line
    shown = []
    for name in sorted(unknown, key=lambda n: lines.get(n, 0)):
        close = _closest(name)
        line = f"line {lines[name]}" if name in lines else "set indirectly"
        shown.append(f"{name} ({line}{f'; did you mean {close}?' if close else ''})")
    raise ConfigError(f"{path}: {len(unknown)} unknown settings: {', '.join(shown)}. Rename or delete them; "
                      "docs/config.md lists every setting.")


def type_text(annotation: str) -> str:
    """An annotation without its range: ``Annotated[int, Range(1, 10)]`` -> ``int``."""
    tree = ast.parse(annotation, mode="eval").body
    if isinstance(tree, ast.Subscript) and isinstance(tree.value, ast.Name) and tree.value.id == "Annotated":
        inner = tree.slice.elts[0] if isinstance(tree.slice, ast.Tuple) else tree.slice
        return ast.unparse(inner)
    return annotation


def check_config(values: Mapping[str, Any], overridden: frozenset[str],
                 where: Callable[..., str] = lambda *names: "") -> None:
    """Check the values the overrides did not set (derived ones may leave their range when the
    settings they follow change) and the rules across settings (:data:`RULES`).

    ``where(*names)`` gives the message prefix (file and line) of the first of ``names`` the
    user set.
    """
    for name in settings():
        if name not in overridden:
            check_range(name, values[name], where(name))
    for rule in rules():
        for problem in rule(values):
            raise ConfigError(f"{where(problem.setting, *problem.related)}{problem.message}.")


class Config(Mapping[str, Any]):
    """The settings of one car, read as attributes (``cfg.DRIVE_LOOP_HZ``) like DonkeyCar's."""

    def __init__(self, values: dict[str, Any], overridden: frozenset[str] = frozenset(),
                 source: Path | None = None, lines: Mapping[str, int] | None = None) -> None:
        object.__setattr__(self, "_values", values)
        object.__setattr__(self, "overridden", overridden)
        object.__setattr__(self, "source", source)
        object.__setattr__(self, "lines", dict(lines or {}))  # override -> its line in source

    @classmethod
    def defaults(cls, **overrides: Any) -> Config:
        """The package defaults with ``overrides`` applied and validated (for code and tests)."""
        for name, value in overrides.items():
            check_value(name, value)
        return cls.build(overrides)

    @classmethod
    def build(cls, overrides: dict[str, Any], source: Path | None = None,
              lines: Mapping[str, int] | None = None) -> Config:
        """Evaluate the defaults with ``overrides`` (each already checked on its own) and check
        the result as a whole; errors point at ``source``'s ``lines``."""
        values = _evaluate(overrides)
        cfg = cls(values, frozenset(overrides), source, lines)
        check_config(values, cfg.overridden, cfg.where)
        return cfg

    def where(self, *names: str) -> str:
        """``"FILE, line N: "`` of the first of ``names`` the user set in the override file (for a
        derived setting: of a setting it follows), or "" when none was."""
        seen: set[str] = set()
        todo = list(names)
        while todo:
            name = todo.pop(0)
            if name in seen:
                continue
            seen.add(name)
            if name in self.lines and self.source is not None:
                return f"{self.source}, line {self.lines[name]}: "
            if name not in self.overridden and name in settings():
                todo += [n.id for n in ast.walk(settings()[name].expression) if isinstance(n, ast.Name)]
        return ""

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
        lines = {n: line for n, line in self.lines.items() if n not in overrides}
        return Config.build(merged, self.source, lines)


def _evaluate(overrides: dict[str, Any]) -> dict[str, Any]:
    """Evaluate the defaults, each after the settings it follows, taking overrides where given, so
    derived values follow; the result is in declaration order."""
    namespace: dict[str, Any] = {}
    known = settings()
    for name in _evaluation_order():
        if name in overrides:
            namespace[name] = overrides[name]
        else:
            setting = known[name]
            code = compile(ast.Expression(setting.expression), str(setting.path), "eval")
            module_globals = dict(vars(_module(setting.module)))
            namespace[name] = eval(code, module_globals, dict(namespace))  # noqa: S307 - our own declarations
    return {name: namespace[name] for name in known}


def read_overrides_with_lines(path: Path) -> tuple[dict[str, Any], dict[str, int]]:
    """Run a myconfig.py file: its UPPERCASE names, each validated, and the line of each name's last
    assignment (the one in effect when a file sets a name twice)."""
    try:
        source = path.read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the config file ({exc.strerror}).") from exc
    try:
        tree = ast.parse(source, filename=str(path))
    except SyntaxError as exc:
        raise ConfigError(f"{path}, line {exc.lineno}: invalid Python: {exc.msg}.") from exc
    lines: dict[str, int] = {}
    for node in sorted(ast.walk(tree), key=lambda n: getattr(n, "lineno", 0)):
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        for t in targets:
            if isinstance(t, ast.Name) and t.id.isupper():
                lines[t.id] = t.lineno
        if isinstance(node, ast.FunctionDef | ast.ClassDef) and node.name.isupper():
            lines[node.name] = node.lineno
    namespace: dict[str, Any] = {"__file__": str(path), "__name__": "myconfig"}
    try:
        exec(compile(tree, str(path), "exec"), namespace)  # noqa: S102 - the user's own config file
    except Exception as exc:
        raise ConfigError(f"{path}: running the config file failed: {type(exc).__name__}: {exc}") from exc
    overrides = {k: v for k, v in namespace.items() if k.isupper()}
    _check_known(path, list(overrides), lines)
    for name, value in overrides.items():
        where = f"{path}, line {lines[name]}: " if name in lines else f"{path}: "
        check_value(name, value, where)
    return overrides, {k: v for k, v in lines.items() if k in overrides}


def load_config(myconfig: str | os.PathLike[str] | None = None,
                car_path: str | os.PathLike[str] | None = None) -> Config:
    """Load defaults plus a car's overrides.

    Args:
        myconfig: the override file; default ``<car_path>/myconfig.py``. A relative path is taken
            relative to ``car_path`` when that is given, else to the current directory.
        car_path: the car folder; default the folder of ``myconfig``, else the current directory.

    Raises:
        ConfigError: the file is missing or invalid, a name is unknown, a value has the wrong type
            or is out of range, or settings contradict each other (one line: file, line, setting,
            what is valid).
    """
    if car_path is None and myconfig:  # the file names its car: relative to the current folder
        path = Path(myconfig).expanduser().resolve()
        car = path.parent
    else:
        car = Path(car_path).expanduser().resolve() if car_path is not None else Path.cwd()
        path = car / (myconfig or "myconfig.py")
    if not path.is_file():
        if myconfig is not None:
            raise ConfigError(f"{path}: no such config file. Pass an existing file to --myconfig.")
        logger.warning("%s not found: using the default settings", path)
        overrides: dict[str, Any] = {}
        lines: dict[str, int] = {}
    else:
        overrides, lines = read_overrides_with_lines(path)
    overrides.setdefault("CAR_PATH", str(car))
    return Config.build(overrides, path, lines)
