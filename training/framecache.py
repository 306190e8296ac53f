"""Decoded camera frames kept in memory so that only the first pass decodes JPEGs.

The cache holds the decoded uint8 frame exactly as recorded, never a processed one: augmentations
and preprocessing run on it afresh every time (DonkeyCar cached processed images and applied its
transformations again from the second epoch on). Frames are decoded up front by a pool of threads
(the JPEG codecs release the GIL while decoding) into one array, which DataLoader workers share.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

logger = logging.getLogger(__name__)

_CHUNK = 64  # frames a decoding thread takes at a time


class FrameCache:
    """Frames of ``records`` under camera ``keys``, addressed by (record position, key index)."""

    def __init__(self, records: Sequence[Any], keys: Sequence[str], *, enabled: bool = True,
                 max_mb: float = 4096, threads: int | None = None) -> None:
        self.records = records
        self.keys = list(keys)
        self.enabled = enabled
        self.max_mb = max_mb
        self.threads = threads or min(8, os.cpu_count() or 1)
        self._rows: np.ndarray | None = None
        self._frames: np.ndarray | None = None
        self.decodes = 0  # frames decoded so far (a test checks later epochs add none)

    def _decode(self, pos: int, key: int, out: np.ndarray | None = None) -> np.ndarray:
        self.decodes += 1
        image = self.records[pos].image(self.keys[key], out)
        if image is None:
            rec = self.records[pos]
            raise ValueError(f"record {rec.index} of {rec.tub} has no image under {self.keys[key]!r}")
        return image

    @property
    def cached(self) -> bool:
        """Whether the frames are held in memory."""
        return self._frames is not None

    @property
    def nbytes(self) -> int:
        return 0 if self._frames is None else int(self._frames.nbytes)

    def fill(self, positions: np.ndarray, progress: bool = False) -> np.ndarray:
        """Decode the frames of ``positions`` (all keys) into memory when enabled and within max_mb.

        Returns the positions whose frames could not be read (corrupt or missing; logged), which
        the caller leaves out of training. Without caching, nothing is decoded here.
        """
        positions = np.unique(np.asarray(positions, np.int64))
        if not self.enabled or positions.size == 0:
            return np.zeros(0, np.int64)
        first = self._decode(int(positions[0]), 0)
        per_frame = first.nbytes
        total_mb = per_frame * positions.size * len(self.keys) / 1e6
        if total_mb > self.max_mb:
            logger.warning("frame cache would need %.0f MB > TRAIN_CACHE_MAX_MB %.0f: decoding every epoch",
                           total_mb, self.max_mb)
            return np.zeros(0, np.int64)
        n_keys = len(self.keys)
        rows = np.full(len(self.records) * n_keys, -1, np.int64)
        slots = (positions[:, None] * n_keys + np.arange(n_keys)[None, :]).reshape(-1)
        rows[slots] = np.arange(slots.size)
        frames = np.empty((slots.size, *first.shape), np.uint8)
        bad: list[int] = []

        def work(j: int) -> bool:
            slot = int(slots[j])
            pos, key = divmod(slot, n_keys)
            dst = frames[j]
            try:
                img = self._decode(pos, key, dst)  # decoded in place when the frame fits
            except Exception as exc:  # CorruptRecord, missing file: skip the record, say which
                logger.warning("skipping record: %s", exc)
                bad.append(pos)
                return False
            if img.shape != first.shape:
                rec = self.records[pos]
                logger.warning("skipping record %s of %s: frame %s differs from %s", rec.index, rec.tub,
                               img.shape, first.shape)
                bad.append(pos)
                return False
            if img.base is not dst:  # decoded elsewhere (OpenCV): copy in
                dst[...] = img
            return True

        def work_chunk(lo: int) -> int:
            hi = min(slots.size, lo + _CHUNK)
            for j in range(lo, hi):
                work(j)
            return hi - lo

        bar: Any = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=int(slots.size), desc="decoding frames", unit="frame", leave=False)
        # Chunks, not one task per frame: a task costs about as much as decoding a small frame,
        # and the decoders (which release the GIL) would wait on the pool's bookkeeping.
        with ThreadPoolExecutor(self.threads) as pool:
            for done in pool.map(work_chunk, range(0, int(slots.size), _CHUNK)):
                if bar is not None:
                    bar.update(done)
        if bar is not None:
            bar.close()
        self._rows, self._frames = rows, frames
        skipped = np.unique(np.asarray(bad, np.int64))
        held = int(slots.size) - len(bad)  # one entry per frame that could not be read
        logger.info("cached %d decoded frames (%.0f MB)%s", held, held * per_frame / 1e6,
                    f"; {skipped.size} record{'s' if skipped.size != 1 else ''} skipped (unreadable frames: "
                    "`vehicle tub check` lists them)" if skipped.size else "")
        return skipped

    def get(self, pos: int, key: int = 0) -> np.ndarray:
        """The uint8 HxWx3 frame (read-only view when cached: never modify it in place)."""
        if self._frames is not None:
            row = self._rows[pos * len(self.keys) + key]
            if row >= 0:
                return self._frames[row]
        return self._decode(pos, key)
