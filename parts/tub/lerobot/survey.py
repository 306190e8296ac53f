"""First pass of an export: what the tubs hold, how they split into episodes, the loop rate.

Reads the catalogs only (and one image per camera for its size), keeping counters, never the
records, so it runs in bounded memory on any number of records.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parts.tub.errors import CorruptRecord, TubError
from parts.tub.format import IMAGE_TYPES, SESSION, TIMESTAMP
from parts.tub.reader import TubRecord, find_tubs, iter_records
from parts.tub.tub import Tub

logger = logging.getLogger(__name__)

THROTTLE_KEY = "user/throttle"
ONE_HOT_KEY = "behavior/one_hot_state_array"
LABEL_KEY = "behavior/label"
STATE_KEY = "behavior/state"
TRACK_KEY = "sim/track"
DEFAULT_FPS = 20  # DRIVE_LOOP_HZ's default, used when no interval can be measured


@dataclass
class FieldSurvey:
    """What the values of one tub field look like across the exported records."""

    type: str
    present: int = 0
    kinds: set[str] = field(default_factory=set)  # int, float, bool, str, list, other
    length: int | None = None                     # list length; -1 when lengths differ
    numeric_items: bool = True                    # every list holds numbers only (no nesting)
    int_items: bool = True                        # ... and whole numbers stored as ints

    def add(self, value: Any) -> None:
        self.present += 1
        if isinstance(value, bool):
            self.kinds.add("bool")
        elif isinstance(value, int):
            self.kinds.add("int")
        elif isinstance(value, float):
            self.kinds.add("float")
        elif isinstance(value, str):
            self.kinds.add("str")
        elif isinstance(value, list):
            self.kinds.add("list")
            n = len(value)
            self.length = n if self.length in (None, n) else -1
            for v in value:
                if isinstance(v, bool) or not isinstance(v, int | float):
                    self.numeric_items = self.int_items = False
                    break
                if not isinstance(v, int):
                    self.int_items = False
        else:
            self.kinds.add("other")


class EpisodeSplitter:
    """Tells where an episode starts: a new tub, a new recording session, another simulator
    track, a gap in capture time longer than ``max_gap_ms`` (recording paused, records deleted,
    clock set back), or an episode that already holds ``max_frames`` frames (a long session cut
    so that its float32 ``timestamp`` stays exact enough, see export.MAX_EPISODE_S)."""

    def __init__(self, max_gap_ms: float | None, max_frames: int | None = None) -> None:
        self.max_gap_ms = max_gap_ms
        self.max_frames = max_frames
        self._key: tuple[Any, ...] | None = None
        self._ts: float | None = None
        self._frames = 0  # in the current episode
        self.interval_ms: float | None = None  # between the last two records, when in one episode

    def is_new(self, rec: TubRecord) -> bool:
        key = (rec.tub, rec.data.get(SESSION), rec.data.get(TRACK_KEY))
        ts = rec.data.get(TIMESTAMP)
        ts = float(ts) if isinstance(ts, int | float) and not isinstance(ts, bool) else None
        new = self._key is None or key != self._key
        self.interval_ms = None
        if not new and ts is not None and self._ts is not None:
            gap = ts - self._ts
            if gap < 0 or (self.max_gap_ms is not None and gap > self.max_gap_ms):
                new = True
            else:
                self.interval_ms = gap
        if not new and self.max_frames is not None and self._frames >= self.max_frames:
            new = True
        self._frames = 1 if new else self._frames + 1
        self._key, self._ts = key, ts
        return new


@dataclass
class TubSource:
    """One exported tub: folder, schema and metadata."""

    path: Path
    inputs: list[str]
    types: list[str]
    metadata: dict[str, Any]


@dataclass
class Intervals:
    """Intervals between consecutive frames of an episode: a count per whole millisecond and the
    exact sum of each bin, so memory stays bounded and the rate keeps sub-millisecond precision
    (capture times are whole ms: a 60 Hz loop gives intervals of 16 and 17 ms)."""

    counts: Counter[int] = field(default_factory=Counter)
    sums: dict[int, float] = field(default_factory=dict)

    def add(self, ms: float) -> None:
        b = int(round(ms))
        self.counts[b] += 1
        self.sums[b] = self.sums.get(b, 0.0) + ms

    def fps(self) -> int | None:
        """Frames per second over the intervals within +-50 % of the median (a missed loop, or
        two frames captured together, left out), rounded: LeRobot's fps is an integer. None when
        no interval was measured."""
        total = sum(self.counts.values())
        if not total:
            return None
        seen = 0
        median = 0
        for ms in sorted(self.counts):
            seen += self.counts[ms]
            if seen * 2 >= total:
                median = ms
                break
        kept = [b for b in self.counts if 0.5 * median <= b <= 1.5 * median]
        span = sum(self.sums[b] for b in kept)
        frames = sum(self.counts[b] for b in kept)
        return max(1, round(1000.0 * frames / span)) if span > 0 else None


@dataclass
class Survey:
    """Everything the second pass needs to know in advance."""

    tubs: list[TubSource]
    fields: dict[str, FieldSurvey]
    records: int = 0
    episodes: int = 0
    skipped: list[str] = field(default_factory=list)
    intervals: Intervals = field(default_factory=Intervals)  # between frames of an episode
    behaviours: dict[int, str] = field(default_factory=dict)  # behaviour index -> label
    image_shapes: dict[str, tuple[int, ...]] = field(default_factory=dict)

    def fps(self) -> int | None:
        """The loop rate measured from the capture times (None: unknown), see :meth:`Intervals.fps`."""
        return self.intervals.fps()

    def image_keys(self) -> list[str]:
        """Image fields in schema order (first tub first)."""
        return [k for k, f in self.fields.items() if f.type in IMAGE_TYPES]


def short(error: CorruptRecord) -> str:
    """A bad record's report without the repair hint (the export lists them all)."""
    return f"{error.tub}: record {error.index}: {error.file.name}: {error.reason}"


def usable(rec: TubRecord) -> str | None:
    """Why a record cannot be exported (no steering or throttle label), or None."""
    angle = rec.angle
    throttle = rec.throttle
    for name, v in (("user/angle", angle), (THROTTLE_KEY, throttle)):
        if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
            return f"no {name} value"
    return None


def exported_records(tubs: list[Path], skipped: list[str]) -> Iterator[TubRecord]:
    """The live records of ``tubs`` that can be exported, in tub and index order; the others are
    reported into ``skipped`` (``"tub: record N: reason"``)."""
    errors: list[CorruptRecord] = []
    seen = 0
    for rec in iter_records(tubs, check_images=True, on_error="skip", errors=errors):
        while seen < len(errors):
            skipped.append(short(errors[seen]))
            seen += 1
        why = usable(rec)
        if why:
            skipped.append(f"{rec.tub}: record {rec.index}: {why}")
            continue
        yield rec
    skipped.extend(short(e) for e in errors[seen:])


def survey_tubs(paths: list[str | Path], *, max_gap_ms: float | None) -> Survey:
    """Scan the tubs (catalogs only): fields, records, episodes, intervals, behaviours, image sizes."""
    tubs: list[TubSource] = []
    fields: dict[str, FieldSurvey] = {}
    for path in find_tubs(paths):
        tub = Tub(path, read_only=True)
        tubs.append(TubSource(tub.path, list(tub.inputs), list(tub.types), dict(tub.metadata)))
        for key, tp in zip(tub.inputs, tub.types, strict=True):
            known = fields.get(key)
            if known is None:
                fields[key] = FieldSurvey(tp)
            elif known.type != tp:
                raise TubError(f"{tub.path}: field {key!r} has type {tp!r} here but {known.type!r} in another "
                               "tub; export these tubs separately")
    survey = Survey(tubs, fields)
    splitter = EpisodeSplitter(max_gap_ms)
    for rec in exported_records([t.path for t in tubs], survey.skipped):
        if not _probe_images(rec, fields, survey):
            continue
        survey.records += 1
        if splitter.is_new(rec):
            survey.episodes += 1
        elif splitter.interval_ms is not None and splitter.interval_ms > 0:
            survey.intervals.add(splitter.interval_ms)
        for key, value in rec.data.items():
            if key.startswith("_"):
                continue
            info = fields.get(key)
            if info is None:  # a field the manifest does not list (an edited tub): type from the value
                info = fields[key] = FieldSurvey(_type_of(value))
            if info.type in IMAGE_TYPES:
                info.present += 1
                continue
            info.add(value)
        _note_behaviour(rec, survey.behaviours)
    return survey


def _probe_images(rec: TubRecord, fields: dict[str, FieldSurvey], survey: Survey) -> bool:
    """Decode the first image of each camera for its size; False (reported) if it is bad."""
    for key in rec.data:
        if key in survey.image_shapes or key not in fields or fields[key].type not in IMAGE_TYPES:
            continue
        try:
            survey.image_shapes[key] = rec.image(key).shape
        except CorruptRecord as exc:
            survey.skipped.append(short(exc))
            return False
    return True


def _type_of(value: Any) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        return "float"
    if isinstance(value, list):
        return "list"
    return "str"


def _note_behaviour(rec: TubRecord, behaviours: dict[int, str]) -> None:
    """Learn the label of each behaviour index from records holding both (state or one-hot)."""
    label = rec.data.get(LABEL_KEY)
    if not isinstance(label, str):
        return
    state = rec.data.get(STATE_KEY)
    if not isinstance(state, int) or isinstance(state, bool):
        hot = rec.data.get(ONE_HOT_KEY)
        if isinstance(hot, list) and hot and max(hot) > 0:
            state = max(range(len(hot)), key=hot.__getitem__)
        else:
            return
    behaviours.setdefault(int(state), label)
