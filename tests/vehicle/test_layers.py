"""Dependencies point one way: kernel (vehicle/*.py) <- parts/ <- training/ <- application (vehicle/app/).

Every import counts, including the ones inside functions (they only hide a cycle), so the rules are
checked on the syntax tree of every module, not by importing it.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def module_name(path: Path, root: Path = ROOT) -> str:
    """``parts/sim/track.py`` -> ``parts.sim.track`` (a package's ``__init__`` is the package)."""
    parts = list(path.relative_to(root).with_suffix("").parts) if path.is_relative_to(root) else [path.stem]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path, root: Path = ROOT) -> set[str]:
    """Every module name ``path`` imports, at any depth of the file: import statements (relative
    ones resolved) and string literals given to ``importlib.import_module`` / ``__import__``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*anchor, *([base] if base else [])])
            names.add(base)
            # `from vehicle import app` imports the module vehicle.app
            names.update(f"{base}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Call) and node.args and (
                getattr(node.func, "attr", None) == "import_module" or getattr(node.func, "id", None) in (
                    "import_module", "__import__")):
            first = node.args[0]
            if isinstance(first, ast.Constant) and isinstance(first.value, str):
                names.add(first.value)
            elif isinstance(first, ast.JoinedStr) and first.values and isinstance(first.values[0], ast.Constant):
                names.add(str(first.values[0].value).rstrip("."))  # f"parts.tub.{name}": its prefix
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


def test_the_checker_resolves_relative_and_dynamic_imports(tmp_path):
    probe = tmp_path / "vehicle" / "_layer_probe.py"  # a module of the package vehicle, in a temporary root
    probe.parent.mkdir()
    probe.write_text("from .app.cli import main\nfrom . import keys\nimport importlib\n"
                     "importlib.import_module('parts.sim.track')\nimportlib.import_module(f'vehicle.app.{1}')\n")
    found = imports_of(probe, root=tmp_path)
    assert {"vehicle.app.cli", "vehicle.keys", "parts.sim.track", "vehicle.app"} <= found


@pytest.mark.parametrize(("folder", "pattern", "forbidden"), [
    ("vehicle", "*.py", ("parts", "vehicle.app", "training")),  # the kernel
    ("parts", "**/*.py", ("vehicle.app", "training")),
    # training uses parts and is used by the application
    ("training", "**/*.py", ("vehicle.app",)),
    # library code raises its own VehicleError subclasses; UserError is the application's
    ("parts", "**/*.py", ("vehicle.errors.UserError",)),
    ("parts/sim", "**/*.py", ("parts.pilots",)),
    ("parts/pilots", "**/*.py", ("parts.sim",)),
])
def test_dependencies_point_one_way(folder, pattern, forbidden):
    paths = modules(folder, pattern)
    assert paths, f"no modules found under {folder}"
    assert offending(paths, forbidden) == {}
