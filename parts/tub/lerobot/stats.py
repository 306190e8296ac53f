"""Feature statistics as LeRobot computes them, in bounded memory, batch by batch.

LeRobot (``compute_stats.py``) stores per feature ``min``, ``max``, ``mean``, ``std`` (population),
``count`` and the quantiles ``q01 q10 q50 q90 q99``, per episode (meta/episodes) and for the whole
dataset (meta/stats.json). Vectors have one value per dimension (shape ``(n,)``); camera features
one per colour channel with shape ``(3, 1, 1)``, pixel values divided by 255 to lie in [0, 1].

Here every number is accumulated as frames arrive, never holding an episode in memory:

- vectors: count, mean and sum of squared deviations merged batch by batch (Chan et al.), min,
  max, and for quantiles LeRobot's method, a 5000-bin histogram per dimension whose range grows
  with the data (the counts are moved to the new bins), read by interpolation in the bin;
- images: an exact histogram of the pixel values per channel (256 bins for 8-bit frames), so
  every statistic is exact. LeRobot samples a subset of an episode's frames (about n^0.75,
  100..10,000); here every frame counts, and ``count`` is the number of frames;
- the dataset's statistics are accumulated over all frames directly: the same mean, std, min, max
  and count as LeRobot's aggregation of the episodes' statistics, and quantiles of the whole data
  rather than LeRobot's combination of per-episode quantiles.

Rows with NaN (a tub field missing in a record) are left out of a feature's statistics.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from parts.tub.lerobot.format import QUANTILES

QUANTILE_KEYS = tuple(f"q{int(round(q * 100)):02d}" for q in QUANTILES)
HISTOGRAM_BINS = 5000  # LeRobot's num_quantile_bins


class RunningStats:
    """Streaming statistics of ``dim``-dimensional vectors (LeRobot's RunningQuantileStats, with an
    exact variance update)."""

    def __init__(self, dim: int, bins: int = HISTOGRAM_BINS) -> None:
        self.dim = dim
        self.bins = bins
        self.count = 0
        self._mean = np.zeros(dim)
        self._m2 = np.zeros(dim)
        self._min = np.full(dim, np.inf)
        self._max = np.full(dim, -np.inf)
        self._hist = np.zeros((dim, bins))
        self._lo = np.zeros(dim)  # histogram range per dimension
        self._hi = np.zeros(dim)

    def update(self, batch: np.ndarray) -> None:
        """Add rows (shape ``(n, dim)`` or ``(n,)`` for dim 1); rows holding a NaN are skipped."""
        x = np.asarray(batch, dtype=np.float64).reshape(-1, self.dim)
        if x.size and np.isnan(x).any():
            x = x[~np.isnan(x).any(axis=1)]
        n = x.shape[0]
        if n == 0:
            return
        bmin, bmax = x.min(axis=0), x.max(axis=0)
        bmean = x.mean(axis=0)
        bm2 = ((x - bmean) ** 2).sum(axis=0)
        if self.count == 0:
            self._lo, self._hi = bmin - 1e-10, bmax + 1e-10
        total = self.count + n
        delta = bmean - self._mean
        self._mean = self._mean + delta * (n / total)
        self._m2 = self._m2 + bm2 + delta ** 2 * (self.count * n / total)
        self.count = total
        self._min = np.minimum(self._min, bmin)
        self._max = np.maximum(self._max, bmax)
        grow = (self._min < self._lo) | (self._max > self._hi)
        for d in np.flatnonzero(grow):
            self._rebin(d)
        for d in range(self.dim):
            self._hist[d] += np.bincount(self._bin_of(x[:, d], d), minlength=self.bins)

    def _bin_of(self, values: np.ndarray, d: int) -> np.ndarray:
        """The histogram bin of each value (a range too narrow for floats: everything in bin 0)."""
        width = self._hi[d] - self._lo[d]
        if not width > 0:
            return np.zeros(len(values), dtype=np.intp)
        idx = np.floor((values - self._lo[d]) / width * self.bins)
        return np.clip(idx, 0, self.bins - 1).astype(np.intp)

    def _rebin(self, d: int) -> None:
        """Widen dimension d's histogram to the new min/max, moving each bin's count to the new bin
        holding its centre (LeRobot's _adjust_histograms, vectorised)."""
        old = np.linspace(self._lo[d], self._hi[d], self.bins + 1)
        centres = (old[:-1] + old[1:]) / 2
        pad = (self._max[d] - self._min[d]) * 1e-10
        self._lo[d], self._hi[d] = self._min[d] - pad, self._max[d] + pad
        self._hist[d] = np.bincount(self._bin_of(centres, d), weights=self._hist[d], minlength=self.bins)

    def _quantile(self, d: int, q: float) -> float:
        hist = self._hist[d]
        edges = np.linspace(self._lo[d], self._hi[d], self.bins + 1)
        cum = np.cumsum(hist)
        target = q * self.count
        i = int(np.searchsorted(cum, target))
        if i == 0:
            return float(edges[0])
        if i >= len(cum):
            return float(edges[-1])
        before = cum[i - 1]
        inside = cum[i] - before
        if inside == 0:
            return float(edges[i])
        return float(edges[i] + (target - before) / inside * (edges[i + 1] - edges[i]))

    def result(self) -> dict[str, np.ndarray]:
        """min, max, mean, std, count, q01 .. q99 (NaN and count 0 when nothing was added)."""
        if self.count == 0:
            nan = np.full(self.dim, np.nan)
            return {"min": nan, "max": nan, "mean": nan, "std": nan, "count": np.array([0]),
                    **{k: nan for k in QUANTILE_KEYS}}
        out = {"min": self._min.copy(), "max": self._max.copy(), "mean": self._mean.copy(),
               "std": np.sqrt(np.maximum(0.0, self._m2 / self.count)), "count": np.array([self.count])}
        for key, q in zip(QUANTILE_KEYS, QUANTILES, strict=True):
            # LeRobot: fewer than two samples -> every quantile is the mean
            out[key] = out["mean"].copy() if self.count < 2 else \
                np.array([self._quantile(d, q) for d in range(self.dim)])
        return out


class ImageStats:
    """Exact per-channel statistics of frames from a histogram of pixel values; results are
    divided by the largest pixel value (255 for 8-bit frames), as LeRobot does."""

    def __init__(self, channels: int, levels: int = 256) -> None:
        self.channels = channels
        self.levels = levels
        self.frames = 0
        self._hist = np.zeros((channels, levels), dtype=np.int64)
        self._offsets = (np.arange(channels) * levels).astype(np.int64)

    def update(self, frame: np.ndarray) -> None:
        """Add one HxWxC (or HxW) frame of integer pixel values."""
        px = frame.reshape(-1, self.channels)
        flat = (px.astype(np.int64 if self.levels > 256 else np.int32) + self._offsets).ravel()
        self._hist += np.bincount(flat, minlength=self.channels * self.levels).reshape(self.channels, self.levels)
        self.frames += 1

    def merge(self, other: ImageStats) -> None:
        self._hist += other._hist
        self.frames += other.frames

    def result(self) -> dict[str, np.ndarray]:
        """The statistics, each of shape (C, 1, 1) in [0, 1]; count = number of frames."""
        shape = (self.channels, 1, 1)
        if self.frames == 0:
            nan = np.full(shape, np.nan)
            return {"min": nan, "max": nan, "mean": nan, "std": nan, "count": np.array([0]),
                    **{k: nan for k in QUANTILE_KEYS}}
        values = np.arange(self.levels, dtype=np.float64)
        n = self._hist.sum(axis=1)
        mean = (self._hist * values).sum(axis=1) / n
        var = (self._hist * (values - mean[:, None]) ** 2).sum(axis=1) / n
        present = self._hist > 0
        lo = present.argmax(axis=1)
        hi = self.levels - 1 - present[:, ::-1].argmax(axis=1)
        cum = np.cumsum(self._hist, axis=1)
        scale = float(self.levels - 1)
        out = {"min": lo / scale, "max": hi / scale, "mean": mean / scale, "std": np.sqrt(var) / scale,
               "count": np.array([self.frames])}
        for key, q in zip(QUANTILE_KEYS, QUANTILES, strict=True):
            # the smallest pixel value whose cumulative count reaches q of the pixels
            out[key] = np.array([np.searchsorted(cum[c], q * n[c]) for c in range(self.channels)]) / scale
        return {k: v if k == "count" else np.asarray(v, dtype=np.float64).reshape(shape) for k, v in out.items()}


def to_json(stats: dict[str, np.ndarray]) -> dict[str, Any]:
    """Arrays -> nested lists of Python numbers (floats, count as [int]), keys in LeRobot's order."""
    out: dict[str, Any] = {}
    for key in ("min", "max", "mean", "std", "count", *QUANTILE_KEYS):
        value = stats[key]
        out[key] = [int(v) for v in value] if key == "count" else np.asarray(value, dtype=np.float64).tolist()
    return out


def flatten(per_feature: dict[str, dict[str, Any]], prefix: str = "stats") -> dict[str, Any]:
    """``{"action": {"min": [...]}}`` -> ``{"stats/action/min": [...]}`` (meta/episodes columns)."""
    return {f"{prefix}/{feature}/{key}": value
            for feature, stats in per_feature.items() for key, value in stats.items()}
