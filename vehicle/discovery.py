"""Finding what the families declare beside their parts, with no list to keep.

A family (``parts/cameras``, ``parts/sensors``, ``training``, ``vehicle/app/console`` ...) declares
its settings in a ``settings.py`` and its memory keys in a ``keys.py`` of its own package. The
kernel finds them by walking the packages under :data:`FAMILY_ROOTS` by name, never by importing
``parts`` (the kernel sits below the parts): a new family is found as soon as its folder, with an
``__init__.py``, has such a module.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from pathlib import Path

#: packages whose every sub-package, at any depth, may declare settings and keys; generated docs
#: list the modules found in this order, each root's modules by path
FAMILY_ROOTS: tuple[str, ...] = ("parts", "training", "vehicle.app")


def family_modules(file_name: str, roots: Sequence[str] = FAMILY_ROOTS) -> list[str]:
    """The dotted names of every module ``file_name`` (``"settings.py"``, ``"keys.py"``) in a package
    under ``roots``, root by root, each root's by path. A folder without ``__init__.py`` (web assets,
    data) and everything under it is not a package and is skipped. Nothing is imported but the roots'
    specs."""
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
    return names
