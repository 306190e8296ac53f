"""Dependencies point one way: kernel (vehicle/*.py) <- parts/ <- application (vehicle/app/).

Every import counts, including the ones inside functions (they only hide a cycle), so the rules are
checked on the syntax tree of every module, not by importing it.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def imports_of(path: Path) -> set[str]:
    """Every module name ``path`` imports, at any depth of the file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            # `from vehicle import app` imports the module vehicle.app
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def modules(folder: str, pattern: str = "**/*.py") -> list[Path]:
    # vehicle/__main__.py is the `python -m vehicle` entry point: it starts the application
    return sorted(p for p in (ROOT / folder).glob(pattern) if p.name != "__main__.py")


def offending(paths: list[Path], forbidden: tuple[str, ...]) -> dict[str, list[str]]:
    """{file: [imports starting with one of ``forbidden``]} for the files that have any."""
    found = {}
    for path in paths:
        bad = sorted(n for n in imports_of(path) if any(n == f or n.startswith(f + ".") for f in forbidden))
        if bad:
            found[str(path.relative_to(ROOT))] = bad
    return found


def test_the_checker_sees_imports_inside_functions(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from vehicle import app\n    import parts.sim.track\n")
    assert {"vehicle.app", "parts.sim.track"} <= imports_of(module)


@pytest.mark.parametrize(("folder", "pattern", "forbidden"), [
    ("vehicle", "*.py", ("parts", "vehicle.app")),  # the kernel
    ("parts", "**/*.py", ("vehicle.app",)),
    # library code raises its own VehicleError subclasses; UserError is the application's
    ("parts", "**/*.py", ("vehicle.errors.UserError",)),
    ("parts/sim", "**/*.py", ("parts.pilots",)),
    ("parts/pilots", "**/*.py", ("parts.sim",)),
])
def test_dependencies_point_one_way(folder, pattern, forbidden):
    paths = modules(folder, pattern)
    assert paths, f"no modules found under {folder}"
    assert offending(paths, forbidden) == {}
