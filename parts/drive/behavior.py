"""Behaviour state: which of a list of behaviours (e.g. Left_Lane / Right_Lane) the car should show.

As in DonkeyCar's BehaviorPart and the thesis seed: the active behaviour is recorded with every
tub record as ``behavior/state`` (index), ``behavior/label`` (name) and
``behavior/one_hot_state_array`` ([1.0, 0.0] for the first of two), and a behaviour pilot takes
the one-hot array as an extra input. A gamepad button or the web page steps through the list
(``behavior/step``); :class:`BehaviorSchedule` steps it at given times (lane changes on demand
in recordings and evaluations).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import ClassVar

import numpy as np

logger = logging.getLogger(__name__)


class BehaviorState:
    """The active behaviour of ``behaviors``.

    Inputs: ``behavior/step`` (gamepad buttons, a schedule) and ``web/behavior_step`` (the web
    page's "change lane" button): +1 next, -1 previous, 0/None nothing; their sum is applied.
    Outputs: ``behavior/state, behavior/label, behavior/one_hot_state_array``.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("behavior/step", "web/behavior_step")
    #: a car without behaviour buttons (or without the web page) has no step: the state stays
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("behavior/step", "web/behavior_step")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("behavior/state", "behavior/label", "behavior/one_hot_state_array")
    #: as DonkeyCar: a car with behaviours (TRAIN_BEHAVIORS) records them with every frame
    RECORDED: ClassVar[Mapping[str, str]] = dict(zip(OUTPUTS, ("int", "str", "vector"), strict=True))

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

    def run(self, step: int | None = None, *more_steps: int | None) -> tuple[int, str, list[float]]:
        """Apply the step requests (several controllers' steps add up), then return (state, label,
        one_hot)."""
        total = sum(int(s) for s in (step, *more_steps) if s)
        for _ in range(abs(total)):
            if total > 0:
                self.increment_state()
            else:
                self.decrement_state()
        return self.state, self.behaviors[self.state], self.one_hot()


def behavior_lane(name: str) -> str | None:
    """The lane a behaviour name asks for: "left", "right" or "center" (Left_Lane -> left), or
    None when the name says no lane."""
    n = name.lower()
    for lane, words in (("left", ("left",)), ("right", ("right",)), ("center", ("center", "centre", "middle"))):
        if any(w in n for w in words):
            return lane
    return None


class BehaviorSchedule:
    """Part: step the behaviour at given times (commanded lane changes in recordings and tests).

    Outputs ``behavior/step`` (+1 on the loop where a change is due, else 0); counts loops of
    ``dt`` seconds, so in simulated time the schedule is exact. Use :func:`random_change_times`
    for the times.

    Args:
        times: seconds after the start at which to step (any order).
        dt: seconds per loop (1 / DRIVE_LOOP_HZ).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ()
    OUTPUTS: ClassVar[tuple[str, ...]] = ("behavior/step",)

    def __init__(self, times: Sequence[float], dt: float) -> None:
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s, got {dt}")
        self.dt = float(dt)
        # loop index of each change (rounded), sorted; duplicates collapse into one step
        self.due = sorted({max(1, int(round(t / self.dt))) for t in times})
        self.loop = 0
        self.steps_done = 0

    def run(self) -> int:
        """+1 on a loop where a change is due, else 0."""
        self.loop += 1
        if self.steps_done < len(self.due) and self.loop >= self.due[self.steps_done]:
            self.steps_done += 1
            return 1
        return 0


def random_change_times(n: int, duration: float, *, seed: int = 0, min_gap: float = 6.0,
                        start: float = 3.0) -> list[float]:
    """``n`` seeded times in (``start``, ``duration``) at least ``min_gap`` seconds apart (the
    time to complete a change), otherwise uniformly random.

    Raises:
        ValueError: ``n`` changes with that gap do not fit into ``duration``.
    """
    if n < 0:
        raise ValueError(f"number of lane changes must be >= 0, got {n}")
    if n == 0:
        return []
    free = duration - start - min_gap * n
    if free < 0:
        raise ValueError(f"{n} lane changes {min_gap:g} s apart do not fit into {duration:.0f} s: record more "
                         f"(at least {start + min_gap * n:.0f} s) or ask for fewer changes")
    rng = np.random.default_rng([seed & 0xFFFFFFFF, 0x1A4E])
    # n gaps of min_gap plus a random share of the free time: sorted uniform cut points
    extra = np.sort(rng.uniform(0.0, free, n))
    return [round(float(start + min_gap * i + extra[i]), 3) for i in range(n)]


def periodic_change_times(duration: float, every: tuple[float, float], *, seed: int = 0,
                          start: float = 4.0) -> list[float]:
    """Seeded times from ``start`` to ``duration``, consecutive ones ``every`` = (min, max) seconds
    apart (uniform): lane changes commanded through an evaluation episode."""
    lo, hi = float(every[0]), float(every[1])
    if not 0 < lo <= hi:
        raise ValueError(f"the interval between lane changes must be (min, max) seconds with 0 < min <= max, "
                         f"got {every!r}")
    rng = np.random.default_rng([seed & 0xFFFFFFFF, 0x1A4F])
    times, t = [], float(start)
    while t < duration:
        times.append(round(t, 3))
        t += rng.uniform(lo, hi)
    return times
