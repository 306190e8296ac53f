"""The moments a failure gallery shows, caught during an evaluation episode.

Two parts join an evaluation's loop when ``vehicle sim eval --gallery`` asks for one
(:func:`attach`):

- :class:`ShadowExpert`: the built-in simulator's expert, asked what it would steer in the car's
  state of every frame (``gallery/expert_angle``); it drives nothing.
- :class:`MomentRecorder`: keeps the last ``window_s`` seconds of what the pilot saw and answered
  (its inputs, its steering and throttle, the expert's steering, the CTE) and snapshots them at
  every intervention (the rising edge of ``sim/off_track``, as :class:`parts.sim.metrics.EpisodeMetrics`
  counts them, so the two lists match one to one) and at the ``worst`` largest |CTE| moments on the
  road (at least one window apart and not in the window before an intervention, which shows them).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

#: the shadow expert's steering, in the episode's memory
EXPERT_KEY = "gallery/expert_angle"
#: m; a worst-|CTE| moment closer to the centre line than this is no failure and is not kept
MIN_WORST_CTE = 0.05
#: worst-|CTE| candidates kept beyond ``worst``: a later intervention's window may take some back
SPARE_CANDIDATES = 4


@dataclass(frozen=True)
class GallerySpec:
    """What a gallery holds and where it goes (plain values: it travels to worker processes).

    Attributes:
        folder: the gallery's folder (must not exist yet); one sub-folder per track.
        model: the pilot's model file (its saliency is computed from it).
        window_s: seconds of frames before each moment.
        frames: frames shown per moment, evenly spaced over the window (the last is the moment's).
        worst: largest-|CTE| moments on the road per track, besides the interventions.
        method: saliency method (:data:`parts.pilots.saliency.METHODS`).
    """

    folder: str
    model: str
    window_s: float = 2.0
    frames: int = 6
    worst: int = 3
    method: str = "integrated"

    def check(self) -> None:
        """ValueError (one line) for values out of range."""
        from parts.pilots.saliency import METHODS

        if not 0.1 <= self.window_s <= 30.0:
            raise ValueError(f"gallery window {self.window_s} s: give 0.1 to 30 seconds")
        if not 1 <= self.frames <= 20:
            raise ValueError(f"gallery frames per moment {self.frames}: give 1 to 20")
        if not 0 <= self.worst <= 20:
            raise ValueError(f"gallery worst |CTE| moments {self.worst}: give 0 to 20")
        if self.method not in METHODS:
            raise ValueError(f"saliency method {self.method!r}: use one of {', '.join(METHODS)}")

    def sub(self, name: str) -> GallerySpec:
        """The same gallery in the sub-folder ``name`` (one per theme and draw)."""
        from dataclasses import replace

        return replace(self, folder=str(Path(self.folder) / name))


class ShadowExpert:
    """Part: what the expert would steer now (``gallery/expert_angle``); it drives nothing. Runs
    after the simulated car, so it sees the state the frame was rendered in."""

    OUTPUTS: ClassVar[tuple[str, ...]] = ("gallery/expert_angle",)  # EXPERT_KEY

    def __init__(self, expert: Any) -> None:
        self.expert = expert

    def run(self, behavior_state: Any = None) -> float:
        return float(self.expert.command(behavior_state)[0])


@dataclass
class _Step:
    """One loop of the episode, as the gallery needs it."""

    time_s: float
    inputs: dict[str, Any]  # the pilot's inputs (frames copied)
    pilot: tuple[float, float]
    expert: float | None
    cte: float | None


@dataclass
class Moment:
    """A snapshot: ``kind`` "intervention" or "worst_cte", at ``time_s`` (the last step's)."""

    kind: str
    time_s: float
    cte: float | None
    pos: list[float] | None
    steps: list[_Step] = field(default_factory=list)


class MomentRecorder:
    """Part: see the module docstring. ``inputs`` are the pilot's input keys (frames first)."""

    def __init__(self, dt: float, inputs: tuple[str, ...], window_s: float, worst: int) -> None:
        self.dt, self.keys, self.worst = float(dt), tuple(inputs), int(worst)
        self.window = max(1, round(window_s / self.dt))
        self.window_s = self.window * self.dt
        self._ring: deque[_Step] = deque(maxlen=self.window)
        self.interventions: list[Moment] = []
        self._worst: list[Moment] = []
        self._was_off = False
        self._last_pos: list[float] | None = None
        self._n = 0

    @property
    def INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """The pilot's inputs, its commands, the expert's steering and the telemetry."""
        return (*self.keys, "pilot/angle", "pilot/throttle", EXPERT_KEY, "sim/cte", "sim/off_track", "sim/pos")

    def run(self, *values: Any) -> None:
        k = len(self.keys)
        inputs = {key: (np.array(v, copy=True) if isinstance(v, np.ndarray) else v)
                  for key, v in zip(self.keys, values[:k], strict=True)}
        angle, throttle, expert, cte, off, pos = values[k:]
        self._n += 1
        t = self._n * self.dt
        cte_f = float(cte) if cte is not None else None
        self._ring.append(_Step(t, inputs, (_num(angle), _num(throttle)),
                                float(expert) if expert is not None else None, cte_f))
        off = bool(off)
        here = [round(float(pos[0]), 3), round(float(pos[1]), 3)] if pos is not None else None
        if off and not self._was_off:  # an intervention: EpisodeMetrics' rule, and its position (the last on road)
            where = self._last_pos if self._last_pos is not None else here
            self.interventions.append(Moment("intervention", t, cte_f, where, list(self._ring)))
            self._worst = [m for m in self._worst if not t - self.window_s <= m.time_s <= t]
        elif not off and cte_f is not None and self.worst and abs(cte_f) >= MIN_WORST_CTE:
            self._consider(t, cte_f, here)
        self._was_off = off
        if here is not None:
            self._last_pos = here

    def _consider(self, t: float, cte: float, where: list[float] | None) -> None:
        """Keep the moment if it is among the ``worst`` largest |CTE|, one window from the others."""
        near = [m for m in self._worst if abs(m.time_s - t) < self.window_s]
        if any(abs(m.cte or 0.0) >= abs(cte) for m in near):
            return
        if len(self._worst) - len(near) >= self.worst + SPARE_CANDIDATES and \
                abs(cte) <= min(abs(m.cte or 0.0) for m in self._worst if m not in near):
            return
        kept = [m for m in self._worst if m not in near] + [Moment("worst_cte", t, cte, where, list(self._ring))]
        self._worst = sorted(kept, key=lambda m: -abs(m.cte or 0.0))[:self.worst + SPARE_CANDIDATES]

    def moments(self) -> list[Moment]:
        """The interventions (in order), then the worst |CTE| moments (largest first)."""
        return [*self.interventions, *self._worst[:self.worst]]


def _num(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def attach(V: Any, sim: Any, cfg: Any, pilot_inputs: tuple[str, ...], spec: GallerySpec) -> MomentRecorder:
    """Add the shadow expert and the recorder to an episode's vehicle (after the metrics part)."""
    from parts.sim.expert import Expert

    expert = Expert.from_config(cfg.replace(TRAIN_BEHAVIORS=False), sim)
    V.add(ShadowExpert(expert), inputs=[])
    recorder = MomentRecorder(sim.dt, pilot_inputs, spec.window_s, spec.worst)
    V.add(recorder)
    return recorder
