"""Declared shapes: a part says the shape of what it makes and of what it expects, and the wiring
check compares them before the first loop (LeRobot's ``observation_features``).

A part declares, as class attributes or properties, mappings from its own keys to shapes (tuples of
ints, None for a dimension it does not fix):

- ``OUTPUT_SHAPES``: of its outputs (a camera: ``{"cam/image_array": (120, 160, 3)}``);
- ``INPUT_SHAPES``: of the inputs it expects (a pilot: the frames its model was trained on).

Keys are the part's own (its ``INPUTS`` / ``OUTPUTS``); when the car wires it to other keys the
declaration follows the renaming. A key whose producer declares no shape is not checked.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from vehicle.vehicle import declared_keys

Shape = tuple[int | None, ...]


def declared_shapes(part: Any, attr: str, own_keys: str, wired: Sequence[str]) -> dict[str, Shape]:
    """``part``'s ``attr`` (``OUTPUT_SHAPES`` or ``INPUT_SHAPES``) keyed by the wired keys: its own
    keys (``own_keys``: ``"OUTPUTS"`` or ``"INPUTS"``) renamed as the car wired them (``wired``)."""
    shapes = declared_keys(part, attr)
    if not isinstance(shapes, Mapping):
        return {}
    own = declared_keys(part, own_keys)
    rename = dict(zip(own, wired, strict=True)) if isinstance(own, list | tuple) and len(own) == len(wired) else {}
    return {rename.get(key, key): tuple(shape) for key, shape in shapes.items() if shape is not None}


def fits(expected: Shape, made: Shape) -> bool:
    """Whether ``made`` fits ``expected`` (same rank; a None dimension on either side fits any)."""
    return len(expected) == len(made) and all(e is None or m is None or e == m for e, m in zip(expected, made,
                                                                                              strict=True))


def show(shape: Shape) -> str:
    """``(120, 160, 3)`` as ``120x160x3`` (``?`` for a free dimension)."""
    return "x".join("?" if d is None else str(d) for d in shape)


def shape_problems(entries: Iterable[Any]) -> list[str]:
    """Every input whose expected shape the shape of its producer's output does not fit.

    ``entries`` are the vehicle's parts in run order (``part``, ``name``, ``inputs``, ``outputs``,
    ``feedback``); an input is made by the last part before it that outputs the key, or, for a
    declared feedback input, by the last part of the loop that does.
    """
    entries = list(entries)
    made_by: list[dict[str, tuple[Shape, str]]] = []
    latest: dict[str, tuple[Shape, str]] = {}
    for e in entries:
        for key, shape in declared_shapes(e.part, "OUTPUT_SHAPES", "OUTPUTS", e.outputs).items():
            if key in e.outputs:
                latest[key] = (shape, e.name)
        made_by.append(dict(latest))
    problems = []
    for i, e in enumerate(entries):
        for key, expected in declared_shapes(e.part, "INPUT_SHAPES", "INPUTS", e.inputs).items():
            before = made_by[i - 1] if i else {}
            source = latest.get(key) if key in e.feedback else before.get(key)
            if source is not None and not fits(expected, source[0]):
                problems.append(f"part {e.name!r} expects {key} of {show(expected)} but part {source[1]!r} makes "
                                f"{show(source[0])}: make the two agree (the size settings of {source[1]!r}) or give "
                                f"{e.name!r} one made for {show(source[0])}")
    return problems
