"""Balancing the training set by a steering histogram (Track Driver AI's num_bins / max_samples_per_bin).

Driving data is mostly straight ahead: a model trained on it learns to go straight. Cutting every
steering bin to at most ``max_per_bin`` random records evens the distribution.
"""

from __future__ import annotations

import numpy as np


def balance_by_steering(angles: np.ndarray, positions: np.ndarray, num_bins: int = 25,
                        max_per_bin: int = 400, seed: int = 42) -> np.ndarray:
    """The positions kept (sorted): at most ``max_per_bin`` per steering bin.

    Args:
        angles: steering label of every record (indexed by position).
        positions: the candidate positions (e.g. the training split).
        num_bins: equal-width bins over the range of the candidates' angles.
        max_per_bin: most records kept per bin (random choice with ``seed``).
    """
    if num_bins < 1 or max_per_bin < 1:
        raise ValueError(f"balancing needs num_bins >= 1 and max_per_bin >= 1, got {num_bins}, {max_per_bin}")
    positions = np.asarray(positions)
    if positions.size == 0:
        return positions
    values = np.asarray(angles)[positions]
    edges = np.histogram_bin_edges(values, bins=num_bins)
    # digitize against the inner edges: bin 0..num_bins-1, the maximum lands in the last bin.
    which = np.digitize(values, edges[1:-1], right=False)
    rng = np.random.default_rng(seed)
    keep = []
    for b in range(num_bins):
        members = positions[which == b]
        if members.size > max_per_bin:
            members = rng.choice(members, size=max_per_bin, replace=False)
        keep.append(members)
    return np.sort(np.concatenate(keep))
