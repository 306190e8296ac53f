"""Tub records -> training samples: filters, labels, continuity, side cameras, and the torch Dataset.

Flow (see :func:`training.trainer.prepare_data`)::

    load_records(paths) -> read_drive_data (filter modes + TRAIN_FILTER, labels, continuity)
        -> split_train_val (sessions / blocks) -> balance (train only) -> build_samples
        (side cameras, sequence/memory history) -> FrameCache (decoded uint8 frames)
        -> PilotDataset (augment -> Preprocess.frame -> uint8 tensors)

The trainer turns the uint8 batch into floats on the training device with
``Preprocess.normalize_batch``, the same function the pilot uses when driving.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
from torch.utils.data import Dataset

from parts.pilots.preprocess import Preprocess
from training.augment import Augmenter
from training.framecache import FrameCache
from training.views import view_mirror

logger = logging.getLogger(__name__)

IMAGE_KEY = "cam/image_array"
ANGLE_KEYS = ("user/angle", "user/steering")
THROTTLE_KEY = "user/throttle"
#: where a record's measured speed (m/s) is, in the order looked up (TRAIN_THROTTLE_LABEL = "speed")
SPEED_KEYS = ("sim/speed", "enc/speed")
#: True on a record the pilot drove whose label is a correction (the simulator's expert in DAgger,
#: the person in correction mode): trained on whatever TRAIN_MODES says
CORRECTION_KEY = "user/correction"


@dataclass
class DriveData:
    """Filtered records of many tubs with their labels and continuity.

    ``segments[i]`` numbers the (tub, session) of record ``i``; ``prev[i]`` is the position of the
    record recorded just before it in the same tub and session (consecutive index), else -1.
    """

    records: list[Any]
    angles: np.ndarray
    throttles: np.ndarray
    segments: np.ndarray
    prev: np.ndarray
    tubs: list[str]

    def __len__(self) -> int:
        return len(self.records)


def _angle(data: dict[str, Any]) -> Any:
    for key in ANGLE_KEYS:
        if key in data:
            return data[key]
    return None


def read_drive_data(paths: Sequence[str | os.PathLike[str]], *, modes: Iterable[str] | None = ("user",),
                    record_filter: Callable[[dict[str, Any]], bool] | None = None,
                    records: list[Any] | None = None, speed_scale: float | None = None) -> DriveData:
    """Records of ``paths`` (tubs or folders of tubs) kept for training.

    Args:
        modes: keep records whose ``user/mode`` is in this list (records without a mode, and
            corrections, ``user/correction`` True, are kept); None keeps all.
        record_filter: the car's TRAIN_FILTER, called with each record's fields.
        records: already loaded records (skips ``load_records``; for tests and tools).
        speed_scale: when given, the throttle label is the record's measured speed
            (:data:`SPEED_KEYS`) divided by this (m/s), not its throttle (TRAIN_THROTTLE_LABEL =
            "speed"); records without a speed are skipped.
    """
    if records is None:
        from parts.tub.reader import load_records

        missing = [str(p) for p in paths if not Path(p).exists()]
        if missing:
            raise ValueError(f"no such tub or folder: {', '.join(missing)}; pass existing tubs with --tubs")
        records = list(load_records([str(p) for p in paths]))
    modes = set(modes) if modes is not None else None
    kept: list[Any] = []
    angles: list[float] = []
    throttles: list[float] = []
    dropped = {"mode": 0, "filter": 0, "label": 0}
    for rec in records:
        data = rec.data
        # a correction (DAgger, correction mode) was driven by the pilot but carries the expert's or
        # the person's label: kept whatever the mode
        if modes is not None and data.get("user/mode", "user") not in modes and data.get(CORRECTION_KEY) is not True:
            dropped["mode"] += 1
            continue
        if record_filter is not None and not record_filter(data):
            dropped["filter"] += 1
            continue
        angle, throttle = _angle(data), data.get(THROTTLE_KEY)
        if speed_scale is not None:
            speed = next((data[k] for k in SPEED_KEYS if data.get(k) is not None), None)
            throttle = None if speed is None else float(speed) / speed_scale
        try:
            a, t = float(angle), float(throttle)
        except (TypeError, ValueError):
            dropped["label"] += 1
            continue
        if not (np.isfinite(a) and np.isfinite(t)):
            dropped["label"] += 1
            continue
        kept.append(rec)
        angles.append(float(np.clip(a, -1.0, 1.0)))
        throttles.append(float(np.clip(t, -1.0, 1.0)))
    if any(dropped.values()):
        logger.info("kept %d records; skipped %d not in modes %s, %d by TRAIN_FILTER, %d without labels",
                    len(kept), dropped["mode"], sorted(modes or []), dropped["filter"], dropped["label"])
    if not kept:
        hint = (f"TRAIN_THROTTLE_LABEL = 'speed' needs a measured speed ({' or '.join(SPEED_KEYS)}) in every "
                "record: record with the simulator or an encoder, or train on the throttle"
                if speed_scale is not None and dropped["label"] else "record some driving in user mode first")
        raise ValueError(f"no training records in {', '.join(map(str, paths)) or 'the given records'} "
                         f"(skipped: {dropped}); {hint}")
    seg_ids: dict[tuple[str, Any], int] = {}
    segments = np.empty(len(kept), np.int64)
    prev = np.full(len(kept), -1, np.int64)
    for i, rec in enumerate(kept):
        key = (str(rec.tub), rec.data.get("_session_id"))
        segments[i] = seg_ids.setdefault(key, len(seg_ids))
        if i and segments[i] == segments[i - 1] and int(rec.index) == int(kept[i - 1].index) + 1:
            prev[i] = i - 1
    tubs = sorted({str(rec.tub) for rec in kept})
    return DriveData(kept, np.asarray(angles, np.float32), np.asarray(throttles, np.float32), segments,
                     prev, tubs)


@dataclass
class Samples:
    """Training samples: record position, camera key index and the chain of earlier positions
    (``chain[:, 0]`` is the sample's own record, ``chain[:, k]`` the one k steps earlier);
    ``mirror[i]`` marks a sample shown mirrored (:meth:`with_mirrored_copies`), None = none is."""

    chain: np.ndarray
    key_index: np.ndarray
    mirror: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.chain)

    def positions(self) -> np.ndarray:
        """Every record position any sample reads (its own and its history)."""
        return np.unique(self.chain)

    def subset(self, mask: np.ndarray) -> Samples:
        return Samples(self.chain[mask], self.key_index[mask], None if self.mirror is None else self.mirror[mask])

    def with_mirrored_copies(self) -> Samples:
        """Every sample twice: as it is, then mirrored (steering negated), in that order."""
        mirror = np.zeros(len(self), bool) if self.mirror is None else self.mirror
        return Samples(np.concatenate([self.chain, self.chain]), np.concatenate([self.key_index, self.key_index]),
                       np.concatenate([mirror, ~mirror]))


def build_samples(data: DriveData, positions: np.ndarray, n_keys: int = 1, depth: int = 0) -> Samples:
    """Samples for ``positions`` x camera keys, each with ``depth`` earlier consecutive records.

    Records with fewer than ``depth`` consecutive predecessors (start of a session, after a deleted
    record) are left out: a sequence or memory model needs the full history.
    """
    positions = np.asarray(positions, np.int64)
    chain = np.empty((len(positions), depth + 1), np.int64)
    chain[:, 0] = positions
    for k in range(1, depth + 1):
        before = chain[:, k - 1]
        chain[:, k] = np.where(before >= 0, data.prev[np.maximum(before, 0)], -1)
    ok = (chain >= 0).all(axis=1)
    chain = chain[ok]
    return Samples(np.repeat(chain, n_keys, axis=0), np.tile(np.arange(n_keys), len(chain)))


BEHAVIOR_STATE_KEY = "behavior/state"
BEHAVIOR_LABEL_KEY = "behavior/label"
BEHAVIOR_ONE_HOT_KEY = "behavior/one_hot_state_array"


def behavior_names(data: DriveData) -> list[str] | None:
    """The behaviour names by index, read from the records' ``behavior/state`` and
    ``behavior/label``; None when the records do not name them all or use indices for different
    names (tubs recorded with different BEHAVIOR_LIST orders: see :func:`behavior_labels`)."""
    names: dict[int, str] = {}
    for rec in data.records:
        state, label = rec.data.get(BEHAVIOR_STATE_KEY), rec.data.get(BEHAVIOR_LABEL_KEY)
        if state is None or not isinstance(label, str):
            return None
        if names.setdefault(int(state), label) != label:
            return None
    if not names or sorted(names) != list(range(len(names))):
        # some behaviour never occurs: its name is unknown, and so is the mirror of the others
        return None
    return [names[i] for i in range(len(names))]


def _tub_orders(data: DriveData) -> dict[str, list[str]]:
    """Each tub's behaviour names by index, as its records show them ("?" for an index never seen)."""
    seen: dict[str, dict[int, str]] = {}
    for rec in data.records:
        state, label = rec.data.get(BEHAVIOR_STATE_KEY), rec.data.get(BEHAVIOR_LABEL_KEY)
        if state is not None and isinstance(label, str):
            seen.setdefault(str(rec.tub), {}).setdefault(int(state), label)
    return {tub: [m.get(i, "?") for i in range(max(m) + 1)] for tub, m in seen.items()}


def behavior_labels(data: DriveData, preferred: Sequence[str] | None = None
                    ) -> tuple[list[str] | None, np.ndarray | None]:
    """The behaviour names in the model's order and, per record, its behaviour's index in them.

    Every record names its behaviour (``behavior/label``), so tubs recorded with different
    BEHAVIOR_LIST orders still agree on what each record means: each record is placed by its
    name. The order is ``preferred`` (the car's BEHAVIOR_LIST) when it names every behaviour in the
    records, else the records' own order when all tubs share it.

    Returns:
        (names, index): ``index[i]`` is record ``i``'s position in ``names``; (None, None) when
        the records name no behaviour (tubs recorded before labels were kept: their one-hot
        arrays are used as recorded) or the tubs share one order that leaves a behaviour unnamed.

    Raises:
        ValueError: some tubs name their behaviours and others do not, or the tubs use different
            orders and ``preferred`` does not name every behaviour in them (one line, naming the
            tubs and their orders).
    """
    labels: list[str | None] = []
    unnamed: set[str] = set()
    for rec in data.records:
        state, label = rec.data.get(BEHAVIOR_STATE_KEY), rec.data.get(BEHAVIOR_LABEL_KEY)
        ok = state is not None and isinstance(label, str)
        labels.append(label if ok else None)
        if not ok:
            unnamed.add(str(rec.tub))
    orders = _tub_orders(data)
    if not orders:
        return None, None
    if unnamed:
        raise ValueError(f"the records of {', '.join(sorted(unnamed))} do not name their behaviour "
                         f"(behavior/label) but those of {', '.join(sorted(orders))} do, so which one-hot index "
                         "means which behaviour is unknown: train them separately or leave out the older tubs")
    names = sorted({label for label in labels if label is not None})
    if preferred is not None and set(names) <= set(preferred):
        order = list(preferred)
    else:
        order = behavior_names(data)  # one order shared by every record, every index named
        if order is None:
            groups: dict[tuple[str, ...], list[str]] = {}
            for tub, tub_order in orders.items():
                groups.setdefault(tuple(tub_order), []).append(Path(tub).name)
            if len(groups) == 1:
                return None, None  # one order, some behaviour never recorded: the one-hot as recorded
            shown = "; ".join(f"{', '.join(sorted(tubs))}: {list(o)}" for o, tubs in groups.items())
            raise ValueError(f"the tubs were recorded with different behaviour orders ({shown}) and BEHAVIOR_LIST "
                             f"{list(preferred) if preferred is not None else None} does not name every behaviour "
                             f"{names}: set BEHAVIOR_LIST to the order the car drives with, and each record's "
                             "behaviour is placed by its name")
    position = {name: i for i, name in enumerate(order)}
    return order, np.asarray([position[label] for label in labels], np.int64)


def behavior_mirror(names: Sequence[str]) -> np.ndarray | None:
    """Index permutation of the behaviours for a horizontally flipped frame: a name with "left"
    swaps with the same name with "right" (Left_Lane <-> Right_Lane), other names stay. None when
    some left/right name has no counterpart (then a flipped frame has no correct label)."""
    lowered = [n.lower() for n in names]
    perm = np.arange(len(names))
    for i, n in enumerate(lowered):
        if "left" in n or "right" in n:
            other = n.replace("left", "\0").replace("right", "left").replace("\0", "right")
            if other not in lowered:
                return None
            perm[i] = lowered.index(other)
    return perm


class PilotDataset(Dataset):
    """Samples as ``(images, extra, target)`` tensors.

    ``images``: uint8 (C, H, W), or (T, C, H, W) oldest first when ``frames > 1``, or (V, C, H, W)
    when ``views > 1`` (camera keys 0 .. V-1 of the cache, e.g. left, centre, right: every view
    gets the same augmentation draw, and a flip mirrors each view and swaps left and right,
    :func:`view_mirror`); ``extra``: float32
    (E,) (previous commands or behaviour one-hot; (0,) when the model takes none); ``target``: float32
    (angle, throttle). With an ``augmenter`` (training only) every sample gets a fresh random draw,
    reproducible from (seed, epoch, index). ``extra_mirror`` permutes the extra values of a flipped
    frame (the left-lane behaviour of a mirrored frame is the right lane, see
    :func:`behavior_mirror`). ``extra_values`` (records x ``extra_size``) replaces what the records
    hold under ``extra_key`` (the behaviour one-hot placed by name, :func:`behavior_labels`).
    """

    def __init__(self, data: DriveData, samples: Samples, cache: FrameCache, preprocess: Preprocess, *,
                 key_offsets: Sequence[float] = (0.0,), frames: int = 1, command_history: int = 0,
                 extra_key: str | None = None, extra_size: int = 0, augmenter: Augmenter | None = None,
                 seed: int = 0, extra_mirror: np.ndarray | None = None,
                 extra_values: np.ndarray | None = None, views: int = 1) -> None:
        if samples.chain.shape[1] < max(frames, command_history + 1):
            raise ValueError("samples were built with too short a history for this model")
        if views > 1 and frames > 1:
            raise ValueError("a sample has either several frames (sequence) or several camera views, not both")
        self.views = views
        self.view_mirror = view_mirror(cache.keys[:views]) if views > 1 else None
        self.data = data
        self.samples = samples
        self.cache = cache
        self.preprocess = preprocess
        self.key_offsets = np.asarray(key_offsets, np.float32)
        self.frames = frames
        self.command_history = command_history
        self.extra_key = extra_key
        self.extra_size = extra_size
        self.augmenter = augmenter
        self.seed = seed
        self.extra_mirror = extra_mirror
        self.extra_values = extra_values
        if extra_values is not None and extra_values.shape != (len(data), extra_size):
            raise ValueError(f"extra_values must be (records, {extra_size}), got {extra_values.shape}")
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        """Change the augmentation draws for a new epoch."""
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return len(self.samples)

    def _extra(self, chain: np.ndarray, flip: bool) -> np.ndarray:
        if self.command_history:
            earlier = chain[self.command_history:0:-1]  # oldest first, excluding the sample's own record
            pairs = np.stack([self.data.angles[earlier], self.data.throttles[earlier]], axis=1)
            if flip:
                pairs[:, 0] *= -1
            return pairs.reshape(-1).astype(np.float32)
        if self.extra_key is not None:
            if self.extra_values is not None:
                values = self.extra_values[chain[0]]
            else:
                raw = self.data.records[chain[0]].data.get(self.extra_key)
                values = np.asarray(raw if raw is not None else [], np.float32).reshape(-1)
            if values.size != self.extra_size:
                rec = self.data.records[chain[0]]
                raise ValueError(f"record {rec.index} of {rec.tub}: {self.extra_key} has {values.size} "
                                 f"values, the model expects {self.extra_size}")
            if flip and self.extra_mirror is not None:
                mirrored = np.empty_like(values)
                mirrored[self.extra_mirror] = values
                return mirrored
            return values
        return np.zeros(0, np.float32)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        chain = self.samples.chain[i]
        key = int(self.samples.key_index[i])
        pos = int(chain[0])
        angle = float(self.data.angles[pos] + self.key_offsets[key])
        throttle = float(self.data.throttles[pos])
        mirrored = self.samples.mirror is not None and bool(self.samples.mirror[i])
        if mirrored:
            angle = -angle
        ops: list = []
        if self.augmenter is not None:
            rng = np.random.default_rng((self.seed, self.epoch, i))
            ops = self.augmenter.draw(rng)
            angle = self.augmenter.steering(angle, ops)
        else:
            angle = float(np.clip(angle, -1.0, 1.0))
        flipped = mirrored != Augmenter.flipped(ops)
        if self.views > 1:
            x = torch.stack([self._view(pos, v, mirrored, ops) for v in range(self.views)])
            if flipped:  # each view was mirrored: the left camera's now shows what the right one would
                x = x[torch.from_numpy(self.view_mirror)]
            extra = torch.from_numpy(self._extra(chain, flipped))
            return x, extra, torch.tensor([angle, throttle], dtype=torch.float32)
        images = []
        for k in range(self.frames - 1, -1, -1):  # oldest first
            frame = self.cache.get(int(chain[k]), key)
            if mirrored:
                frame = cv2.flip(frame, 1)
            if ops:
                frame = self.augmenter.apply(frame, ops)
            images.append(Preprocess.to_chw(self.preprocess.frame(frame)))
        x = images[0] if self.frames == 1 else torch.stack(images)
        extra = torch.from_numpy(self._extra(chain, flipped))
        return x, extra, torch.tensor([angle, throttle], dtype=torch.float32)

    def _view(self, pos: int, key: int, mirrored: bool, ops: list) -> torch.Tensor:
        """Camera view ``key`` of record ``pos``, mirrored / augmented as the sample is (CxHxW uint8)."""
        frame = self.cache.get(pos, key)
        if mirrored:
            frame = cv2.flip(frame, 1)
        if ops:
            frame = self.augmenter.apply(frame, ops)
        return Preprocess.to_chw(self.preprocess.frame(frame))
