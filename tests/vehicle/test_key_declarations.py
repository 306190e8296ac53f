"""One style of declaring a part's keys, everywhere (vehicle/keys.py's docstring, vehicle/part.py):

- fixed keys: ``INPUTS: ClassVar[tuple[str, ...]] = ("a/b", ...)`` in the class body, a tuple of
  string literals (or an expression of the class's own declarations: ``OPTIONAL_INPUTS = INPUTS[1:]``);
- keys that depend on how the part was built: a read-only ``@property`` returning such a tuple;
- never an attribute assigned per instance (``self.INPUTS = ...``), never a list, never ``Final``;
  a car wires other keys with ``rename`` when it adds the part.

Checked on the source of every part in the library, the application and the templates (so every
table row and every template part), and at run time on the rows of every family table.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DECLARATIONS = ("INPUTS", "OUTPUTS", "OPTIONAL_INPUTS", "FEEDBACK")
ANNOTATION = "ClassVar[tuple[str, ...]]"
SOURCES = sorted(p for d in ("parts", "vehicle", "training", "templates") for p in (ROOT / d).rglob("*.py"))


def _own_names(value: ast.expr, earlier: set[str]) -> bool:
    """A tuple of string literals, or an expression over the class's earlier declarations only."""
    if isinstance(value, ast.Tuple):
        return all(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in value.elts)
    names = [n for n in ast.walk(value) if isinstance(n, ast.Name)]
    calls = [n for n in ast.walk(value) if isinstance(n, ast.Call | ast.Attribute)]
    return bool(names) and not calls and all(n.id in earlier for n in names)


def style_problems(source: str, where: str) -> list[str]:
    """Where ``source`` declares keys in another style than the one above."""
    problems = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ClassDef):
            earlier: set[str] = set()
            for item in node.body:
                if isinstance(item, ast.Assign | ast.AugAssign):
                    targets = item.targets if isinstance(item, ast.Assign) else [item.target]
                    bad = [t.id for t in targets if isinstance(t, ast.Name) and t.id in DECLARATIONS]
                    problems += [f"{where}:{item.lineno} {node.name}.{b}: annotate it {ANNOTATION}" for b in bad]
                elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name) \
                        and item.target.id in DECLARATIONS:
                    name = f"{where}:{item.lineno} {node.name}.{item.target.id}"
                    if ast.unparse(item.annotation) != ANNOTATION:
                        problems.append(f"{name}: annotate it {ANNOTATION}, not {ast.unparse(item.annotation)}")
                    if item.value is None or not _own_names(item.value, earlier):
                        problems.append(f"{name}: a tuple of key strings written here, or a property")
                    earlier.add(item.target.id)
                elif isinstance(item, ast.FunctionDef) and item.name in DECLARATIONS \
                        and not any(ast.unparse(d) == "property" for d in item.decorator_list):
                    problems.append(f"{where}:{item.lineno} {node.name}.{item.name}: make it a @property")
        elif isinstance(node, ast.Assign | ast.AnnAssign | ast.AugAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            problems += [f"{where}:{node.lineno} .{t.attr} assigned per instance: declare it on the class "
                         "(a property when it depends on how the part was built)"
                         for t in targets if isinstance(t, ast.Attribute) and t.attr in DECLARATIONS]
    return problems


def test_the_style_check_finds_each_other_style():
    source = '''
class A:
    INPUTS = ("a/b",)
    OUTPUTS: Final = ("a/c",)
    FEEDBACK: ClassVar[tuple[str, ...]] = ["a/b"]
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = SOME_CONSTANT
    def __init__(self, key):
        self.INPUTS = (key,)
class B:
    INPUTS: ClassVar[tuple[str, ...]] = ("a/b", "a/c")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = INPUTS[1:]
    def OUTPUTS(self):
        return ()
class C:
    OUTPUTS: ClassVar[tuple[str, ...]] = OUTPUTS  # a module constant
'''
    found = style_problems(source, "x.py")
    assert [p.split(" ", 1)[1].split(":")[0] for p in found] == [
        "A.INPUTS", "A.OUTPUTS", "A.FEEDBACK", "A.OPTIONAL_INPUTS", "B.OUTPUTS", "C.OUTPUTS",
        ".INPUTS assigned per instance"]


def test_every_part_declares_its_keys_in_the_one_style():
    problems = [p for path in SOURCES for p in style_problems(path.read_text(), str(path.relative_to(ROOT)))]
    assert problems == []


@pytest.mark.parametrize("attr", DECLARATIONS)
def test_every_table_row_declares_tuples_or_properties(attr):
    from parts.actuators.registry import DRIVETRAINS
    from parts.bridges.registry import SIMULATORS
    from parts.cameras.registry import CAMERAS
    from parts.sensors.registry import SENSOR_TABLES

    for table in (CAMERAS, DRIVETRAINS, SIMULATORS, *SENSOR_TABLES):
        for name in table:
            cls = table.load(name)
            declared = next((vars(k)[attr] for k in cls.__mro__ if attr in vars(k)), None)
            assert declared is None or isinstance(declared, tuple | property), f"{table.setting} {name}: {attr}"
