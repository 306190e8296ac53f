"""Behaviour state: which of a list of behaviours (e.g. Left_Lane / Right_Lane) the car should show.

As in DonkeyCar's BehaviorPart and the thesis seed: the active behaviour is recorded with every
tub record as ``behavior/state`` (index), ``behavior/label`` (name) and
``behavior/one_hot_state_array`` ([1.0, 0.0] for the first of two), and a behaviour pilot takes
the one-hot array as an extra input. A gamepad button steps through the list (``behavior/step``).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import ClassVar

logger = logging.getLogger(__name__)


class BehaviorState:
    """The active behaviour of ``behaviors``.

    Input: ``behavior/step`` (+1 next, -1 previous, 0/None nothing; optional).
    Outputs: ``behavior/state, behavior/label, behavior/one_hot_state_array``.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("behavior/step",)
    #: a car without behaviour buttons has no step: the state stays where it is
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("behavior/step",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("behavior/state", "behavior/label", "behavior/one_hot_state_array")

    def __init__(self, behaviors: Sequence[str], initial: int | str = 0) -> None:
        names = list(behaviors)
        if not names:
            raise ValueError("BEHAVIOR_LIST is empty; give at least one behaviour, "
                             "e.g. ['Left_Lane', 'Right_Lane']")
        if len(set(names)) != len(names):
            raise ValueError(f"BEHAVIOR_LIST {names} has duplicate names")
        for n in names:
            if not isinstance(n, str) or not n:
                raise TypeError(f"behaviour names must be non-empty strings, got {n!r} in {names}")
        self.behaviors = names
        self.state = 0
        self.set_state(initial)

    def set_state(self, state: int | str) -> None:
        """Select a behaviour by index or name."""
        if isinstance(state, str):
            if state not in self.behaviors:
                raise ValueError(f"unknown behaviour {state!r}; BEHAVIOR_LIST is {self.behaviors}")
            state = self.behaviors.index(state)
        if isinstance(state, bool) or not isinstance(state, int) or not 0 <= state < len(self.behaviors):
            raise ValueError(f"behaviour index {state!r} must be 0..{len(self.behaviors) - 1}")
        if state != self.state:
            logger.info("behaviour: %s", self.behaviors[state])
        self.state = state

    def increment_state(self) -> None:
        """Next behaviour (wraps around)."""
        self.set_state((self.state + 1) % len(self.behaviors))

    def decrement_state(self) -> None:
        """Previous behaviour (wraps around)."""
        self.set_state((self.state - 1) % len(self.behaviors))

    def one_hot(self) -> list[float]:
        """One-hot encoding of the active behaviour."""
        return [1.0 if i == self.state else 0.0 for i in range(len(self.behaviors))]

    def run(self, step: int | None = None) -> tuple[int, str, list[float]]:
        """Apply a step request, then return (state, label, one_hot)."""
        if step:
            if step > 0:
                self.increment_state()
            else:
                self.decrement_state()
        return self.state, self.behaviors[self.state], self.one_hot()
