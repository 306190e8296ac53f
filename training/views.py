"""Samples of several camera views (the ``three_camera`` model): which tubs have them, and how a
flip reorders them.

The views of a sample are the camera keys the model declares (``image_inputs``: left, centre,
right), read from the same record and given the same augmentation draw (see
:class:`training.dataset.PilotDataset`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["require_views", "view_mirror"]


def view_mirror(keys: Sequence[str]) -> np.ndarray:
    """Index permutation of camera views for a horizontally flipped sample: the mirror image of
    the left camera's frame is what the right camera would see, so a key with "left" swaps with
    the same key with "right" (``cam/image_array_left`` <-> ``cam/image_array_right``); others stay.

    Raises:
        ValueError: a left/right key has no counterpart among ``keys``.
    """
    keys = list(keys)
    perm = np.arange(len(keys))
    for i, key in enumerate(keys):
        if "left" in key or "right" in key:
            other = key.replace("left", "\0").replace("right", "left").replace("\0", "right")
            if other not in keys:
                raise ValueError(f"camera view {key!r} has no mirror {other!r} among {keys}")
            perm[i] = keys.index(other)
    return perm


def require_views(type_name: str, keys: Sequence[str], records: Sequence[Any]) -> None:
    """Raise ValueError (one line: which tubs lack which keys, and how to record them) unless every
    record holds a frame under each of ``keys``."""
    lacking: dict[str, set[str]] = {}
    for rec in records:
        for key in keys:
            if not rec.data.get(key):
                lacking.setdefault(str(rec.tub), set()).add(key)
    if lacking:
        shown = "; ".join(f"{tub}: no {', '.join(sorted(k))}" for tub, k in sorted(lacking.items())[:3])
        more = f" (and {len(lacking) - 3} more tubs)" if len(lacking) > 3 else ""
        raise ValueError(f"model type {type_name!r} trains on the frames {list(keys)} of every record, which "
                         f"these tubs lack ({shown}{more}): import Udacity recordings with `vehicle tub "
                         "import-udacity`, or record in the built-in simulator with SIM_SIDE_CAMERAS_OFFSET "
                         "set (e.g. 0.15 m)")
