"""Finding what the families declare beside their parts, with no list to keep.

A family (``parts/cameras``, ``parts/sensors``, ``training``, ``vehicle/app/console`` ...) declares
its settings in a ``settings.py``, its memory keys in a ``keys.py`` and its part tables in a
``registry.py`` of its own package. The kernel finds them by walking the packages that installed
distributions name in the ``vehicle.families`` entry-point group (this project names ``parts``,
``training`` and ``vehicle.app`` in its pyproject.toml; a third-party package of parts names its
own), by file name, never by importing them: the kernel knows no client, a new family is found as
soon as its folder, with an ``__init__.py``, has such a module, and an installed package of parts
is found by being installed.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.util
from collections.abc import Sequence
from functools import cache
from pathlib import Path
from typing import Any

from vehicle.errors import VehicleError

#: the entry-point group whose values are the packages to walk (``parts = "parts"``)
FAMILY_GROUP = "vehicle.families"


class DiscoveryError(VehicleError):
    """No family is installed, or a declared family package cannot be found."""


@cache
def family_roots() -> tuple[str, ...]:
    """The packages of the ``vehicle.families`` entry points: those of the distribution this
    kernel belongs to first (in its entry-point order), then other distributions' by distribution
    and entry-point name, so settings, keys and tables are found in the same order everywhere.

    Raises:
        DiscoveryError: none is declared (the project is not installed: ``pip install -e .``).
    """
    # every distribution's, not entry_points()'s first per name: a stale egg-info left in a
    # checkout (an old editable install) would hide the installed metadata from a run started there
    kernel = set(importlib.metadata.packages_distributions().get(__name__.split(".")[0], ()))
    own: list[str] = []
    others: list[tuple[str, str, str]] = []
    for dist in importlib.metadata.distributions():
        name = dist.metadata["Name"] or ""
        for ep in dist.entry_points.select(group=FAMILY_GROUP):
            if name in kernel:
                own.append(ep.value)
            else:
                others.append((name, ep.name, ep.value))
    roots = own + [value for *_, value in sorted(others)]
    if not roots:
        raise DiscoveryError(f"no package declares the '{FAMILY_GROUP}' entry points: install the project "
                             "(python3 bootstrap.py, or pip install -e . in the checkout)")
    return tuple(dict.fromkeys(roots))


def family_modules(file_name: str, roots: Sequence[str] | None = None) -> list[str]:
    """The dotted names of every module ``file_name`` (``"settings.py"``, ``"keys.py"``) in a package
    under ``roots`` (default: :func:`family_roots`), root by root, each root's by path. A folder
    without ``__init__.py`` (web assets, data) and everything under it is not a package and is
    skipped. Nothing is imported but the roots' specs."""
    return list(_walk(file_name, family_roots() if roots is None else tuple(roots)))


@cache
def _walk(file_name: str, roots: tuple[str, ...]) -> tuple[str, ...]:
    names: list[str] = []
    for root in roots:
        spec = importlib.util.find_spec(root)
        for folder in (spec.submodule_search_locations or []) if spec else []:
            for path in sorted(Path(folder).rglob(file_name)):
                rel = path.relative_to(folder)
                if all((Path(folder) / p / "__init__.py").is_file() for p in rel.parents):
                    name = ".".join((root, *rel.with_suffix("").parts))
                    if name not in names:
                        names.append(name)
    return tuple(names)


def family_declarations(file_name: str, attribute: str) -> list[tuple[str, Any]]:
    """(module name, value) of ``attribute`` in every family module ``file_name`` that defines it
    (``("registry.py", "SENSOR_TABLES")``), in :func:`family_modules` order; the modules are
    imported now."""
    found = []
    for name in family_modules(file_name):
        value = getattr(importlib.import_module(name), attribute, None)
        if value is not None:
            found.append((name, value))
    return found
