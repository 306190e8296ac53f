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
  With commanded lane changes (:class:`ChangeLimits`) it also keeps, for every command judged a
  failure (:func:`parts.sim.lane_metrics.judge_change`, the lane metrics' own rule on the same
  steps), the frames from ``window_s`` before the command to its failure: a ``failed_change``
  moment, which the evaluation gives the command's record (:func:`with_commands`).
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
    """A snapshot: ``kind`` "intervention", "failed_change" or "worst_cte", at ``time_s`` (the
    last step's); a failed change also has the time it was commanded and, once the evaluation has
    scored the episode, the command's record (:func:`parts.sim.lane_metrics.lane_metrics`)."""

    kind: str
    time_s: float
    cte: float | None
    pos: list[float] | None
    steps: list[_Step] = field(default_factory=list)
    command_time_s: float | None = None
    command: dict[str, Any] | None = None


@dataclass(frozen=True)
class ChangeLimits:
    """How commanded lane changes are judged (SIM_EVAL_LANE_CHANGE_TIME_LIMIT, _HOLD)."""

    lane_width: float  # m, one lane
    time_limit: float  # s a change may take
    hold: float  # s the car must stay centred in the new lane


@dataclass
class _Change:
    """The command being judged: its steps since ``window_s`` before it, and what the judge reads."""

    time_s: float
    offset: float  # m left of the centre line: the commanded lane's centre
    steps: deque[_Step]
    t: list[float] = field(default_factory=list)
    lateral: list[float] = field(default_factory=list)
    off: list[bool] = field(default_factory=list)


class MomentRecorder:
    """Part: see the module docstring. ``inputs`` are the pilot's input keys (frames first)."""

    def __init__(self, dt: float, inputs: tuple[str, ...], window_s: float, worst: int,
                 changes: ChangeLimits | None = None) -> None:
        self.dt, self.keys, self.worst = float(dt), tuple(inputs), int(worst)
        self.window = max(1, round(window_s / self.dt))
        self.window_s = self.window * self.dt
        self._ring: deque[_Step] = deque(maxlen=self.window)
        self.interventions: list[Moment] = []
        self.changes = changes
        self.failed_changes: list[Moment] = []
        self._change: _Change | None = None
        self._center: float | None = None
        self._worst: list[Moment] = []
        self._was_off = False
        self._last_pos: list[float] | None = None
        self._n = 0

    @property
    def INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """The pilot's inputs, its commands, the expert's steering and the telemetry."""
        lanes = ("sim/lane_center",) if self.changes is not None else ()
        return (*self.keys, "pilot/angle", "pilot/throttle", EXPERT_KEY, "sim/cte", "sim/off_track", "sim/pos",
                *lanes)

    def run(self, *values: Any) -> None:
        k = len(self.keys)
        inputs = {key: (np.array(v, copy=True) if isinstance(v, np.ndarray) else v)
                  for key, v in zip(self.keys, values[:k], strict=True)}
        angle, throttle, expert, cte, off, pos = values[k:k + 6]
        self._n += 1
        t = self._n * self.dt
        cte_f = float(cte) if cte is not None else None
        step = _Step(t, inputs, (_num(angle), _num(throttle)), float(expert) if expert is not None else None, cte_f)
        self._ring.append(step)
        off = bool(off)
        here = [round(float(pos[0]), 3), round(float(pos[1]), 3)] if pos is not None else None
        if self.changes is not None:
            self._judge(t, step, values[k + 6], cte_f, off, here)
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

    def _judge(self, t: float, step: _Step, center: Any, cte: float | None, off: bool,
               where: list[float] | None) -> None:
        """Follow the commanded lane (``sim/lane_center``): a change of it starts a command, which
        is judged on the steps LaneMetrics scores (those with a CTE and a commanded lane)."""
        from parts.sim.lane_metrics import judge_change

        if center is None or cte is None:
            return
        c = float(center)
        if self._center is not None and c != self._center:
            assert self.changes is not None
            # the window before the command, then up to the longest judgement after it
            after = int(np.ceil((self.changes.time_limit + self.changes.hold) / self.dt)) + 2
            self._change = _Change(t, c, deque(self._ring, maxlen=self.window + after))
        elif self._change is not None:
            self._change.steps.append(step)
        self._center = c
        change = self._change
        if change is None:
            return
        change.t.append(t)
        change.lateral.append(-cte)  # sim/cte is positive to the right
        change.off.append(off)
        limits = self.changes
        assert limits is not None
        outcome, _, _ = judge_change(np.asarray(change.t), np.asarray(change.lateral), np.asarray(change.off, bool),
                                     change.offset, 0, change.time_s + limits.time_limit + 1e-9,
                                     limits.lane_width / 4, limits.hold)
        if outcome is False:
            self.failed_changes.append(Moment("failed_change", t, cte, where, list(change.steps), change.time_s))
        if outcome is not None:
            self._change = None

    def moments(self) -> list[Moment]:
        """The interventions (in order), the failed lane changes (in order), then the worst |CTE|
        moments (largest first)."""
        return [*self.interventions, *self.failed_changes, *self._worst[:self.worst]]


def with_commands(moments: list[Moment], commands: list[dict[str, Any]], dt: float) -> list[Moment]:
    """Give each failed change its command's record from the episode's lane metrics (matched by
    the time it was commanded, within half a step)."""
    for m in moments:
        if m.command_time_s is not None:
            m.command = next((c for c in commands if c.get("time_s") is not None
                              and abs(c["time_s"] - m.command_time_s) < dt / 2), None)
    return moments


def _num(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def attach(V: Any, sim: Any, cfg: Any, pilot_inputs: tuple[str, ...], spec: GallerySpec,
           changes: ChangeLimits | None = None) -> MomentRecorder:
    """Add the shadow expert and the recorder to an episode's vehicle (after the metrics part);
    with ``changes``, failed commanded lane changes are moments too."""
    from parts.sim.expert import Expert

    # with commanded changes the shadow expert follows the commanded lane, as it would drive
    expert = Expert.from_config(cfg.replace(TRAIN_BEHAVIORS=changes is not None), sim)
    V.add(ShadowExpert(expert), inputs=["behavior/state"] if changes is not None else [])
    recorder = MomentRecorder(sim.dt, pilot_inputs, spec.window_s, spec.worst, changes)
    V.add(recorder)
    return recorder
