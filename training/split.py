"""Train/validation split by whole sessions or contiguous blocks, or (to reproduce a document) by
random records.

Consecutive frames of a tub are near copies: a random per-frame split puts the neighbours of
every validation frame in the training set and the validation loss then measures memory, not
driving. By default the validation set is therefore made of whole recording sessions or of
contiguous blocks; "random" exists because the source documents split that way
(scikit-learn's ``train_test_split``), so their recipes can be reproduced exactly.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from vehicle.config import check_settings

logger = logging.getLogger(__name__)


def _runs(segments: Sequence[int]) -> list[np.ndarray]:
    """Positions grouped into runs of equal, adjacent segment ids (a segment = tub + session)."""
    seg = np.asarray(segments)
    if seg.size == 0:
        return []
    cuts = np.flatnonzero(seg[1:] != seg[:-1]) + 1
    return np.split(np.arange(seg.size), cuts)


def _take(groups: list[np.ndarray], n_val: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Pick random groups into validation, each only if it brings the count closer to n_val (at
    least one group stays in training)."""
    order = rng.permutation(len(groups))
    val: list[np.ndarray] = []
    count = 0
    for i in order[:-1]:  # the last group of the order always trains
        if count >= n_val:
            break
        if abs(count + len(groups[i]) - n_val) < abs(count - n_val):
            val.append(groups[i])
            count += len(groups[i])
    val_pos = np.sort(np.concatenate(val)) if val else np.zeros(0, np.int64)
    mask = np.ones(sum(len(g) for g in groups), bool)
    mask[val_pos] = False
    return np.flatnonzero(mask), val_pos


def split_train_val(segments: Sequence[int], train_fraction: float, by: str = "block", block: int = 100,
                    seed: int = 42) -> tuple[np.ndarray, np.ndarray]:
    """Split positions ``0..len(segments)-1`` into (train, validation) index arrays.

    Args:
        segments: per record (in tub order), an id of its tub + recording session.
        train_fraction: share of records for training, in [0, 1] (at least one group always
            trains, so 0 holds out all but one session or block).
        by: "session" (whole sessions when there are at least 2, else falls back to blocks), "block",
            or "random" (single records drawn at random: optimistic validation, see the module).
        block: records per contiguous block; shrunk for small data so there are at least 10 blocks.
        seed: random seed of the choice of validation sessions/blocks.
    """
    n = len(segments)
    check_settings(TRAIN_TEST_SPLIT=train_fraction, TRAIN_SPLIT_BY=by, TRAIN_SPLIT_BLOCK=block)
    if n == 0:
        raise ValueError("no records to split")
    n_val = int(round(n * (1.0 - train_fraction)))
    if n_val == 0:
        return np.arange(n), np.zeros(0, np.int64)
    if n < 2:
        raise ValueError(f"{n} record cannot be split into training and validation; record more data "
                         "or set TRAIN_TEST_SPLIT = 1.0")
    rng = np.random.default_rng(seed)
    if by == "random":
        val = rng.choice(n, size=min(n_val, n - 1), replace=False)
        return np.setdiff1d(np.arange(n), val), np.sort(val)
    runs = _runs(segments)
    if by == "session":
        if len(runs) >= 2:
            train, val = _take(runs, n_val, rng)
            if 0.5 * n_val <= len(val) <= 1.5 * n_val:
                return train, val
            logger.warning("sessions are too unequal to hold out %d of %d records: splitting by blocks "
                           "of records instead", n_val, n)
        else:
            logger.warning("only one recording session: splitting by blocks of records instead")
    block = max(1, min(block, n // 10))
    blocks = [run[i:i + block] for run in runs for i in range(0, len(run), block)]
    return _take(blocks, n_val, rng)
