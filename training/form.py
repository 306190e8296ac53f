"""The form field a training setting carries in its annotation: the trainer console's field and
``vehicle train``'s option, declared once beside the setting (:mod:`training.hyperparams` reads it)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Form:
    """A setting that is also a field of a form and a command-line option (the training settings in
    the trainer console and ``vehicle train``), declared once in its annotation::

        MAX_EPOCHS: Annotated[int, Range(1), Form("epochs", "Epochs", "Optimisation",
                                                  why="training needs at least one epoch")] = 100

    The field's kind, bounds and choices come from the type and the range, its help from the
    setting's comment. ``name``: the field (and ``--name`` option, unless ``flag``); ``why``: the
    reason for the bounds, shown with an invalid value; ``kind``: only where the type cannot say
    ("device", or "choice" for a name checked against a db); ``help`` and ``complement``:
    for a field that shows ``1 - setting`` (the validation share of TRAIN_TEST_SPLIT).
    """

    name: str
    label: str
    group: str
    why: str = ""
    flag: str = ""
    kind: str = ""
    help: str = ""
    complement: bool = False
